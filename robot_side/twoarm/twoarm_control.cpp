#include "robot_side/twoarm/twoarm_control.h"

#include <algorithm>
#include <cmath>

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

namespace {

// The wrench the environment exerts on the gripper, at G, in A: the sensor's
// flange-on-gripper wrench balances it and the gripper's weight (statics).
hk::Wrench6 external_wrench_A(const ArmMount& mount, const hk::Arm7Frames& f, const hk::Wrench6& ft_J7,
                              const Eigen::Vector3d& gravity_A) {
  const Eigen::Isometry3d T_A_J7 = mount.T_A_Ar * f.joint(hk::kArm7Flange);
  const Eigen::Vector3d w_J7 = mount.gripper_J7.mass * (T_A_J7.linear().transpose() * gravity_A);
  const Eigen::Vector3d f_env = -ft_J7.head<3>() - w_J7;
  const Eigen::Vector3d t_env_fl = -ft_J7.tail<3>() - mount.gripper_J7.com.cross(w_J7);
  const Eigen::Vector3d t_env_G = t_env_fl - mount.T_J7_G.translation().cross(f_env);
  hk::Wrench6 out;
  out << T_A_J7.linear() * f_env, T_A_J7.linear() * t_env_G;
  return out;
}

bool holding(const TwoArmModel& model, const TwoArmParams& p, const std::array<ArmReading, kArms>& in,
             const TwoArmTargets& targets, std::size_t a) {
  return gripper_holding(model.arms[a].gripper, p.gripper, targets.gripper[a], in[a].gripper);
}

}  // namespace

void twoarm_control(const TwoArmModel& model, const TwoArmParams& p, const std::array<ArmReading, kArms>& in,
                    const TwoArmTargets& targets, TwoArmOutput& out) noexcept {
  std::array<hk::Arm7Frames, kArms> frames;
  std::array<hk::Arm7Vector, kArms> qd;
  for (std::size_t a = 0; a < kArms; ++a) {
    hk::forward_kinematics(model.arms[a].arm, in[a].q, frames[a]);
    qd[a] = in[a].qd;
  }
  // The gaps are reported either way; the repulsion acts only when asked.
  avoidance(model, p.avoidance, frames, qd, out.avoidance);
  if (!p.avoid) {
    for (auto& t : out.avoidance.tau) t.setZero();
  }
  // One object in both hands: the hands' mismatch at a share of the stiffness.
  std::array<Eigen::Isometry3d, kArms> T_d = targets.T_A_G;
  out.coupled = p.relative_stiffness_ratio < 1.0 && holding(model, p, in, targets, 0) && holding(model, p, in, targets, 1);
  if (out.coupled) {
    std::array<Eigen::Vector3d, kArms> pos, e;
    for (std::size_t a = 0; a < kArms; ++a) {
      pos[a] = grasp_pose_A(model.arms[a], frames[a]).translation();
      e[a] = T_d[a].translation() - pos[a];
    }
    const Eigen::Vector3d e_c = 0.5 * (e[0] + e[1]);
    const double r = std::max(0.0, p.relative_stiffness_ratio);
    for (std::size_t a = 0; a < kArms; ++a) T_d[a].translation() = pos[a] + e_c + r * (e[a] - e_c);
  }
  for (std::size_t a = 0; a < kArms; ++a) {
    const Side s = static_cast<Side>(a);
    const ArmMount& mount = model.arms[a];
    ImpedanceInput ii;
    ii.q = in[a].q;
    ii.qd = in[a].qd;
    ii.T_A_G_d = T_d[a];
    ii.tau_extra = out.avoidance.tau[a];
    arm_impedance(mount, model.gravity_Ar(s), p.arm[a], ii, frames[a], out.arm[a]);
    gripper_control(mount.gripper, p.gripper, targets.gripper[a], in[a].gripper, out.gripper[a]);
    out.command[a].tau = out.arm[a].tau;
    out.command[a].finger_force_N = out.gripper[a].finger_force_N;
    out.wrench_ext_A[a] = external_wrench_A(mount, frames[a], in[a].ft_J7, model.gravity_A);
  }
}

TwoArmTargets hold_targets(const TwoArmModel& model, const std::array<ArmReading, kArms>& in,
                           const std::array<double, kArms>& hold_force_N) {
  TwoArmTargets t;
  for (std::size_t a = 0; a < kArms; ++a) {
    t.T_A_G[a] = grasp_pose_A(model.arms[a], in[a].q);
    t.gripper[a].opening_m = in[a].gripper.finger_m[0] + in[a].gripper.finger_m[1];
    t.gripper[a].force_N = hold_force_N[a];
  }
  return t;
}

}  // namespace hemm::twoarm
