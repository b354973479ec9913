// The link's two halves without sockets: commands from setpoints (the
// dead-man only while pressed and fresh, arms not yet initialized not
// named), and ArmsStates from the robot, where bad input (non-finite values,
// wrong counts, unknown or repeated indices, inconsistent refusal fields)
// is counted and changes nothing, older datagrams are dropped, and each rise
// of the refusal count is one refusal, by reason, per frame epoch.
#include "operator/telemanip/telemanip_link.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/mapping/depth_stream.h"
#include "tests/operator/telemanip/arms_state_wire.h"

namespace tele = hemm::op::telemanip;
namespace hw = hemm::wire;

namespace {

hw::ArmsState link_test_state(double x_right) { return hemm::test::telemanip_test_state(x_right); }

struct LinkTestRig {
  asio::io_context io;
  hemm::NewestMailbox<tele::TelemanipSetpoint> setpoints;
  hemm::NewestMailbox<tele::RemoteArmsState> remote;
  std::vector<hw::ArmsCommand> sent;
  std::int64_t now = 1'000'000'000;
  tele::TelemanipLink link{io,
                           setpoints,
                           remote,
                           [this](const hw::StreamMessage& m) {
                             sent.push_back(m.arms_command());
                             return true;
                           },
                           [this] { return now; },
                           tele::TelemanipLinkParams{}};
};

}  // namespace

TEST(TelemanipLink, CommandsCarryTheDeadManOnlyWhilePressedAndFresh) {
  LinkTestRig r;
  r.link.send_once();  // nothing published yet: nothing sent
  EXPECT_TRUE(r.sent.empty());
  EXPECT_EQ(r.link.stats().no_setpoint, 1u);
  tele::TelemanipSetpoint sp;
  sp.t_ns = r.now;
  sp.arm[0].active = true;
  sp.arm[0].pressed = true;
  sp.arm[0].p_A = Eigen::Vector3d(0.7, -0.2, 0.9);
  sp.arm[0].has_gripper = true;
  sp.arm[0].opening_m = 0.03;
  sp.arm[0].force_n = 20.0;
  r.setpoints.publish(sp);  // arm 1 not initialized: not named
  r.link.send_once();
  ASSERT_EQ(r.sent.size(), 1u);
  const hw::ArmsCommand& c = r.sent.back();
  EXPECT_TRUE(c.deadman());
  EXPECT_EQ(c.mode(), hw::MODE_MANIPULATION);
  ASSERT_EQ(c.arm_size(), 1);
  EXPECT_EQ(c.arm(0).index(), 0u);
  EXPECT_DOUBLE_EQ(c.arm(0).t_a_g().position().x(), 0.7);
  EXPECT_DOUBLE_EQ(c.arm(0).t_a_g().orientation().w(), 1.0);
  ASSERT_EQ(c.gripper_size(), 1);
  EXPECT_DOUBLE_EQ(c.gripper(0).opening_m(), 0.03);
  // The servo thread stalls: 150 ms later the same setpoint goes released.
  r.now += 150'000'000;
  r.link.send_once();
  EXPECT_FALSE(r.sent.back().deadman());
  EXPECT_EQ(r.link.stats().stale, 1u);
  // Fresh but released.
  sp.t_ns = r.now;
  sp.arm[0].pressed = false;
  r.setpoints.publish(sp);
  r.link.send_once();
  EXPECT_FALSE(r.sent.back().deadman());
  EXPECT_EQ(r.link.stats().deadman_pressed, 1u);
}

