#include "operator/station/tool6_bimanual.h"

#include <stdexcept>
#include <string>
#include <vector>

#include "operator/bimanual/bimanual_config.h"
#include "operator/bimanual/hand_path_check.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

std::unique_ptr<hb::SimulatedBimanualDevice> make_tool6_bimanual_device(const config::BimanualDeviceConfig& c,
                                                                        const device::Trajectory& path_H,
                                                                        const Eigen::Vector3d& offset_D,
                                                                        double period_s, Tool6Params* tool) {
  const std::string offset_field = "probe_3d.tool_device_offset_x_m";
  if (const auto issues = validate_bimanual_config(c); !issues.empty())
    throw std::invalid_argument(issues.front().field + ": " + issues.front().message);
  if (path_H.samples.empty() || path_H.end_effectors != 1 || !path_H.has_orientation)
    throw std::invalid_argument("tool6: the SIMULATED hand path needs one end-effector with orientations");
  if (!offset_D.allFinite() || offset_D.norm() > 5.0)
    throw std::invalid_argument(offset_field + ": the offset must be finite, within 5 m of D's origin");
  BimanualSetup setup = bimanual_setup(c);
  setup.sim.plant.control_period_s = period_s;
  const auto rest = hb::BimanualSimulation(setup.sim).resting_targets();  // where the hands rest at the start
  // The grasp: the tool upright (as the path's start asks) in the resting hand.
  const Eigen::Matrix3d R_E_P = rest[0].orientation_D.normalized().toRotationMatrix().transpose() *
                                path_H.samples.front().ee[0].orientation_H.normalized().toRotationMatrix();
  // The lead-in: the hand moves from its rest to the path's start while the
  // script holds its start (the hand6 scripts wait 5 s there for the voxmap).
  const device::TrajectorySample& s0 = path_H.samples.front();
  if (!(s0.t_s == 0.0 && path_H.samples.size() > 1 && path_H.samples[1].t_s >= kTool6LeadIn_s &&
        path_H.samples[1].ee[0].position_H == s0.ee[0].position_H &&
        path_H.samples[1].ee[0].orientation_H.angularDistance(s0.ee[0].orientation_H) == 0.0))
    throw std::invalid_argument("tool6: the SIMULATED hand path must start at t = 0 and hold its start for the " +
                                std::to_string(kTool6LeadIn_s) + " s lead-in from the hand's rest");
  std::vector<hb::HumanKey> keys;
  keys.reserve(path_H.samples.size() + 1);
  keys.push_back({0.0, rest[0]});
  for (const device::TrajectorySample& s : path_H.samples) {
    if (s.t_s < kTool6LeadIn_s) continue;
    hb::HumanKey k;  // holds the handle, dead-man pressed, no push
    k.t_s = s.t_s;
    k.target.position_D = offset_D + s.ee[0].position_H;
    k.target.orientation_D = Eigen::Quaterniond(s.ee[0].orientation_H.normalized().toRotationMatrix() * R_E_P.transpose());
    if (keys.size() == 1) {  // the start, reached at the lead-in's end
      hb::HumanKey start = k;
      start.t_s = kTool6LeadIn_s;
      if (k.t_s > kTool6LeadIn_s) keys.push_back(start);
    }
    keys.push_back(k);
  }
  const auto right = std::make_shared<const hb::HumanKeyScript>(std::move(keys));
  const auto left = std::make_shared<const hb::HumanKeyScript>(std::vector<hb::HumanKey>{{0.0, rest[1]}});
  auto dev = std::make_unique<hb::SimulatedBimanualDevice>(
      setup.sim, std::array<std::shared_ptr<const hb::HumanScript>, hb::kArms>{right, left});
  const auto issue = check_hand_path(
      *dev, hb::ArmSide::kRight,
      [&right](double t) { return hb::pose_D(right->at(t)); },
      path_H.samples.back().t_s);
  if (issue) {
    using Kind = HandPathIssue::Kind;
    std::string hint;
    if (issue->kind == Kind::kPosture) hint = "; move the path (the offset) where the right arm reaches it";
    throw std::invalid_argument(offset_field + ": " + issue->message + hint);
  }
  tool->T_H_D = Eigen::Isometry3d(Eigen::Translation3d(-offset_D));
  tool->R_E_P = R_E_P;
  tool->limits = dev->limits().ee[0];
  return dev;
}

}  // namespace hemm::op
