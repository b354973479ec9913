// The robot end of the direct force-feedback mode (issue 25, part 5) on the
// SIMULATED two-arm robot, in simulated time (one step per 1 ms period, a
// fake operator at 100 Hz): a DirectTwist moves G as integrated (MuJoCo
// truth); the robot end's output energy, recomputed here from the wrench
// the observer was given and the twist the target really moved with, never
// exceeds the operator's input energy the robot had received; a stale twist
// stops the arm; bad twists and passivity ports are refused whole and
// change nothing.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "common/net/datagram.h"
#include "robot_side/twoarm/twoarm_robot.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace hk = hemm::kinematics;
namespace ht = hemm::twoarm;
namespace hw = hemm::wire;
namespace td = hemm::haptics::tdpa;

namespace direct_test {

using hemm::test::kWorkbenchScene;
using Vec6 = td::Vec6;

void set_vec(const Eigen::Vector3d& v, hemm::proto::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

// One arm's direct part of a command: its twist and the operator end's input energies.
struct ArmDirect {
  uint32_t index = 0;
  td::ArmTwist twist;
  std::optional<Vec6> energy_in_J;
};

hw::ArmsCommand direct_command(bool deadman, std::initializer_list<ArmDirect> arms) {
  hw::ArmsCommand c;
  c.set_deadman(deadman);
  for (const ArmDirect& a : arms) {
    hw::DirectTwist* t = c.add_twist();
    t->set_index(a.index);
    set_vec(a.twist.v, t->mutable_v_a());
    set_vec(a.twist.omega, t->mutable_omega_a());
    if (a.energy_in_J) {
      hw::PassivityPort* p = c.add_passivity();
      p->set_index(a.index);
      for (int i = 0; i < 6; ++i) p->add_energy_in_j((*a.energy_in_J)[i]);
    }
  }
  return c;
}

ht::TwoArmRobotOptions options(td::PcMode mode, bool measured) {
  ht::TwoArmRobotOptions o;
  o.pc_mode = mode;
  o.direct_feedback_measured = measured;
  return o;
}

struct DirectDriver {
  explicit DirectDriver(ht::TwoArmRobotOptions o = {}) : robot(kWorkbenchScene, o) { robot.set_link(true, true); }
  ht::TwoArmRobot robot;
  uint64_t seq = 0;
  bool send(const hw::ArmsCommand& c) { return robot.command(c, ++seq, robot.time_ns()); }
  // Re-arms with zero twists on both arms (a neutral, then a pressed command).
  void arm_direct(const Vec6& budget) {
    EXPECT_TRUE(send(direct_command(false, {{0, {}, budget}, {1, {}, budget}})));
    EXPECT_TRUE(send(direct_command(true, {{0, {}, budget}, {1, {}, budget}})));
    ASSERT_TRUE(robot.armed());
  }
  Eigen::Vector3d grasp(ht::Side s) const { return robot.sim().grasp_site_A(s).translation(); }
};

Vec6 constant(double j) { return Vec6::Constant(j); }

}  // namespace direct_test

using namespace direct_test;

TEST(TwoArmDirect, TwistMovesTheGraspFrameAsIntegrated) {
  DirectDriver d;
  const Vec6 budget = constant(1e3);  // ample: the controller has no reason to act
  d.arm_direct(budget);
  for (int k = 0; k < 300; ++k) {  // settle at the hold
    if (k % 10 == 0) {
      ASSERT_TRUE(d.send(direct_command(true, {{0, {}, budget}, {1, {}, budget}})));
    }
    d.robot.step();
  }
  const Eigen::Isometry3d T0 = d.robot.active_targets().T_A_G[0];
  const Eigen::Vector3d left0 = d.grasp(ht::Side::kLeft);
  const td::ArmTwist tw{Eigen::Vector3d(0.05, -0.03, 0.02), Eigen::Vector3d(0.0, 0.0, 0.2)};
  // 1 s of the twist on arm 0 (a command every 10 ms), then zero twists.
  for (int k = 0; k < 1000; ++k) {
    if (k % 10 == 0) {
      ASSERT_TRUE(d.send(direct_command(true, {{0, tw, budget}, {1, {}, budget}})));
    }
    d.robot.step();
  }
  ASSERT_TRUE(d.send(direct_command(true, {{0, {}, budget}, {1, {}, budget}})));
  for (int k = 0; k < 1500; ++k) {
    if (k % 10 == 0) d.send(direct_command(true, {{0, {}, budget}, {1, {}, budget}}));
    d.robot.step();
  }
  EXPECT_TRUE(d.robot.following());
  EXPECT_EQ(d.robot.port(0).pc_active_ticks, 0u);
  // The target: 1000 ticks of 1 ms, closed form.
  const Eigen::Isometry3d T1 = d.robot.active_targets().T_A_G[0];
  EXPECT_LT((T1.translation() - (T0.translation() + tw.v * 1.0)).norm(), 1e-9);
  const Eigen::Matrix3d R_expected = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix() * T0.linear();
  EXPECT_LT((T1.linear() - R_expected).norm(), 1e-9);
  // G (MuJoCo truth) got there: 6.2 cm and 11.5 degrees away from the start.
  const Eigen::Isometry3d G = d.robot.sim().grasp_site_A(ht::Side::kRight);
  EXPECT_LT((G.translation() - T1.translation()).norm(), 0.004);
  EXPECT_LT(Eigen::AngleAxisd(G.linear() * T1.linear().transpose()).angle(), 0.03);
  // The other arm, with zero twists, stayed.
  EXPECT_LT((d.grasp(ht::Side::kLeft) - left0).norm(), 0.002);
  // The ArmsState carries both arms' ports and fed-back wrenches, within one datagram.
  hw::StreamMessage m;
  d.robot.state(m.mutable_arms_state());
  EXPECT_EQ(m.arms_state().passivity_size(), 2);
  EXPECT_EQ(m.arms_state().direct_wrench_size(), 2);
  EXPECT_LE(m.ByteSizeLong(), hemm::net::kMaxDatagramPayloadBytes);
  std::printf("ArmsState with both arms direct: %zu bytes (payload limit %zu)\n", m.ByteSizeLong(),
              hemm::net::kMaxDatagramPayloadBytes);
}

// The robot end's passivity: per axis, the energy that left the channel at
// the robot (the wrench fed back against the twist the target moved with,
// summed by this test) stays within the operator's input energy the robot had
// received, at every tick, with either wrench fed back; without the
// controller the same run exceeds it (so the check can fail).
namespace direct_test {

struct PassivityRun {
  double worst_excess_J = -1e9;  // max over ticks and axes of out - received budget
  double dissipated_J = 0.0;
  Vec6 out_J = Vec6::Zero();
};

PassivityRun push_down(td::PcMode mode, bool measured) {
  DirectDriver d(options(mode, measured));
  PassivityRun r;
  // The operator's budget grows by 2 mJ/s per axis: far less than pressing
  // down and turning at these speeds takes out.
  auto budget_at = [](int k) { return constant(0.002 * k * 1e-3); };
  d.arm_direct(budget_at(0));
  Vec6 received = budget_at(0);
  Vec6 out = Vec6::Zero(), in = Vec6::Zero();
  // Down at 0.15 m/s towards the bench (the arm's joints stop G some 19 cm
  // above it, so the target is held at the yield), sideways and turning,
  // for 2 s.
  const td::ArmTwist tw{Eigen::Vector3d(0.04, 0.02, -0.15), Eigen::Vector3d(0.3, 0.0, -0.2)};
  for (int k = 1; k <= 2000; ++k) {
    if (k % 10 == 0) {
      EXPECT_TRUE(d.send(direct_command(true, {{0, tw, budget_at(k)}, {1, {}, budget_at(k)}})));
      received = budget_at(k);
    }
    const hk::Wrench6 f = d.robot.feedback_A(0);  // what this tick's observer is given
    const Eigen::Vector3d p0 = d.robot.active_targets().T_A_G[0].translation();
    d.robot.step();
    const td::ArmTwist& v = d.robot.tracked_twist(0);
    // The twist is what the target moved with (up to the yield at the force limit).
    const Eigen::Vector3d moved = d.robot.active_targets().T_A_G[0].translation() - p0;
    if (!d.robot.control_output().arm[0].force_limited) {
      EXPECT_LT((moved - v.v * 1e-3).norm(), 1e-12);
    }
    const Vec6 power = f.cwiseProduct(td::stack(v));
    for (int i = 0; i < 6; ++i) {
      if (power[i] >= 0.0) {
        in[i] += power[i] * 1e-3;
      } else {
        out[i] -= power[i] * 1e-3;
      }
      r.worst_excess_J = std::max(r.worst_excess_J, out[i] - received[i]);
    }
  }
  r.dissipated_J = d.robot.port(0).dissipated_J.sum();
  r.out_J = out;
  // The library's books agree with the test's (same signals).
  EXPECT_LT((d.robot.port(0).out_J - out).norm(), 1e-9);
  return r;
}

}  // namespace direct_test

TEST(TwoArmDirect, RobotEndOutputStaysWithinReceivedEnergy) {
  for (const bool measured : {false, true}) {
    SCOPED_TRACE(measured ? "measured wrench" : "spring wrench");
    const PassivityRun on = push_down(td::PcMode::kControl, measured);
    EXPECT_LE(on.worst_excess_J, 1e-9);
    EXPECT_GT(on.dissipated_J, 0.0);
    const PassivityRun off = push_down(td::PcMode::kObserveOnly, measured);
    EXPECT_GT(off.worst_excess_J, 1e-3);
    std::printf("direct, %s wrench: controller on: worst excess %.3g J, dissipated %.3g J; off: excess %.3g J\n",
                measured ? "measured" : "spring", on.worst_excess_J, on.dissipated_J, off.worst_excess_J);
  }
}

TEST(TwoArmDirect, StaleTwistStopsTheArm) {
  DirectDriver d;
  const Vec6 budget = constant(1e3);
  d.arm_direct(budget);
  const td::ArmTwist tw{Eigen::Vector3d(0.0, 0.08, 0.0), Eigen::Vector3d::Zero()};
  for (int k = 0; k < 300; ++k) {
    if (k % 10 == 0) {
      ASSERT_TRUE(d.send(direct_command(true, {{0, tw, budget}, {1, {}, budget}})));
    }
    d.robot.step();
  }
  // The operator falls silent after its command at 290 ms. The twist holds
  // for 50 ms (direct_twist_hold_ns) after that command's send time, then is
  // zero; the watchdog (250 ms) has not expired yet.
  const Eigen::Vector3d p_last = d.robot.active_targets().T_A_G[0].translation();
  for (int k = 0; k < 60; ++k) d.robot.step();
  const Eigen::Vector3d p_stop = d.robot.active_targets().T_A_G[0].translation();
  EXPECT_LE((p_stop - p_last).norm(), 0.08 * 0.051 + 1e-9);
  const uint64_t stale0 = d.robot.counters().direct_stale_ticks;
  EXPECT_GT(stale0, 0u);
  for (int k = 0; k < 140; ++k) d.robot.step();
  EXPECT_EQ(d.robot.safety() & hw::SAFETY_WATCHDOG, 0u);
  EXPECT_TRUE(d.robot.following());
  EXPECT_EQ((d.robot.active_targets().T_A_G[0].translation() - p_stop).norm(), 0.0);
  EXPECT_EQ(d.robot.counters().direct_stale_ticks, stale0 + 2 * 140);  // both arms
  // G settles at the stopped target (truth).
  EXPECT_LT((d.grasp(ht::Side::kRight) - p_stop).norm(), 0.004);
}

TEST(TwoArmDirect, BadTwistOrPortIsRefusedAndChangesNothing) {
  DirectDriver d;
  const Vec6 budget = constant(0.5);
  d.arm_direct(budget);
  const td::ArmTwist tw{Eigen::Vector3d(0.0, 0.0, 0.05), Eigen::Vector3d::Zero()};
  for (int k = 0; k < 100; ++k) {
    if (k % 10 == 0) {
      ASSERT_TRUE(d.send(direct_command(true, {{0, tw, budget}})));
    }
    d.robot.step();
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const td::ArmTwist fast{Eigen::Vector3d(0.3, 0.0, 0.0), Eigen::Vector3d::Zero()};
  struct Case {
    const char* what;
    hw::ArmsCommand cmd;
    hw::ArmsRefusalReason reason;
    uint32_t index;
  };
  std::vector<Case> cases;
  cases.push_back({"nan twist", direct_command(true, {{0, {Eigen::Vector3d(nan, 0, 0), {}}, budget}}),
                   hw::ARMS_REFUSAL_NONFINITE, 0});
  cases.push_back({"inf omega", direct_command(true, {{1, {{}, Eigen::Vector3d(0, inf, 0)}, budget}}),
                   hw::ARMS_REFUSAL_NONFINITE, 1});
  cases.push_back({"arm 2", direct_command(true, {{0, fast, budget}, {2, fast, budget}}), hw::ARMS_REFUSAL_UNKNOWN_ARM, 2});
  cases.push_back({"arm twice", direct_command(true, {{0, fast, budget}, {0, fast, budget}}),
                   hw::ARMS_REFUSAL_UNKNOWN_ARM, 0});
  {
    hw::ArmsCommand c = direct_command(true, {{0, fast, budget}});
    ht::TwoArmTargets t = d.robot.active_targets();
    hw::ArmsCommand poses;
    ht::to_wire(t, true, &poses);
    *c.add_arm() = poses.arm(0);
    cases.push_back({"pose and twist", c, hw::ARMS_REFUSAL_BAD_POSE, 0});
  }
  cases.push_back({"negative energy", direct_command(true, {{0, fast, Vec6(0.5, 0.5, -0.1, 0.5, 0.5, 0.5)}}),
                   hw::ARMS_REFUSAL_PASSIVITY, 0});
  cases.push_back({"nan energy", direct_command(true, {{1, fast, Vec6(0.5, 0.5, 0.5, nan, 0.5, 0.5)}}),
                   hw::ARMS_REFUSAL_PASSIVITY, 1});
  cases.push_back({"decreasing energy", direct_command(true, {{0, fast, Vec6(0.5, 0.5, 0.5, 0.5, 0.49, 0.5)}}),
                   hw::ARMS_REFUSAL_PASSIVITY, 0});
  {
    hw::ArmsCommand c = direct_command(true, {{0, fast, budget}});
    c.mutable_passivity(0)->mutable_energy_in_j()->RemoveLast();
    cases.push_back({"five energies", c, hw::ARMS_REFUSAL_PASSIVITY, 0});
  }
  {
    hw::ArmsCommand c = direct_command(true, {{0, fast, budget}});
    c.mutable_passivity(0)->set_index(7);
    cases.push_back({"port of arm 7", c, hw::ARMS_REFUSAL_UNKNOWN_ARM, 7});
  }
  uint64_t refusals = d.robot.counters().refusals;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const ht::TwoArmTargets before = d.robot.active_targets();
    const td::ArmSide port0 = d.robot.port(0), port1 = d.robot.port(1);
    EXPECT_FALSE(d.send(c.cmd));
    EXPECT_EQ(d.robot.counters().refusals, ++refusals);
    EXPECT_EQ(d.robot.counters().last_refusal, c.reason);
    EXPECT_EQ(d.robot.counters().last_refused_index, c.index);
    EXPECT_EQ(d.robot.port(0).peer_in_J, port0.peer_in_J);
    EXPECT_EQ(d.robot.port(1).peer_in_J, port1.peer_in_J);
    EXPECT_EQ(d.robot.port(0).peer_seq, port0.peer_seq);
    // The twist did not change: the next 5 ticks move the target by the old one.
    for (int k = 0; k < 5; ++k) d.robot.step();
    const Eigen::Vector3d moved = d.robot.active_targets().T_A_G[0].translation() - before.T_A_G[0].translation();
    EXPECT_LT((moved - tw.v * 5e-3).norm(), 1e-12);
    EXPECT_EQ((d.robot.active_targets().T_A_G[1].matrix() - before.T_A_G[1].matrix()).norm(), 0.0);
    // Keep the twist fresh for the next case.
    ASSERT_TRUE(d.send(direct_command(true, {{0, tw, budget}})));
  }
}

// Zero delay, closed loop, on the MuJoCo arm: a SIMULATED hand (0.5 kg,
// the human a 200 N/m, 10 N s/m spring-damper to a reference) drives arm 0's
// grasp frame down at 0.1 m/s towards a reference 5 cm below the bench top
// and holds it there for 2 s; the operator end (tdpa operator_arm_tick)
// shows the fed-back wrench on the hand. Both ends' controllers on, messages
// each way every 1 ms tick. From the rest posture the arm cannot reach that
// low: its joints stop G about 19 cm above the bench, touching nothing (the
// wrist sensor reads 0). Fed back as the spring wrench the operator feels
// that stop (the wrist limit's 40 N) and the hand rests where the statics
// say; fed back as the measured wrench the hand feels nothing and goes on
// to its reference while the arm cannot follow.
namespace direct_test {

struct ClosedLoopResult {
  double worst_robot_excess_J = -1e9, worst_operator_excess_J = -1e9;
  double peak_contact_N = 0.0;   // the wrist sensor's |f_z| (the bench on the gripper)
  double hold_contact_N = 0.0;   // mean over the last 0.5 s of the press
  double hold_contact_sd_N = 0.0;
  double hold_shown_N = 0.0;     // mean force shown on the hand, same window
  double hold_gap_m = 0.0;       // the true grasp frame's height above the bench top, same window
  double hold_hand_offset_m = 0.0;  // where the hand rests less its reference (end of the press)
  double min_arm_bench_m = 0.0;     // the avoidance's smallest link-bench gap at the end
  bool force_limited = false;       // the spring at the wrist limit at the end
};

ClosedLoopResult zero_delay_press(bool measured) {
  DirectDriver d(options(td::PcMode::kControl, measured));
  td::ArmSide op;  // the operator end's port
  const Vec6 zero6 = Vec6::Zero();
  d.arm_direct(zero6);
  const double z0 = d.grasp(ht::Side::kRight).z();
  const double bench = 0.75;
  const double m = 0.5, k = 200.0, b = 10.0, dt = 1e-3;
  double x = 0.0, v = 0.0;  // the hand along z, from the start
  const double depth = (z0 - bench) + 0.05;
  ClosedLoopResult r;
  Vec6 op_out = Vec6::Zero(), robot_in_sent = Vec6::Zero();
  double sum = 0.0, sum2 = 0.0, shown_sum = 0.0, gap_sum = 0.0;
  int n = 0;
  const int ticks = static_cast<int>((depth / 0.1 + 2.0) * 1000.0);
  for (int k_tick = 0; k_tick < ticks; ++k_tick) {
    const double t = k_tick * dt;
    const double ref = -std::min(depth, 0.1 * t);
    // Operator end: show the robot's newest wrench on the hand.
    td::receive_peer<6>(op, static_cast<uint64_t>(k_tick + 1), robot_in_sent);
    const hk::Wrench6 f_recv = d.robot.feedback_A(0);
    td::ArmTwist hand;
    hand.v.z() = v;
    const td::ArmWrench shown = td::operator_arm_tick(op, {f_recv.head<3>(), f_recv.tail<3>()}, hand, dt);
    // The operator end's output energy, from the shown force and the hand's velocity (P_in = -f v).
    const double p = -shown.force.z() * v;
    if (p < 0.0) op_out[2] -= p * dt;
    r.worst_operator_excess_J = std::max(r.worst_operator_excess_J, op_out[2] - robot_in_sent[2]);
    // The hand: the human's spring-damper and the shown force.
    const double a = (k * (ref - x) - b * v + shown.force.z()) / m;
    v += a * dt;
    x += v * dt;
    // Robot end: the hand's twist and the operator's energy, no delay.
    td::ArmTwist cmd;
    cmd.v.z() = v;
    EXPECT_TRUE(d.send(direct_command(true, {{0, cmd, op.in_J}, {1, {}, zero6}})));
    d.robot.step();
    robot_in_sent = d.robot.port(0).in_J;
    const double fz = std::abs(d.robot.control_output().wrench_ext_A[0].z());
    r.peak_contact_N = std::max(r.peak_contact_N, fz);
    r.worst_robot_excess_J =
        std::max(r.worst_robot_excess_J, (d.robot.port(0).out_J - d.robot.port(0).peer_in_J).maxCoeff());
    if (k_tick >= ticks - 500) {
      sum += fz;
      sum2 += fz * fz;
      shown_sum += shown.force.z();
      gap_sum += d.grasp(ht::Side::kRight).z() - bench;
      ++n;
    }
  }
  r.hold_contact_N = sum / n;
  r.hold_contact_sd_N = std::sqrt(std::max(0.0, sum2 / n - r.hold_contact_N * r.hold_contact_N));
  r.hold_shown_N = shown_sum / n;
  r.hold_gap_m = gap_sum / n;
  r.hold_hand_offset_m = x + depth;
  r.min_arm_bench_m = d.robot.control_output().avoidance.min_arm_bench_m;
  r.force_limited = d.robot.control_output().arm[0].force_limited;
  return r;
}

}  // namespace direct_test

TEST(TwoArmDirect, ZeroDelayPressWhereTheArmCannotFollowWithEitherWrench) {
  for (const bool measured : {false, true}) {
    SCOPED_TRACE(measured ? "measured wrench" : "spring wrench");
    const ClosedLoopResult r = zero_delay_press(measured);
    std::printf("zero delay, %s wrench fed back: peak contact %.1f N; hold: contact %.2f N (sd %.2f), shown %.2f N, "
                "G %.1f mm above the bench, hand %.1f mm above its reference; link-bench gap %.1f mm, force limited %d; "
                "worst excess robot %.2g J, operator %.2g J\n",
                measured ? "measured" : "spring", r.peak_contact_N, r.hold_contact_N, r.hold_contact_sd_N,
                r.hold_shown_N, r.hold_gap_m * 1e3, r.hold_hand_offset_m * 1e3, r.min_arm_bench_m * 1e3,
                r.force_limited, r.worst_robot_excess_J, r.worst_operator_excess_J);
    EXPECT_LE(r.worst_robot_excess_J, 1e-9);
    EXPECT_LE(r.worst_operator_excess_J, 1e-9);
    EXPECT_GT(r.hold_gap_m, 0.1);          // the arm stopped short (truth)
    EXPECT_LT(r.hold_contact_N, 0.5);      // on nothing
    // The hand at rest: k (ref - x) + shown = 0.
    EXPECT_NEAR(r.hold_hand_offset_m, r.hold_shown_N / 200.0, 0.005);
    if (measured) {
      EXPECT_LT(std::abs(r.hold_shown_N), 0.5);
    } else {
      EXPECT_GT(r.hold_shown_N, 30.0);  // the spring at (nearly) the 40 N wrist limit
      EXPECT_LE(r.hold_shown_N, 40.0 + 0.5);
    }
  }
}

TEST(TwoArmDirect, ANonPositiveTwistHoldIsRefused) {
  for (const int64_t hold_ns : {int64_t{0}, int64_t{-1}}) {
    ht::TwoArmRobotOptions o;
    o.direct_twist_hold_ns = hold_ns;
    EXPECT_THROW(ht::TwoArmRobot(kWorkbenchScene, o), std::runtime_error);
  }
}
