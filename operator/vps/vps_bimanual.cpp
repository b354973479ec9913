#include "operator/vps/vps_bimanual.h"

#include <algorithm>
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
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const std::string field = a == 0 ? "vps.right" : "vps.left";
    const SceneHandScript& s = *scripts[k];
    const auto issue = check_hand_path(*dev, static_cast<hb::ArmSide>(a),
                                       [&s](double t) { return s.T_D_E(t); }, s.duration_s());
    if (!issue) continue;
    using Kind = HandPathIssue::Kind;
    switch (issue->kind) {
      case Kind::kStartPosition:
      case Kind::kStartOrientation: {
        // What would fit, keeping T_W_H's axes and the grasp's origin:
        // R_E_M = (R_W_H R_D_E)^T R_W_M(0), h_origin = p_W_M(0) - R_W_H (p_D_E + R_D_E p_E_M).
        const Eigen::Vector3d p_rest = rest[k].position_D;
        const Eigen::Matrix3d R_rest = rest[k].orientation_D.normalized().toRotationMatrix();
        const vps::BimanualPoses p0 = path.at(0.0);
        const Eigen::Isometry3d& T_W_M = a == 0 ? p0.right : p0.left;
        const Eigen::Matrix3d R_W_H = mapping[k].T_W_H.linear();
        const Eigen::AngleAxisd grasp((R_W_H * R_rest).transpose() * T_W_M.linear());
        const Eigen::Vector3d origin =
            T_W_M.translation() - R_W_H * (p_rest + R_rest * mapping[k].T_E_M.translation());
        throw std::invalid_argument(field + (issue->kind == Kind::kStartPosition ? ".h_origin" : ".grasp_rx") + ": " +
                                    issue->message + "; h_origin " + vector_text(origin) + " and grasp_r " +
                                    vector_text(grasp.axis() * grasp.angle()) + " put it there");
      }
      case Kind::kWorkspace:
        throw std::invalid_argument(field + ".h_origin: " + issue->message);
      case Kind::kPosture:
        throw std::invalid_argument(field + ".h_rx: " + issue->message + "; turn (h_rx, h_ry, h_rz) or move the path");
    }
  }
  return dev;
}

}  // namespace hemm::op
