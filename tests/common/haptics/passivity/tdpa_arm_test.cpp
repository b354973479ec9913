// The 6-DoF TDPA of one arm on a SIMULATED 6-DoF direct loop: the hand and
// the robot's gripper as rigid bodies (rotation kept as a small-angle vector,
// enough for the 0.1-0.3 rad this test turns), the robot's Cartesian
// impedance with hemm's default gains, an oblique stiff plane (its normal
// mixes x, y and z, so the per-axis ports are coupled through the contact)
// and a stiff rotational stop about z. Energies are the test's own, per axis
// from the applied signals, as in tdpa_loop_sim.h.
#include "common/haptics/passivity/tdpa_arm.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace {

namespace td = hemm::haptics::tdpa;
using td::Vec6;

struct ArmLoopParams {
  double rtt_s = 0.3, loss = 0.0, duration_s = 8.0, dt = 1e-3;
  std::uint32_t seed = 1;
  double k_wall = 5000, k_stop = 40;  // N/m, N m/rad
  td::PcMode mode = td::PcMode::kControl;
};

struct ArmLoopResult {
  Vec6 op_violation = Vec6::Constant(-1e300), robot_violation = Vec6::Constant(-1e300);
  double op_out_J = 0, op_in_J = 0, robot_out_J = 0, robot_in_J = 0;
  double max_pos = 0, max_angle = 0, peak_force = 0, peak_torque = 0;
  double min_margin_J = 1e300;  // the code's own summary, only checked for sign
  bool finite = true;
};

