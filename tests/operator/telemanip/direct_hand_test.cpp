// The direct mode's operator end (direct_hand_tick) in a SIMULATED delayed
// loop, simulated time, in process: a SIMULATED hand (0.5 kg; the human arm a
// 200 N/m, 10 N s/m spring-damper pulling it towards a scripted reference
// 10 cm down in D, held 3 s, back) on the device, mapped into A turned 180
// degrees about z; a SIMULATED robot (a 2 kg point mass held by hemm's arm
// impedance, 1000 N/m and 60 N s/m, to the target robot_arm_tick advances,
// its spring wrench fed back as the station does by default) above a
// 5 kN/m wall 5 cm below its start in A. One message each way per 1 ms tick
// through a delay line of half the round trip each way.
//
// The energies asserted on are the test's own: it sums each end's port
// energy per axis from the wrench and twist it applied (the device wrench on
// the hand and the hand's velocity; the spring wrench and the velocity the
// target moved with), and knows which robot message the hand had last
// received, so the robot's true E_in it was given.
#include "operator/telemanip/direct_hand.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <numbers>
#include <vector>

namespace tele = hemm::op::telemanip;
namespace td = hemm::haptics::tdpa;

namespace {

struct DhLoop {
  double rtt_s = 0.3;
  td::PcMode mode = td::PcMode::kControl;
  double release_at_s = -1.0;  // the dead-man released from then on (< 0: never)
  double duration_s = 6.0;
  // What the robot feeds back: its impedance's spring wrench (the station's
  // default) or the wall's force on it (direct_feedback_measured).
  bool measured = false;
};

struct DhResult {
  double op_excess_J = -1e300;     // max over ticks and axes of E_out(hand) - E_in(robot, as received)
  double robot_excess_J = -1e300;  // the same at the robot end
  double op_out_J = 0.0, robot_in_J = 0.0;
  double peak_contact_n = 0.0, peak_shown_n = 0.0, max_depth_m = 0.0, max_robot_depth_m = 0.0;
  double hold_shown_n = 0.0, hold_contact_n = 0.0;  // mean over 3.5-4 s (the hold's end)
  double max_release_step_n = 0.0;  // largest |dF_D| per tick after the release
  double shown_at_release_n = 0.0;
  double max_sent_after_release = 0.0;  // |twist sent| after the release
  double robot_travel_after_release_m = 0.0;
  std::uint64_t pc_ticks = 0;
  bool finite = true;
};

struct DhToRobot {
  std::int64_t arrive = 0;
  std::uint64_t seq = 0;
  td::ArmTwist twist;
  td::Vec6 in_J;
};
struct DhToOp {
  std::int64_t arrive = 0;
  std::uint64_t seq = 0;
  tele::DirectPeer peer;
  td::Vec6 true_in_J;  // the test's own sum
};

DhResult dh_run(const DhLoop& L) {
  const double dt = 1e-3;
  const int sub = 10;
  const auto ticks = static_cast<std::int64_t>(std::llround(L.duration_s / dt));
  const auto delay = static_cast<std::int64_t>(std::llround(0.5 * L.rtt_s / dt));
  tele::DirectHandParams p;
  p.R_A_D = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  p.peak_force_n = 0.0;  // no device clamp: the loop's own forces
  p.pc_mode = L.mode;
  tele::DirectHandState hand;
  td::ArmSide robot;
  // Hand in D, robot in A (both start at 0).
  Eigen::Vector3d x_h = Eigen::Vector3d::Zero(), v_h = Eigen::Vector3d::Zero();
  Eigen::Vector3d x_r = Eigen::Vector3d::Zero(), v_r = Eigen::Vector3d::Zero(), target = Eigen::Vector3d::Zero();
  const double m_h = 0.5, k_h = 200.0, b_h = 10.0, m_r = 2.0, k_t = 1000.0, b_t = 60.0, k_w = 5000.0, z_w = -0.05;
  std::deque<DhToRobot> to_robot;
  std::deque<DhToOp> to_op;
  td::ArmTwist twist_recv;
  std::int64_t twist_sent_tick = -1000000;
  tele::DirectPeer latest;
  bool have_latest = false;
  td::Vec6 op_in_true_received = td::Vec6::Zero();  // the robot's true E_in in the message the hand holds
  td::Vec6 op_in_recv_at_robot = td::Vec6::Zero();  // the hand's true E_in in the message the robot holds
  td::Vec6 op_out = td::Vec6::Zero(), op_in = td::Vec6::Zero(), rob_in = td::Vec6::Zero(), rob_out = td::Vec6::Zero();
  std::vector<td::Vec6> op_in_by_seq(static_cast<std::size_t>(ticks + 1), td::Vec6::Zero());
  DhResult r;
  Eigen::Vector3d last_F = Eigen::Vector3d::Zero();
  Eigen::Vector3d x_r_release = Eigen::Vector3d::Zero();
  double hold_n = 0;
  for (std::int64_t n = 0; n < ticks; ++n) {
    const double t = static_cast<double>(n) * dt;
    const bool pressed = !(L.release_at_s >= 0 && t >= L.release_at_s);
    // ---- operator end: what arrived, then the tick
    const tele::DirectPeer* fresh = nullptr;
    tele::DirectPeer fresh_copy;
    while (!to_op.empty() && to_op.front().arrive <= n) {
      fresh_copy = to_op.front().peer;
      fresh = &fresh_copy;
      latest = fresh_copy;
      have_latest = true;
      op_in_true_received = to_op.front().true_in_J;
      to_op.pop_front();
    }
    hemm::device::EndEffectorSample e;
    e.position_H = x_h;
    e.velocity_H = v_h;
    hemm::device::EndEffectorCommand cmd;
    tele::direct_hand_tick(p, e, pressed, fresh, have_latest ? &latest : nullptr, dt, &hand, &cmd);
    // The test's own energies at the hand, per axis in A (translation only moves).
    const Eigen::Vector3d F_A = p.R_A_D * cmd.force_H, v_A = p.R_A_D * v_h;
    for (int i = 0; i < 3; ++i) {
      const double pw = -F_A[i] * v_A[i];
      (pw >= 0 ? op_in[i] : op_out[i]) += std::abs(pw) * dt;
    }
    for (int i = 0; i < 6; ++i) r.op_excess_J = std::max(r.op_excess_J, op_out[i] - op_in_true_received[i]);
    op_in_by_seq[static_cast<std::size_t>(n + 1)] = op_in;
    to_robot.push_back({n + delay, static_cast<std::uint64_t>(n + 1), hand.sent_A, hand.side.in_J});
    const double shown = cmd.force_H.norm();
    r.peak_shown_n = std::max(r.peak_shown_n, shown);
    if (!pressed) {
      if (r.max_sent_after_release == 0.0 && r.shown_at_release_n == 0.0) {
        r.shown_at_release_n = last_F.norm();
        x_r_release = x_r;
      }
      r.max_release_step_n = std::max(r.max_release_step_n, (cmd.force_H - last_F).norm());
      r.max_sent_after_release = std::max(r.max_sent_after_release, hand.sent_A.v.norm() + hand.sent_A.omega.norm());
      r.robot_travel_after_release_m = std::max(r.robot_travel_after_release_m, (x_r - x_r_release).norm());
    }
    last_F = cmd.force_H;
    // ---- robot end
    while (!to_robot.empty() && to_robot.front().arrive <= n) {
      const DhToRobot& m = to_robot.front();
      if (td::receive_peer<6>(robot, m.seq, m.in_J) == td::Receive::kAccepted) {
        twist_recv = m.twist;
        twist_sent_tick = static_cast<std::int64_t>(m.seq) - 1;
        op_in_recv_at_robot = op_in_by_seq[m.seq];
      }
      to_robot.pop_front();
    }
    // Silent longer than the one-way delay plus 50 ms: hold still (the station's rule).
    const td::ArmTwist recv = n - twist_sent_tick > delay + 50 ? td::ArmTwist{} : twist_recv;
    td::ArmWrench spring;
    spring.force = -k_t * (target - x_r);  // the environment's on the gripper, as the spring holds it
    if (L.measured) spring.force = Eigen::Vector3d(0, 0, x_r.z() < z_w ? k_w * (z_w - x_r.z()) : 0.0);
    const td::ArmTwist v = td::robot_arm_tick(robot, recv, spring, dt, L.mode);
    for (int i = 0; i < 3; ++i) {
      const double pw = spring.force[i] * v.v[i];
      (pw >= 0 ? rob_in[i] : rob_out[i]) += std::abs(pw) * dt;
    }
    for (int i = 0; i < 6; ++i) r.robot_excess_J = std::max(r.robot_excess_J, rob_out[i] - op_in_recv_at_robot[i]);
    target += v.v * dt;
    double contact = 0.0;
    for (int s = 0; s < sub; ++s) {
      const double h = dt / sub;
      contact = x_r.z() < z_w ? k_w * (z_w - x_r.z()) : 0.0;
      const Eigen::Vector3d f = k_t * (target - x_r) - b_t * v_r + Eigen::Vector3d(0, 0, contact);
      v_r += h * f / m_r;
      x_r += h * v_r;
      // The hand: the human's spring towards the reference, the device's force.
      const double tc = t + s * h;
      const double ref = tc < 1.0 ? -0.1 * tc : tc < 4.0 ? -0.1 : std::min(0.0, -0.1 + 0.1 * (tc - 4.0));
      const Eigen::Vector3d fh = k_h * (Eigen::Vector3d(0, 0, ref) - x_h) - b_h * v_h + cmd.force_H;
      v_h += h * fh / m_h;
      x_h += h * v_h;
    }
    r.peak_contact_n = std::max(r.peak_contact_n, contact);
    r.max_depth_m = std::max(r.max_depth_m, -x_h.z());
    r.max_robot_depth_m = std::max(r.max_robot_depth_m, -x_r.z());
    if (t >= 3.5 && t < 4.0) {
      r.hold_shown_n += shown;
      r.hold_contact_n += contact;
      ++hold_n;
    }
    tele::DirectPeer out;
    out.has_port = true;
    out.seq = static_cast<std::uint64_t>(n + 1);
    out.energy_in_J = robot.in_J;
    out.has_wrench = true;
    out.wrench_A << spring.force, spring.torque;
    out.wrist_force_A = Eigen::Vector3d(0, 0, contact);
    to_op.push_back({n + 1 + delay, out.seq, out, rob_in});
    r.finite = r.finite && x_h.allFinite() && x_r.allFinite();
  }
  r.op_out_J = op_out.sum();
  r.robot_in_J = rob_in.sum();
  r.hold_shown_n /= std::max(1.0, hold_n);
  r.hold_contact_n /= std::max(1.0, hold_n);
  r.pc_ticks = hand.side.pc_active_ticks;
  return r;
}

void dh_print(const char* what, const DhLoop& L, const DhResult& r) {
  std::printf("%s, %s fed back: RTT %.0f ms PC %s: hand E_out %.4f J (excess %.3g J), robot E_in %.4f J (excess %.3g J), peak "
              "contact %.1f N, peak shown %.1f N, deepest hand %.3f m, robot %.3f m, hold shown %.2f N contact %.2f N, "
              "hand PC ticks %llu\n",
              what, L.measured ? "wall force" : "spring wrench", L.rtt_s * 1e3, L.mode == td::PcMode::kControl ? "on" : "off", r.op_out_J, r.op_excess_J,
              r.robot_in_J, r.robot_excess_J, r.peak_contact_n, r.peak_shown_n, r.max_depth_m, r.max_robot_depth_m, r.hold_shown_n,
              r.hold_contact_n, static_cast<unsigned long long>(r.pc_ticks));
}

}  // namespace

