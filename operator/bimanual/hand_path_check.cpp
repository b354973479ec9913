#include "operator/bimanual/hand_path_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace hemm::op {

namespace hb = hemm::device::bimanual;

std::string vector_text(const Eigen::Vector3d& v) {
  char b[96];
  std::snprintf(b, sizeof b, "%.6g %.6g %.6g", v.x(), v.y(), v.z());
  return b;
}

std::optional<HandPathIssue> check_hand_path(const hb::SimulatedBimanualDevice& dev, hb::ArmSide side,
                                             const HandPath& path, double duration_s) {
  using Kind = HandPathIssue::Kind;
  const auto k = static_cast<std::size_t>(hb::index(side));
  const std::string arm = side == hb::ArmSide::kRight ? "right" : "left";
  const hb::BimanualSimulation& sim = dev.simulation();
  // The start where the hand rests.
  const hb::HumanTarget rest = sim.resting_targets()[k];
  const Eigen::Isometry3d T0 = path(0.0);
  const Eigen::Matrix3d R_rest = rest.orientation_D.normalized().toRotationMatrix();
  const double dp = (T0.translation() - rest.position_D).norm();
  const double dr = Eigen::AngleAxisd(T0.linear() * R_rest.transpose()).angle();
  if (!(dp <= kStartTolerance_m && dr <= kStartTolerance_rad)) {
    char how_far[64];
    std::snprintf(how_far, sizeof how_far, "%.1f mm and %.3f rad", dp * 1e3, dr);
    return HandPathIssue{dp <= kStartTolerance_m ? Kind::kStartOrientation : Kind::kStartPosition,
                         std::string("the path starts ") + how_far + " from where the SIMULATED " + arm +
                             " hand rests (D: " + vector_text(rest.position_D) + ")"};
  }
  const device::EndEffectorLimits& l = dev.limits().ee[k];
  const hb::SimulationConfig& sc = sim.config();
  const kinematics::Arm7Elbow elbow = kinematics::arm7_elbow(sim.controller().nominal(side));
  const Eigen::Isometry3d& T_D_A = sc.plant.rig.T_D_A[k];
  const hb::HandleSpec& handle = sim.controller().handle(side);
  const Eigen::Isometry3d T_E_J7 = handle.T_J7_E.inverse();
  const double table_top = sc.plant.rig.table.max_D.z();
  const double activation = sc.control[k].collision.activation_m;
  // The wrist centre ends links 5 and 6: the wider of their capsules.
  const double wrist_radius = std::max(sc.plant.rig.link_radius(4), sc.plant.rig.link_radius(5));
  // The worst point of each (the message names it).
  double min_bend = 1e9, t_bend = 0.0, min_gap = 1e9, t_gap = 0.0;
  bool wrist_closest = true;
  Eigen::Vector3d p_bend = Eigen::Vector3d::Zero(), p_gap = Eigen::Vector3d::Zero();
  for (double t = 0.0;; t = std::min(t + 0.01, duration_s)) {
    const Eigen::Isometry3d T_D_E = path(t);
    const Eigen::Vector3d p = T_D_E.translation();
    if (!p.allFinite() || !l.contains(p))
      return HandPathIssue{Kind::kWorkspace, "the path leaves the SIMULATED " + arm + " arm's workspace at t = " +
                                                 std::to_string(t) + " s (D: " + vector_text(p) + "; box " +
                                                 vector_text(l.workspace_min_H) + " to " +
                                                 vector_text(l.workspace_max_H) + ")"};
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
    if (t >= duration_s) break;
  }
  char why[256];
  if (min_bend < kMinElbowBend_rad) {
    if (min_bend < 0)
      std::snprintf(why, sizeof why, "puts the wrist centre %.1f mm beyond the arm's reach (%.3f m from the shoulder)",
                    -min_bend * 1e3, elbow.upper_arm_m + elbow.forearm_m);
    else
      std::snprintf(why, sizeof why, "needs the elbow nearly stretched (bent %.1f deg, at least %.0f: singular)",
                    min_bend * 180.0 / std::numbers::pi, kMinElbowBend_rad * 180.0 / std::numbers::pi);
    return HandPathIssue{Kind::kPosture, std::string("the path ") + why + " at t = " + std::to_string(t_bend) +
                                             " s (SIMULATED " + arm + " arm, D: " + vector_text(p_bend) +
                                             "): the hand would stall short of it"};
  }
  if (min_gap < activation) {
    std::snprintf(why, sizeof why,
                  "brings the %s %.1f mm from the table, inside the %.0f mm where the SIMULATED %s arm's collision "
                  "avoidance pushes it away",
                  wrist_closest ? "wrist" : "handle", min_gap * 1e3, activation * 1e3, arm.c_str());
    return HandPathIssue{Kind::kPosture, std::string("the path ") + why + " at t = " + std::to_string(t_gap) +
                                             " s (D: " + vector_text(p_gap) + "): the hand would stay above it"};
  }
  return std::nullopt;
}

}  // namespace hemm::op