ArmLoopResult run_arm_loop(const ArmLoopParams& p) {
  const Eigen::Vector3d n = Eigen::Vector3d(0.8, 0.36, -0.48).normalized();
  const double d = 0.04;  // plane n . x = d
  const double stop = 0.1;  // rad about z
  const auto ticks = static_cast<int>(std::lround(p.duration_s / p.dt));
  const int delay = static_cast<int>(std::lround(0.5 * p.rtt_s / p.dt));
  struct Msg {
    int seq;
    Vec6 value, in_J;
  };
  std::vector<std::vector<Msg>> to_robot(static_cast<std::size_t>(ticks + delay + 1)), to_op(to_robot);
  std::vector<Vec6> op_in_by(static_cast<std::size_t>(ticks)), robot_in_by(op_in_by);
  std::mt19937 rng(p.seed);
  auto lost = [&]() { return static_cast<double>(rng()) / 4294967296.0 < p.loss; };
  // Diagonal masses and inertias, human and robot gains (translation, rotation).
  const Vec6 m_h = (Vec6() << 0.5, 0.5, 0.5, 0.01, 0.01, 0.01).finished();
  const Vec6 k_h = (Vec6() << 200, 200, 200, 4, 4, 4).finished();
  const Vec6 b_h = (Vec6() << 10, 10, 10, 0.2, 0.2, 0.2).finished();
  const Vec6 m_r = (Vec6() << 2, 2, 2, 0.05, 0.05, 0.05).finished();
  const Vec6 k_r = (Vec6() << 1000, 1000, 1000, 60, 60, 60).finished();
  const Vec6 b_r = (Vec6() << 60, 60, 60, 2.5, 2.5, 2.5).finished();
  // The reference pushes 4 cm through the plane along its normal and turns 0.3 rad
  // about z, in 1.5 s, holds, goes back, repeats every 4 s.
  auto reference = [&](double t) {
    const double tc = std::fmod(t, 4.0);
    const double s = tc < 1.5 ? tc / 1.5 : (tc < 3.0 ? 1.0 : std::max(0.0, 1.0 - (tc - 3.0)));
    Vec6 x;
    x << (d + 0.04) * s * n, 0.0, 0.0, 0.3 * s;
    return x;
  };
  auto env = [&](const Vec6& x) {
    Vec6 f = Vec6::Zero();
    const double pen = n.dot(x.head<3>()) - d;
    if (pen > 0) f.head<3>() = -p.k_wall * pen * n;
    if (x[5] > stop) f[5] = -p.k_stop * (x[5] - stop);
    return f;
  };
  td::ArmSide op, rob;
  Vec6 x_h = Vec6::Zero(), v_h = Vec6::Zero(), x_r = Vec6::Zero(), v_r = Vec6::Zero(), target = Vec6::Zero();
  Vec6 f_recv = Vec6::Zero(), v_recv = Vec6::Zero();
  Vec6 op_in = Vec6::Zero(), op_out = Vec6::Zero(), rob_in = Vec6::Zero(), rob_out = Vec6::Zero();
  int op_newest = -1, rob_newest = -1;
  ArmLoopResult r;
  for (int k = 0; k < ticks; ++k) {
    const double t = k * p.dt;
    for (const Msg& m : to_op[static_cast<std::size_t>(k)]) {
      if (td::receive_peer<6>(op, static_cast<std::uint64_t>(m.seq), m.in_J) == td::Receive::kAccepted) f_recv = m.value;
      op_newest = std::max(op_newest, m.seq);
    }
    const td::ArmWrench shown = td::operator_arm_tick(op, td::ArmWrench{f_recv.head<3>(), f_recv.tail<3>()},
                                                      td::ArmTwist{v_h.head<3>(), v_h.tail<3>()}, p.dt, p.mode);
    const Vec6 f_disp = td::stack(shown);
    for (int i = 0; i < 6; ++i) {
      const double pw = -f_disp[i] * v_h[i];
      (pw > 0 ? op_in[i] : op_out[i]) += std::abs(pw) * p.dt;
    }
    op_in_by[static_cast<std::size_t>(k)] = op_in;
    r.op_violation = r.op_violation.cwiseMax(op_out - (op_newest >= 0 ? robot_in_by[op_newest] : Vec6::Zero()));
    if (!lost() && k + delay < ticks) to_robot[static_cast<std::size_t>(k + delay)].push_back(Msg{k, v_h, op.in_J});
    const Vec6 f_h = k_h.cwiseProduct(reference(t) - x_h) - b_h.cwiseProduct(v_h);
    v_h += (f_h + f_disp).cwiseQuotient(m_h) * p.dt;
    x_h += v_h * p.dt;

    for (const Msg& m : to_robot[static_cast<std::size_t>(k)]) {
      if (td::receive_peer<6>(rob, static_cast<std::uint64_t>(m.seq), m.in_J) == td::Receive::kAccepted) v_recv = m.value;
      rob_newest = std::max(rob_newest, m.seq);
    }
    const Vec6 f_env = env(x_r);
    const td::ArmTwist vs = td::robot_arm_tick(rob, td::ArmTwist{v_recv.head<3>(), v_recv.tail<3>()},
                                               td::ArmWrench{f_env.head<3>(), f_env.tail<3>()}, p.dt, p.mode);
    const Vec6 v_s = td::stack(vs);
    for (int i = 0; i < 6; ++i) {
      const double pw = f_env[i] * v_s[i];
      (pw > 0 ? rob_in[i] : rob_out[i]) += std::abs(pw) * p.dt;
    }
    robot_in_by[static_cast<std::size_t>(k)] = rob_in;
    r.robot_violation = r.robot_violation.cwiseMax(rob_out - (rob_newest >= 0 ? op_in_by[rob_newest] : Vec6::Zero()));
    if (!lost() && k + delay + 1 < ticks) to_op[static_cast<std::size_t>(k + delay + 1)].push_back(Msg{k, f_env, rob.in_J});
    target += v_s * p.dt;
    const Vec6 u = k_r.cwiseProduct(target - x_r) - b_r.cwiseProduct(v_r);  // hemm's impedance form
    for (int s = 0; s < 10; ++s) {
      v_r += (u + env(x_r)).cwiseQuotient(m_r) * (p.dt / 10);
      x_r += v_r * (p.dt / 10);
    }
    r.max_pos = std::max({r.max_pos, x_h.head<3>().norm(), x_r.head<3>().norm()});
    r.max_angle = std::max({r.max_angle, x_h.tail<3>().norm(), x_r.tail<3>().norm()});
    r.peak_force = std::max(r.peak_force, f_env.head<3>().norm());
    r.peak_torque = std::max(r.peak_torque, f_env.tail<3>().norm());
    r.min_margin_J = std::min(r.min_margin_J, td::summarize(op).min_margin_J);
    if (!x_h.allFinite() || !x_r.allFinite()) {
      r.finite = false;
      break;
    }
  }
  r.op_in_J = op_in.sum();
  r.op_out_J = op_out.sum();
  r.robot_in_J = rob_in.sum();
  r.robot_out_J = rob_out.sum();
  return r;
}

