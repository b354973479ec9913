#include "operator/vps/vps_bimanual.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "operator/bimanual/bimanual_config.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

SceneHandScript::SceneHandScript(SceneHands path, int arm, const VpsEndEffectorParams& mapping)
    : path_(path), arm_(arm), mapping_(mapping) {
  if (path_.at == nullptr) throw std::invalid_argument("SceneHandScript: no path");
  if (arm_ != 0 && arm_ != 1) throw std::invalid_argument("SceneHandScript: arm must be 0 (right) or 1 (left)");
}

Eigen::Isometry3d SceneHandScript::T_D_E(double t_s) const noexcept {
  const vps::BimanualPoses p = path_.at(t_s);
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
    scripts[k] = std::make_shared<const SceneHandScript>(path, a, mapping[k]);
    hands[k] = scripts[k];
  }
  auto dev = std::make_unique<hb::SimulatedBimanualDevice>(setup.sim, hands);
  const auto rest = dev->simulation().resting_targets();
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const std::string field = a == 0 ? "vps.right" : "vps.left";
    const std::string arm = a == 0 ? "right" : "left";
    const SceneHandScript& s = *scripts[k];
    const device::EndEffectorLimits& l = dev->limits().ee[k];
    // The whole path inside the arm's workspace (the controller walls it off
    // outside: the object would stop short of the path).
    for (double t = 0.0;; t = std::min(t + 0.01, s.duration_s())) {
      const Eigen::Vector3d p = s.T_D_E(t).translation();
      if (!p.allFinite() || !l.contains(p))
        throw std::invalid_argument(field + ".h_origin: the path leaves the SIMULATED " + arm +
                                    " arm's workspace at t = " + std::to_string(t) + " s (D: " + str(p) + "; box " +
                                    str(l.workspace_min_H) + " to " + str(l.workspace_max_H) + ")");
      if (t >= s.duration_s()) break;
    }
    // The path's start where the hand rests.
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
  }
  return dev;
}

}  // namespace hemm::op