TEST(TelemanipLink, BadStatesAreCountedAndChangeNothing) {
  LinkTestRig r;
  r.link.on_arms_state(10, 1, link_test_state(0.6));
  const tele::RemoteArmsState* got = r.remote.take();
  ASSERT_NE(got, nullptr);
  EXPECT_TRUE(got->valid);
  EXPECT_DOUBLE_EQ(got->arm[0].p_A.x(), 0.6);
  EXPECT_DOUBLE_EQ(got->arm[1].p_A.y(), 0.25);
  EXPECT_DOUBLE_EQ(got->arm[0].force_A.z(), -2.0);
  EXPECT_DOUBLE_EQ(got->gripper[1].opening_m, 0.05);
  std::vector<hw::ArmsState> bad;
  hw::ArmsState s = link_test_state(0.7);
  s.mutable_arm(0)->mutable_t_a_g()->mutable_position()->set_x(NAN);
  bad.push_back(s);
  s = link_test_state(0.7);
  s.mutable_arm(1)->set_index(0);  // arm 0 twice
  bad.push_back(s);
  s = link_test_state(0.7);
  s.mutable_arm(1)->set_index(5);  // an arm the two-arm robot has not
  bad.push_back(s);
  s = link_test_state(0.7);
  s.mutable_gripper()->RemoveLast();  // one gripper short
  bad.push_back(s);
  s = link_test_state(0.7);
  s.mutable_arm(0)->mutable_t_a_g()->mutable_orientation()->set_w(0.5);  // not a unit quaternion
  bad.push_back(s);
  s = link_test_state(0.7);
  s.mutable_arm(0)->mutable_force_a()->set_x(INFINITY);
  bad.push_back(s);
  std::uint64_t seq = 11;
  for (const hw::ArmsState& b : bad) r.link.on_arms_state(seq++, 2, b);
  EXPECT_EQ(r.link.stats().states_rejected, bad.size());
  EXPECT_EQ(r.remote.take(), nullptr);  // nothing new for the servo thread
  EXPECT_DOUBLE_EQ(r.remote.latest()->arm[0].p_A.x(), 0.6);
  // An older datagram than one accepted: dropped.
  r.link.on_arms_state(9, 3, link_test_state(0.8));
  EXPECT_EQ(r.link.stats().states_reordered, 1u);
  EXPECT_EQ(r.remote.take(), nullptr);
  EXPECT_EQ(r.link.stats().states_in, 1u);
}

TEST(TelemanipLink, EachRiseOfTheRefusalCountIsOneRefusalPerEpoch) {
  tele::ArmsRefusalMonitor m;
  hw::ArmsState s = link_test_state(0.6);
  std::string err;
  EXPECT_FALSE(tele::observe_arms_refusals(m, s, &err));  // none
  s.set_refusals(2);
  s.set_last_refusal(hw::ARMS_REFUSAL_OUT_OF_REACH);
  s.set_last_refused_seq(40);
  s.set_last_refused_index(1);
  auto e = tele::observe_arms_refusals(m, s, &err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->new_refusals, 2u);
  EXPECT_EQ(e->index, 1u);
  EXPECT_FALSE(tele::observe_arms_refusals(m, s, &err));  // the same state again
  s.set_refusals(1);
  EXPECT_FALSE(tele::observe_arms_refusals(m, s, &err));  // an older one (reordered)
  s.set_refusals(3);
  s.set_last_refusal(hw::ARMS_REFUSAL_GRIPPER_RANGE);
  ASSERT_TRUE(tele::observe_arms_refusals(m, s, &err));
  EXPECT_EQ(m.summary.refused, 3u);
  EXPECT_EQ(m.summary.events, 2u);
  EXPECT_EQ(m.summary.by_reason[hw::ARMS_REFUSAL_OUT_OF_REACH], 1u);
  EXPECT_EQ(m.summary.by_reason[hw::ARMS_REFUSAL_GRIPPER_RANGE], 1u);
  // A restarted robot (another epoch) counts from 0 again.
  s.set_frame_epoch(4);
  s.set_refusals(1);
  ASSERT_TRUE(tele::observe_arms_refusals(m, s, &err));
  EXPECT_EQ(m.summary.refused, 4u);
  // Inconsistent fields: counted as errors, nothing else changes.
  hw::ArmsState bad = s;
  bad.set_refusals(5);
  bad.set_last_refusal(hw::ARMS_REFUSAL_UNSPECIFIED);
  EXPECT_FALSE(tele::observe_arms_refusals(m, bad, &err));
  EXPECT_FALSE(err.empty());
  bad.set_last_refusal(static_cast<hw::ArmsRefusalReason>(42));
  EXPECT_FALSE(tele::observe_arms_refusals(m, bad, &err));
  EXPECT_EQ(m.summary.errors, 2u);
  EXPECT_EQ(m.summary.refused, 4u);
  EXPECT_EQ(m.count, 1u);
}