// Without the controllers the delayed loop hands the hand energy the robot
// never put in and the contact grows; with them E_out <= E_in(peer, as
// received) at every tick at both ends and the contact stays bounded.
TEST(DirectHand, DelayedWallStaysPassiveOnlyWithTheController) {
  // A passive hold plus twice the robot mass's impact: 4 k_h d + 2 v sqrt(k_w m_r) (as tdpa_loop_test).
  const double bound = 4 * 200.0 * 0.05 + 2 * 0.1 * std::sqrt(5000.0 * 2.0);
  for (bool measured : {false, true}) {
    for (double rtt : {0.3, 1.0}) {
    DhLoop off{rtt, td::PcMode::kObserveOnly};
    off.measured = measured;
    const DhResult a = dh_run(off);
    dh_print("observer only", off, a);
    EXPECT_TRUE(a.op_excess_J > 0.5 || a.peak_contact_n > bound || !a.finite) << rtt;
    DhLoop on{rtt, td::PcMode::kControl};
    on.measured = measured;
    const DhResult b = dh_run(on);
    dh_print("controller", on, b);
    ASSERT_TRUE(b.finite);
    EXPECT_LE(b.op_excess_J, 1e-9) << rtt;
    EXPECT_LE(b.robot_excess_J, 1e-9) << rtt;
    EXPECT_LT(b.peak_contact_n, bound) << rtt;
    EXPECT_LT(b.max_depth_m, 0.15) << rtt;  // within 1.5x the reference's reach
    EXPECT_GT(b.pc_ticks, 0u) << rtt;       // it had work to do
    // The wall force fed back: the robot reaches the wall (the contact is
    // what the bound is about); the spring wrench: TDPA's drift, the robot
    // follows almost none of the hand's 10 cm (printed; docs "Operator end").
    if (measured) {
      EXPECT_GT(b.peak_contact_n, 1.0) << rtt;
    }
  }
  }
}

