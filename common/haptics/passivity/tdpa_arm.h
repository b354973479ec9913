#pragma once
// The TDPA of one arm (6 DoF): force and torque against velocity and
// angular velocity, each axis its own port in the robot's torso frame A
// (tdpa.h). Axes 0-2: force_A . v_A; axes 3-5: torque_A . omega_A. Passivity
// per axis implies it for their sum, and a rotation never borrows energy a
// translation brought in.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/haptics/passivity/tdpa.h"

namespace hemm::haptics::tdpa {

using ArmSide = Side<6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

struct ArmWrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   // N, in A
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  // N m, in A
};

struct ArmTwist {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();      // m/s, in A
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  // rad/s, in A
};

inline Vec6 stack(const ArmWrench& w) noexcept {
  Vec6 x;
  x << w.force, w.torque;
  return x;
}
inline Vec6 stack(const ArmTwist& t) noexcept {
  Vec6 x;
  x << t.v, t.omega;
  return x;
}

// Robot end: the twist the arm's target moves with this tick, from the
// operator's (newest) twist and the wrist's measured wrench (the
// environment's on the gripper at G).
inline ArmTwist robot_arm_tick(ArmSide& s, const ArmTwist& received, const ArmWrench& env, double dt_s,
                               PcMode mode = PcMode::kControl) noexcept {
  const Vec6 v = robot_tick<6>(s, stack(received), stack(env), dt_s, mode);
  return ArmTwist{v.head<3>(), v.tail<3>()};
}

// Operator end: the wrench displayed on the hand this tick, from the robot's
// (newest) wrench mapped to the hand and the hand's twist, both in A.
inline ArmWrench operator_arm_tick(ArmSide& s, const ArmWrench& received, const ArmTwist& hand, double dt_s,
                                   PcMode mode = PcMode::kControl) noexcept {
  const Vec6 f = operator_tick<6>(s, stack(received), stack(hand), dt_s, mode);
  return ArmWrench{f.head<3>(), f.tail<3>()};
}

// What a side reports (the station's JSON, ArmsState / ArmsCommand
// PassivityPort): sums over the six axes and the smallest axis margin.
struct ArmPortSummary {
  double in_J = 0.0;
  double out_J = 0.0;
  double peer_in_J = 0.0;
  double dissipated_J = 0.0;
  double min_margin_J = 0.0;  // min over axes of peer_in_J - out_J (>= 0 with the PC)
  std::uint64_t pc_active_ticks = 0;
};

inline ArmPortSummary summarize(const ArmSide& s) noexcept {
  return ArmPortSummary{s.in_J.sum(), s.out_J.sum(), s.peer_in_J.sum(), s.dissipated_J.sum(),
                        margin_J<6>(s).minCoeff(), s.pc_active_ticks};
}

// The robot end's target after one tick of the (PC-scaled) twist: the
// position moves by v dt, the orientation turns by omega dt about A's axes
// (left-multiplied: omega is in A).
inline Eigen::Isometry3d advance_target(const Eigen::Isometry3d& T_A_G, const ArmTwist& t, double dt_s) noexcept {
  Eigen::Isometry3d out = T_A_G;
  out.translation() += t.v * dt_s;
  const double angle = t.omega.norm() * dt_s;
  if (angle > 0.0) {
    out.linear() = (Eigen::AngleAxisd(angle, t.omega.normalized()) * Eigen::Quaterniond(T_A_G.linear()))
                       .normalized()
                       .toRotationMatrix();
  }
  return out;
}

}  // namespace hemm::haptics::tdpa