TEST(TdpaArm, SixDofLoopStaysPassivePerAxis) {
  for (double rtt : {0.0, 0.3, 1.0, 3.0}) {
    for (double loss : {0.0, 0.05}) {
      ArmLoopParams p;
      p.rtt_s = rtt;
      p.loss = loss;
      p.seed = 7;
      const ArmLoopResult r = run_arm_loop(p);
      std::printf("6-DoF PC rtt %4.0f ms loss %.2f: op in %.3f out %.3f J, robot in %.3f out %.3f J, peak %.1f N "
                  "%.2f N m, max %.3f m %.3f rad\n",
                  rtt * 1e3, loss, r.op_in_J, r.op_out_J, r.robot_in_J, r.robot_out_J, r.peak_force, r.peak_torque,
                  r.max_pos, r.max_angle);
      ASSERT_TRUE(r.finite);
      for (int i = 0; i < 6; ++i) {
        EXPECT_LE(r.op_violation[i], 1e-9) << "axis " << i << " rtt " << rtt;
        EXPECT_LE(r.robot_violation[i], 1e-9) << "axis " << i << " rtt " << rtt;
      }
      EXPECT_GE(r.min_margin_J, -1e-12);
      // Bounded where the delay dominates (at 0 ms the robot's own dynamics
      // drive the contact, as in the 1-DoF loop: tdpa_loop_test.cpp): within
      // the reference's reach (0.08 m, 0.3 rad) and a force of the order of
      // the human's springs' hold (200 N/m x 4 cm).
      if (rtt > 0) {
        EXPECT_LT(r.max_pos, 0.12);
        EXPECT_LT(r.max_angle, 0.45);
        EXPECT_LT(r.peak_force, 40.0);
      }
    }
  }
}

TEST(TdpaArm, WithoutPcTheDelayedContactGeneratesEnergy) {
  ArmLoopParams p;
  p.rtt_s = 1.0;
  p.mode = td::PcMode::kObserveOnly;
  const ArmLoopResult r = run_arm_loop(p);
  std::printf("6-DoF no PC rtt 1000 ms: op in %.3f out %.3f J, robot in %.3f out %.3f J, worst axis excess %.3f J\n",
              r.op_in_J, r.op_out_J, r.robot_in_J, r.robot_out_J, r.op_violation.maxCoeff());
  EXPECT_GT(r.op_violation.maxCoeff(), 1.0);
}

// A constant twist for 1 s in 1000 ticks: the position moves by v, the
// orientation turns by |omega| about omega's axis (closed form).
TEST(TdpaArm, AdvanceTargetIntegratesTheTwist) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Matrix3d R0 = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.linear() = R0;
  T.translation() = Eigen::Vector3d(0.5, -0.2, 0.9);
  const td::ArmTwist tw{Eigen::Vector3d(0.1, -0.05, 0.02), Eigen::Vector3d(0.0, 0.6, -0.8)};
  Eigen::Isometry3d X = T;
  for (int k = 0; k < 1000; ++k) X = td::advance_target(X, tw, 1e-3);
  EXPECT_LT((X.translation() - (T.translation() + tw.v)).norm(), 1e-12);
  const Eigen::Matrix3d expect = Eigen::AngleAxisd(1.0, Eigen::Vector3d(0, 0.6, -0.8)).toRotationMatrix() * R0;
  EXPECT_LT((X.linear() - expect).norm(), 1e-9);
  // Zero twist: unchanged.
  EXPECT_TRUE(td::advance_target(T, td::ArmTwist{}, 1e-3).isApprox(T, 0.0));
}

}  // namespace
