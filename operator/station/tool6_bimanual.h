// The 6-DoF probe tool (tool6_explorer.h) held by the RIGHT arm (end-effector
// 0) of the SIMULATED bimanual device in the networked operator station
// (device.type "sim-bimanual" with probe_3d.tool "pointshell").
//
// The right arm's SIMULATED human follows the same hand script as the rigid
// hand (make_hand6_trajectory, H), mapped into the device frame D with a
// fixed offset: D and H share their axes (x forward from the operator, or
// from the robot; z up), and H's origin sits at `offset_D` in D, so the
// hand's target is T_D_E(t) = offset_D + T_H_P(t), turned by the grasp R_E_P
// that makes the upright tool start in the hand's resting grasp. The human
// pulls its handle towards that target with its arm's spring (human.h), so
// the hand yields to the rendered wrench: the path the tool follows (and the
// station logs as the goal) is the device hand's, not the script's. The left
// arm's human holds its hand still where it rests.
//
// The offset puts the path where the right arm reaches it well, which is not
// where its hand rests: the human first moves the hand from its rest to the
// path's start over kTool6LeadIn_s while the script holds its start (the
// hand6 scripts wait there 5 s for the voxmap), so the script's time is
// unchanged. The whole path, lead-in included, is checked before the device
// runs (hand_path_check.h, as the VPS scenes' paths): inside the arm's
// workspace, within its reach with the elbow bent, out of the table zone.
#pragma once

#include <memory>

#include <Eigen/Geometry>

#include "config_operator.pb.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/device/trajectory_csv.h"
#include "operator/station/tool6_explorer.h"

namespace hemm::op {

inline constexpr double kTool6LeadIn_s = 4.0;

// The SIMULATED bimanual device of block `c` at `period_s`, its right human
// following `path_H` (one end-effector with orientations) shifted by
// `offset_D`. On success sets tool->T_H_D, tool->R_E_P and tool->limits (the
// right arm's); throws std::invalid_argument ("field: message") on a bad
// block, path or offset, leaving *tool unchanged.
std::unique_ptr<device::bimanual::SimulatedBimanualDevice> make_tool6_bimanual_device(
    const config::BimanualDeviceConfig& c, const device::Trajectory& path_H, const Eigen::Vector3d& offset_D,
    double period_s, Tool6Params* tool);

}  // namespace hemm::op
