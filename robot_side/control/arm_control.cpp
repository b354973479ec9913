#include "robot_side/control/arm_control.h"

#include <algorithm>
#include <cmath>

namespace hemm::robot {

bool set_arm_goal(const kinematics::Arm5Model& model, ArmControlState& s, const Arm5Vector& q_goal) {
  const Arm5Vector c = kinematics::clamp_to_limits(model, q_goal);
  s.q_goal = c;
  return !(c.array() == q_goal.array()).all();
}

void hold_arm(ArmControlState& s) {
  s.q_goal = s.q_ref;
  s.qd_ref.setZero();
}

void reset_arm(ArmControlState& s, const Arm5Vector& q) {
  s.q_goal = q;
  s.q_ref = q;
  s.qd_ref.setZero();
}

Arm5Vector arm_reference_after(const Arm5Vector& q_from, const Arm5Vector& q_to, double travel) {
  Arm5Vector q = q_from;
  for (int i = 0; i < kinematics::kArm5Dof; ++i) q(i) += std::clamp(q_to(i) - q_from(i), -travel, travel);
  return q;
}

Arm5Vector arm_control_step(const ArmControlParams& p, ArmControlState& s, const Arm5Vector& q, const Arm5Vector& qd,
                            const Arm5Vector& bias, double dt, bool* saturated) {
  const Arm5Vector next = arm_reference_after(s.q_ref, s.q_goal, p.max_joint_speed * dt);
  s.qd_ref = dt > 0 ? Arm5Vector((next - s.q_ref) / dt) : Arm5Vector::Zero();
  s.q_ref = next;
  Arm5Vector tau = p.kp * (s.q_ref - q) + p.kd * (s.qd_ref - qd) + bias;
  bool sat = false;
  for (int i = 0; i < kinematics::kArm5Dof; ++i) {
    if (!std::isfinite(tau(i))) tau(i) = 0.0;
    if (std::abs(tau(i)) > p.max_joint_torque) {
      sat = true;
      tau(i) = std::clamp(tau(i), -p.max_joint_torque, p.max_joint_torque);
    }
  }
  if (saturated) *saturated = sat;
  return tau;
}

}  // namespace hemm::robot
