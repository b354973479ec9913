#include "operator/vps/vps_bimanual.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>
#include <string>

#include "operator/bimanual/bimanual_config.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

SceneHandScript::SceneHandScript(SceneHands path, int arm, const VpsEndEffectorParams& mapping, double start_hold_s)
    : path_(path), arm_(arm), mapping_(mapping), start_hold_s_(start_hold_s) {
  if (path_.at == nullptr) throw std::invalid_argument("SceneHandScript: no path");
  if (!(start_hold_s_ >= 0.0 && start_hold_s_ < 60.0))
    throw std::invalid_argument("SceneHandScript: start hold must be in [0, 60) s");
  if (arm_ != 0 && arm_ != 1) throw std::invalid_argument("SceneHandScript: arm must be 0 (right) or 1 (left)");
}

Eigen::Isometry3d SceneHandScript::T_D_E(double t_s) const noexcept {
  const vps::BimanualPoses p = path_.at(std::max(0.0, t_s - start_hold_s_));
  return end_effector_pose_H(mapping_, arm_ == 0 ? p.right : p.left);
}

hb::HumanTarget SceneHandScript::at(double t_s) const noexcept {
  const Eigen::Isometry3d T = T_D_E(t_s);
  hb::HumanTarget g;  // holds the handle, dead-man pressed, no push
  g.position_D = T.translation();
  g.orientation_D = Eigen::Quaterniond(T.linear()).normalized();
  return g;
}

namespace {

std::string str(const Eigen::Vector3d& v) {
  char b[96];
  std::snprintf(b, sizeof b, "%.6g %.6g %.6g", v.x(), v.y(), v.z());
  return b;
}

}  // namespace

