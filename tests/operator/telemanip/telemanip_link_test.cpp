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

namespace tele = hemm::op::telemanip;
namespace hw = hemm::wire;

namespace {

hw::ArmsState link_test_state(double x_right) {
  hw::ArmsState s;
  s.set_stamp_ns(5);
  s.set_frame_epoch(3);
  for (std::uint32_t k = 0; k < 2; ++k) {
    hw::ArmState* a = s.add_arm();
    a->set_index(k);
    for (int j = 0; j < 7; ++j) {
      a->add_q(0.0);
      a->add_qd(0.0);
      a->add_tau(0.0);
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(k == 0 ? x_right : 0.6, k == 0 ? -0.25 : 0.25, 0.9);
    hemm::mapping::pose3_to_wire(T, a->mutable_t_a_g());
    a->mutable_v_a();
    a->mutable_omega_a();
    a->mutable_force_a()->set_z(-2.0);
    a->mutable_torque_a();
    hw::GripperState* g = s.add_gripper();
    g->set_index(k);
    g->set_opening_m(0.05);
  }
  return s;
}

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