// The direct mode (issue 25 part 5): an arm in it is named with its twist
// (zero while released: the robot holds) and its passivity port, never a
// pose; its gripper is still commanded; the other arm keeps its pose.
TEST(TelemanipLink, DirectArmsSendTheirTwistAndPortInPlaceOfThePose) {
  tele::TelemanipSetpoint sp;
  sp.t_ns = 1;
  for (tele::ArmSetpoint& a : sp.arm) {
    a.active = true;
    a.pressed = true;
    a.p_A = Eigen::Vector3d(0.6, 0.0, 0.9);
  }
  tele::ArmSetpoint& d = sp.arm[1];
  d.direct = true;
  d.twist_A.v = Eigen::Vector3d(0.01, -0.02, 0.03);
  d.twist_A.omega = Eigen::Vector3d(0.0, 0.0, 0.2);
  d.side.in_J << 1, 2, 3, 4, 5, 6;
  d.side.out_J.setConstant(0.5);
  d.has_gripper = true;
  d.opening_m = 0.04;
  hw::ArmsCommand c;
  tele::setpoint_to_command(sp, true, 7, &c, hemm::haptics::tdpa::PcMode::kControl);
  ASSERT_EQ(c.arm_size(), 1);
  EXPECT_EQ(c.arm(0).index(), 0u);
  ASSERT_EQ(c.twist_size(), 1);
  EXPECT_EQ(c.twist(0).index(), 1u);
  EXPECT_DOUBLE_EQ(c.twist(0).v_a().y(), -0.02);
  EXPECT_DOUBLE_EQ(c.twist(0).omega_a().z(), 0.2);
  ASSERT_EQ(c.passivity_size(), 1);
  EXPECT_EQ(c.passivity(0).index(), 1u);
  ASSERT_EQ(c.passivity(0).energy_in_j_size(), 6);
  EXPECT_DOUBLE_EQ(c.passivity(0).energy_in_j(5), 6.0);
  EXPECT_TRUE(c.passivity(0).pc_on());
  ASSERT_EQ(c.gripper_size(), 1);
  EXPECT_DOUBLE_EQ(c.gripper(0).opening_m(), 0.04);
  // Released: the twist is zero, the port still goes (the energy is cumulative).
  tele::setpoint_to_command(sp, false, 8, &c, hemm::haptics::tdpa::PcMode::kObserveOnly);
  ASSERT_EQ(c.twist_size(), 1);
  EXPECT_DOUBLE_EQ(c.twist(0).v_a().y(), 0.0);
  EXPECT_DOUBLE_EQ(c.twist(0).omega_a().z(), 0.0);
  ASSERT_EQ(c.passivity_size(), 1);
  EXPECT_FALSE(c.passivity(0).pc_on());
}

// The robot's ports and wrenches reach the servo thread with the state's
// sequence; a bad one is dropped and counted, the rest of the state taken.
TEST(TelemanipLink, DirectPortsAndWrenchesAreCheckedOneByOne) {
  LinkTestRig r;
  hw::ArmsState s = link_test_state(0.6);
  hw::PassivityPort* p = s.add_passivity();
  p->set_index(0);
  for (int i = 0; i < 6; ++i) p->add_energy_in_j(0.1 * (i + 1));
  hw::DirectWrench* w = s.add_direct_wrench();
  w->set_index(0);
  for (int i = 0; i < 6; ++i) w->add_wrench_a(static_cast<float>(i));
  hw::PassivityPort* bad = s.add_passivity();  // arm 1: a negative energy
  bad->set_index(1);
  for (int i = 0; i < 6; ++i) bad->add_energy_in_j(i == 3 ? -1.0 : 1.0);
  hw::DirectWrench* badw = s.add_direct_wrench();  // arm 1: five values
  badw->set_index(1);
  for (int i = 0; i < 5; ++i) badw->add_wrench_a(1.0f);
  r.link.on_arms_state(10, 1, s);
  const tele::RemoteArmsState* got = r.remote.take();
  ASSERT_NE(got, nullptr);
  const tele::DirectPeer& d0 = got->arm[0].direct;
  EXPECT_TRUE(d0.has_port);
  EXPECT_EQ(d0.seq, 10u);
  EXPECT_DOUBLE_EQ(d0.energy_in_J[5], 0.6);
  EXPECT_TRUE(d0.has_wrench);
  EXPECT_DOUBLE_EQ(d0.wrench_A[4], 4.0);
  EXPECT_DOUBLE_EQ(d0.wrist_force_A.z(), -2.0);
  EXPECT_FALSE(got->arm[1].direct.has_port);
  EXPECT_FALSE(got->arm[1].direct.has_wrench);
  EXPECT_EQ(r.link.stats().ports_rejected, 1u);
  EXPECT_EQ(r.link.stats().wrenches_rejected, 1u);
  EXPECT_EQ(r.link.stats().states_in, 1u);
  // The next state without ports: none for the servo (the arms left the direct mode).
  r.link.on_arms_state(11, 2, link_test_state(0.6));
  got = r.remote.take();
  ASSERT_NE(got, nullptr);
  EXPECT_FALSE(got->arm[0].direct.has_port);
  EXPECT_FALSE(got->arm[0].direct.has_wrench);
}