std::unique_ptr<hb::SimulatedBimanualDevice> make_vps_bimanual_device(
    const config::OperatorConfig& cfg, const std::string& scene,
    const std::array<VpsEndEffectorParams, device::kMaxEndEffectors>& mapping, double period_s) {
  const config::BimanualDeviceConfig& b = cfg.device().bimanual();
  if (const auto issues = validate_bimanual_config(b); !issues.empty())
    throw std::invalid_argument(issues.front().field + ": " + issues.front().message);
  BimanualSetup setup = bimanual_setup(b);
  setup.sim.plant.control_period_s = period_s;
  const SceneHands path = scene_hands(scene);
  std::array<std::shared_ptr<const hb::HumanScript>, hb::kArms> hands;
  std::array<std::shared_ptr<const SceneHandScript>, hb::kArms> scripts;
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    scripts[k] = std::make_shared<const SceneHandScript>(path, a, mapping[k], kStartHold_s);
    hands[k] = scripts[k];
  }
  auto dev = std::make_unique<hb::SimulatedBimanualDevice>(setup.sim, hands);
  const auto rest = dev->simulation().resting_targets();
  const kinematics::Arm7Elbow elbow = kinematics::arm7_elbow(dev->simulation().controller().nominal(hb::ArmSide::kRight));
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const std::string field = a == 0 ? "vps.right" : "vps.left";
    const std::string arm = a == 0 ? "right" : "left";
    const SceneHandScript& s = *scripts[k];
    const device::EndEffectorLimits& l = dev->limits().ee[k];
    // The path's start where the hand rests (first: the message says what fits).
    const Eigen::Isometry3d T0 = s.T_D_E(0.0);
    const Eigen::Vector3d p_rest = rest[k].position_D;
    const Eigen::Matrix3d R_rest = rest[k].orientation_D.normalized().toRotationMatrix();
    const double dp = (T0.translation() - p_rest).norm();
    const double dr = Eigen::AngleAxisd(T0.linear() * R_rest.transpose()).angle();
    if (dp > kStartTolerance_m || dr > kStartTolerance_rad) {
      // What would fit, keeping T_W_H's axes and the grasp's origin:
      // R_E_M = (R_W_H R_D_E)^T R_W_M(0), h_origin = p_W_M(0) - R_W_H (p_D_E + R_D_E p_E_M).
      const vps::BimanualPoses p0 = path.at(0.0);
      const Eigen::Isometry3d& T_W_M = a == 0 ? p0.right : p0.left;
      const Eigen::Matrix3d R_W_H = mapping[k].T_W_H.linear();
      const Eigen::AngleAxisd grasp((R_W_H * R_rest).transpose() * T_W_M.linear());
      const Eigen::Vector3d origin =
          T_W_M.translation() - R_W_H * (p_rest + R_rest * mapping[k].T_E_M.translation());
      char how_far[64];
      std::snprintf(how_far, sizeof how_far, "%.1f mm and %.3f rad", dp * 1e3, dr);
      throw std::invalid_argument(field + (dp > kStartTolerance_m ? ".h_origin" : ".grasp_rx") + ": the path starts " +
                                  how_far + " from where the SIMULATED " + arm + " hand rests (D: " + str(p_rest) +
                                  "); h_origin " + str(origin) + " and grasp_r " + str(grasp.axis() * grasp.angle()) +
                                  " put it there");
    }
    // Along the whole path: inside the arm's workspace (the controller walls
    // it off outside); within the arm's reach with the elbow bent at least
    // kMinElbowBend_rad (a flange pose fixes the bend, arm7.h: near the
    // stretched elbow the arm is singular and the hand stalls short of the
    // path); the wrist centre and the handle, both fixed to the flange, out
    // of the device's own table repulsion (collision.h), which would hold
    // the hand above the path.
    const hb::SimulationConfig& sc = dev->simulation().config();
    const Eigen::Isometry3d& T_D_A = sc.plant.rig.T_D_A[k];
    const Eigen::Isometry3d T_E_J7 = dev->simulation().controller().handle(static_cast<hb::ArmSide>(a)).T_J7_E.inverse();
    const hb::HandleSpec& handle = dev->simulation().controller().handle(static_cast<hb::ArmSide>(a));
    const double table_top = sc.plant.rig.table.max_D.z();
    const double activation = sc.control[k].collision.activation_m;
    // The wrist centre ends links 5 and 6: the wider of their capsules.
    const double wrist_radius = std::max(sc.plant.rig.link_radius(4), sc.plant.rig.link_radius(5));
    // The worst point of each (the message names it).
    double min_bend = 1e9, t_bend = 0.0, min_gap = 1e9, t_gap = 0.0;
    bool wrist_closest = true;
    Eigen::Vector3d p_bend, p_gap;
    for (double t = 0.0;; t = std::min(t + 0.01, s.duration_s())) {
      const Eigen::Isometry3d T_D_E = s.T_D_E(t);
      const Eigen::Vector3d p = T_D_E.translation();
      if (!p.allFinite() || !l.contains(p))
        throw std::invalid_argument(field + ".h_origin: the path leaves the SIMULATED " + arm + " arm's workspace at t = " +
                                    std::to_string(t) + " s (D: " + str(p) + "; box " + str(l.workspace_min_H) +
                                    " to " + str(l.workspace_max_H) + ")");
      const Eigen::Isometry3d T_D_J7 = T_D_E * T_E_J7;
      const Eigen::Vector3d wrist_D = T_D_J7 * elbow.wrist_J7;
      const double bend = kinematics::elbow_bend(elbow, T_D_A.inverse() * wrist_D);
      if (bend < min_bend) {
        min_bend = bend;
        t_bend = t;
        p_bend = p;
      }
      const double wrist_gap = wrist_D.z() - wrist_radius - table_top;
      const double handle_gap = std::min((T_D_J7 * Eigen::Vector3d(0, 0, handle.capsule_radius)).z(),
                                         (T_D_J7 * Eigen::Vector3d(0, 0, handle.capsule_length)).z()) -
                                handle.capsule_radius - table_top;
      if (std::min(wrist_gap, handle_gap) < min_gap) {
        min_gap = std::min(wrist_gap, handle_gap);
        wrist_closest = wrist_gap <= handle_gap;
        t_gap = t;
        p_gap = p;
      }
      if (t >= s.duration_s()) break;
    }
    char why[256];
    if (min_bend < kMinElbowBend_rad) {
      if (min_bend < 0)
        std::snprintf(why, sizeof why, "puts the wrist centre %.1f mm beyond the arm's reach (%.3f m from the shoulder)",
                      -min_bend * 1e3, elbow.upper_arm_m + elbow.forearm_m);
      else
        std::snprintf(why, sizeof why, "needs the elbow nearly stretched (bent %.1f deg, at least %.0f: singular)",
                      min_bend * 180.0 / std::numbers::pi, kMinElbowBend_rad * 180.0 / std::numbers::pi);
      throw std::invalid_argument(field + ".h_rx: the path " + why + " at t = " + std::to_string(t_bend) +
                                  " s (SIMULATED " + arm + " arm, D: " + str(p_bend) +
                                  "): the hand would stall short of it; turn (h_rx, h_ry, h_rz) or move the path");
    }
    if (min_gap < activation) {
      std::snprintf(why, sizeof why,
                    "brings the %s %.1f mm from the table, inside the %.0f mm where the SIMULATED %s arm's collision "
                    "avoidance pushes it away",
                    wrist_closest ? "wrist" : "handle", min_gap * 1e3, activation * 1e3, arm.c_str());
      throw std::invalid_argument(field + ".h_rx: the path " + why + " at t = " + std::to_string(t_gap) + " s (D: " +
                                  str(p_gap) + "): the hand would stay above it; turn (h_rx, h_ry, h_rz) or move the path");
    }
  }
  return dev;
}

}  // namespace hemm::op
