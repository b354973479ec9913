// The VPS scenes with the SIMULATED bimanual interface in the servo loop
// (device.type "sim-bimanual" with vps.hands): the simulated human of each
// arm follows its object's scripted path (scenes.h), mapped into the device
// frame D through the inverse of the task's own mapping (vps_task.h:
// end_effector_pose_H), so that a rigid hand would put the object exactly on
// its path. The hand is not rigid: it pulls the handle towards that target
// with its arm's spring (human.h: 300 N/m), and the rendered VPS wrench
// pushes it back, as on a real hand. The device reports its own limits
// (bimanual_limits), from which the task designs the couplings.
//
// The scenes sit about the origin of W, the arms' workspace is a box in
// front of the column (arm_control.h: default_workspace), and two hands
// cannot hold two objects that touch at one place: each arm has its own
// T_W_H (vps.right/left.h_origin) and grasp (T_E_M), explicit in the config
// and checked here against where each SIMULATED hand rests.
#pragma once

#include <array>
#include <memory>

#include "config_operator.pb.h"
#include "operator/bimanual/hand_path_check.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/vps/vps_session.h"
#include "operator/vps/vps_task.h"

namespace hemm::op {

// One arm's target: where its hand (the handle's E frame, in D) must be for
// the object to be on the scene's path. const and allocation-free (called on
// the servo thread by the device's write()).
class SceneHandScript final : public device::bimanual::HumanScript {
 public:
  // arm 0: the right object's path, 1: the left's; the hand holds the
  // path's start for start_hold_s before following it.
  SceneHandScript(SceneHands path, int arm, const VpsEndEffectorParams& mapping, double start_hold_s = 0.0);
  device::bimanual::HumanTarget at(double t_s) const noexcept override;
  Eigen::Isometry3d T_D_E(double t_s) const noexcept;
  double duration_s() const noexcept { return start_hold_s_ + path_.duration_s; }

 private:
  SceneHands path_;
  int arm_;
  VpsEndEffectorParams mapping_;
  double start_hold_s_;
};

// How long the SIMULATED humans hold their paths' starts in
// make_vps_bimanual_device: the device starts at rest on the plant's true
// model, and its controllers, on the nominal one (a few per cent off), let
// the held hands sag by ~2-3 mm at first with LWR-like actuators; a real
// operator takes hold and steadies the handles before starting, and the
// humans' voluntary effort (human.h) takes the sag out in well under 1 s.
inline constexpr double kStartHold_s = 1.0;


// The SIMULATED bimanual device of cfg.device().bimanual() at `period_s`,
// its humans following scene `scene`'s paths through `mapping` (right: 0,
// left: 1). Checks, with errors "field: message" (std::invalid_argument):
// the bimanual block; each path with check_hand_path (hand_path_check.h:
// start at the hand's rest, workspace, reach and elbow bend, table zone;
// for a start off the rest the message gives the h_origin and grasp that
// would put it there).
std::unique_ptr<device::bimanual::SimulatedBimanualDevice> make_vps_bimanual_device(
    const config::OperatorConfig& cfg, const std::string& scene,
    const std::array<VpsEndEffectorParams, device::kMaxEndEffectors>& mapping, double period_s);

}  // namespace hemm::op