// Zero delay: the wall is felt (the spring wrench, the hand rests against
// it); released in contact, the shown force fades out over fade_s instead
// of stepping to zero, and the twist sent is zero: the robot holds.
TEST(DirectHand, ReleaseFadesTheWrenchAndStopsTheTwist) {
  DhLoop L{0.0, td::PcMode::kControl, 3.5, 4.0};
  const DhResult r = dh_run(L);
  dh_print("release at 3.5 s", L, r);
  ASSERT_TRUE(r.finite);
  EXPECT_LE(r.op_excess_J, 1e-9);
  EXPECT_GT(r.shown_at_release_n, 4.0);  // in contact: 200 N/m x 5 cm at rest
  // 0.2 s fade: at most |F| dt / fade a tick, beside the remote's own change.
  EXPECT_LT(r.max_release_step_n, 2.0 * r.shown_at_release_n * 1e-3 / 0.2 + 0.05);
  EXPECT_DOUBLE_EQ(r.max_sent_after_release, 0.0);
  EXPECT_LT(r.robot_travel_after_release_m, 0.01);
}

// The rotation scale k in the direct mode: the hand's angular velocity goes
// out k times as fast (about the same axis, in A), the remote torque is shown
// k times as large, so the power at the hand equals the arm's (tau_D . w_D =
// tau_A . w_A); the observer alone (no controller) leaves the wrench as sent.
TEST(DirectHand, RotationScaleScalesTheTurnAndTheTorqueShown) {
  for (double k : {1.0, 2.5}) {
    tele::DirectHandParams p;
    p.R_A_D = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.rotation_scale = k;
    p.max_rate_radps = 100.0;
    p.pc_mode = td::PcMode::kObserveOnly;
    ASSERT_EQ(tele::validate(p), "");
    tele::DirectHandState s;
    s.gain = 1.0;
    hemm::device::EndEffectorSample e;
    e.angular_velocity_H = Eigen::Vector3d(0.2, -0.1, 0.3);
    tele::DirectPeer peer;
    peer.has_wrench = true;
    peer.wrench_A << 0.0, 0.0, 0.0, 0.4, 0.1, -0.2;
    hemm::device::EndEffectorCommand cmd;
    tele::direct_hand_tick(p, e, true, nullptr, &peer, 1e-3, &s, &cmd);
    EXPECT_TRUE(s.sent_A.omega.isApprox(k * (p.R_A_D * e.angular_velocity_H), 1e-12)) << k;
    const Eigen::Vector3d tau_A = peer.wrench_A.tail<3>();
    EXPECT_TRUE(cmd.torque_H.isApprox(k * (p.R_A_D.transpose() * tau_A), 1e-12)) << k;
    EXPECT_NEAR(cmd.torque_H.dot(e.angular_velocity_H), tau_A.dot(s.sent_A.omega), 1e-12) << k;
  }
  tele::DirectHandParams bad;
  bad.rotation_scale = 0.1;
  EXPECT_NE(tele::validate(bad), "");
}
