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

Arm5Vector arm_control_step(const ArmControlParams& p, ArmControlState& s, const Arm5Vector& q, const Arm5Vector& qd,
                            const Arm5Vector& bias, double dt, bool* saturated) {
  const double step = p.max_joint_speed * dt;
  for (int i = 0; i < kinematics::kArm5Dof; ++i) {
    const double d = std::clamp(s.q_goal(i) - s.q_ref(i), -step, step);
    s.q_ref(i) += d;
    s.qd_ref(i) = dt > 0 ? d / dt : 0.0;
  }
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
