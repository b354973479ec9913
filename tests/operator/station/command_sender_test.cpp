// The command sender: deadman logic, mode-change frames, the history handed
// to the pose prediction, and the send rate on a real io_context.
#include <gtest/gtest.h>

#include <chrono>
#include <vector>

#include "operator/station/command_sender.h"

namespace ho = hemm::op;
namespace hw = hemm::wire;
namespace hm = hemm::math;

namespace {

struct Fixture {
  asio::io_context io;
  hemm::NewestMailbox<ho::StationSetpoint> box;
  std::vector<hw::Command> sent;
  std::vector<hw::SessionFrame> frames;
  bool fail = false;
  bool up = true;
  std::int64_t now = 1'000'000'000;
  hemm::servo::ModelChannel channel;
  ho::ModelThread model{channel, {}};
  ho::CommandSender sender{io,
                           box,
                           [this](const hw::StreamMessage& m) {
                             if (fail) return false;
                             sent.push_back(m.command());
                             return true;
                           },
                           [this](const hw::SessionFrame& f) { frames.push_back(f); },
                           &model,
                           ho::CommandSenderParams{},
                           [this] { return now; },
                           [this] { return up; }};
};

ho::StationSetpoint nav(std::int64_t t, double v, double w) {
  ho::StationSetpoint s;
  s.t_ns = t;
  s.mode = hm::Mode::kNavigation;
  s.v = v;
  s.omega = w;
  s.moves_robot = true;
  s.deadman = true;  // the hand presses the dead-man
  return s;
}

TEST(CommandSender, DeadmanModeFramesAndHistory) {
  Fixture f;
  f.sender.send_once();
  EXPECT_TRUE(f.sent.empty());  // nothing from the servo yet

  f.box.publish(nav(f.now, 0.4, 0.1));
  f.sender.send_once();
  ASSERT_EQ(f.sent.size(), 1u);
  EXPECT_TRUE(f.sent[0].deadman());
  EXPECT_EQ(f.sent[0].mode(), hw::MODE_NAVIGATION);
  EXPECT_DOUBLE_EQ(f.sent[0].v(), 0.4);
  EXPECT_DOUBLE_EQ(f.sent[0].omega(), 0.1);
  EXPECT_EQ(f.sent[0].stamp_ns(), f.now);
  ASSERT_EQ(f.frames.size(), 1u);
  EXPECT_EQ(f.frames[0].mode_change().mode(), hw::MODE_NAVIGATION);

  f.now += 5'000'000;
  f.sender.send_once();  // same setpoint, still fresh
  ASSERT_EQ(f.sent.size(), 2u);
  EXPECT_TRUE(f.sent[1].deadman());
  EXPECT_EQ(f.frames.size(), 1u);  // no new mode frame

  f.now += 200'000'000;  // the servo stalled: stop the robot
  f.sender.send_once();
  ASSERT_EQ(f.sent.size(), 3u);
  EXPECT_FALSE(f.sent[2].deadman());
  EXPECT_EQ(f.sent[2].v(), 0.0);
  EXPECT_EQ(f.sender.stats().stale, 1u);

  ho::StationSetpoint e;
  e.t_ns = f.now;
  e.mode = hm::Mode::kExploration;
  f.box.publish(e);
  f.sender.send_once();
  EXPECT_FALSE(f.sent.back().deadman());
  ASSERT_EQ(f.frames.size(), 2u);
  EXPECT_EQ(f.frames[1].mode_change().mode(), hw::MODE_EXPLORATION);
  EXPECT_GT(f.frames[1].mode_change().request_id(), f.frames[0].mode_change().request_id());

  ho::StationSetpoint m;
  m.t_ns = f.now;
  m.mode = hm::Mode::kManipulation;
  m.arm_target_R = {0.4, 0.1, 0.3};
  m.arm_valid = true;
  m.moves_robot = true;
  m.deadman = true;
  f.box.publish(m);
  f.sender.send_once();
  EXPECT_TRUE(f.sent.back().deadman());
  EXPECT_DOUBLE_EQ(f.sent.back().arm_target().x(), 0.4);
  EXPECT_DOUBLE_EQ(f.sent.back().arm_target().z(), 0.3);

  const std::size_t frames_before = f.frames.size();
  f.fail = true;
  f.sender.send_once();
  EXPECT_EQ(f.sender.stats().send_failures, 1u);
  EXPECT_EQ(f.sender.stats().commands_sent, f.sent.size());
  EXPECT_EQ(f.frames.size(), frames_before);  // no mode frame without a link
  f.fail = false;  // link back: the mode is said again
  f.sender.send_once();
  ASSERT_EQ(f.frames.size(), frames_before + 1);
  EXPECT_EQ(f.frames.back().mode_change().mode(), hw::MODE_MANIPULATION);
}

// Issue 23 item 2: the wire's dead-man is the hand's. Released: no dead-man
// and no motion, whatever the task commands. Pressed while the task holds
// motion: the dead-man with a neutral command. Pressed in manipulation
// without an arm target: nothing to follow, no dead-man. Non-finite device
// poses the task counted are counted (and logged) here.
TEST(CommandSender, TheDeadManIsTheHandsAndMotionGoesOnlyWithIt) {
  Fixture f;
  ho::StationSetpoint sp = nav(f.now, 0.4, 0.1);
  sp.deadman = false;
  f.box.publish(sp);
  f.sender.send_once();
  ASSERT_EQ(f.sent.size(), 1u);
  EXPECT_FALSE(f.sent[0].deadman());
  EXPECT_EQ(f.sent[0].v(), 0.0);
  EXPECT_EQ(f.sent[0].omega(), 0.0);
  sp.deadman = true;
  sp.moves_robot = false;  // the task's motion hold
  f.box.publish(sp);
  f.sender.send_once();
  EXPECT_TRUE(f.sent.back().deadman());
  EXPECT_EQ(f.sent.back().v(), 0.0);
  ho::StationSetpoint m;
  m.t_ns = f.now;
  m.mode = hm::Mode::kManipulation;
  m.deadman = true;  // pressed, but held: no arm target
  f.box.publish(m);
  f.sender.send_once();
  EXPECT_FALSE(f.sent.back().deadman());
  EXPECT_FALSE(f.sent.back().has_arm_target());
  m.nonfinite_poses = 7;
  f.box.publish(m);
  f.sender.send_once();
  EXPECT_EQ(f.sender.stats().nonfinite_poses, 7u);
  EXPECT_EQ(f.sender.stats().deadman_pressed, 1u);
}

// With the link down nothing is sent and it is not a failure; when it comes
// back the session hears the mode again.
TEST(CommandSender, LinkDownSendsNothingAndRepeatsTheModeAfterwards) {
  Fixture f;
  f.box.publish(nav(f.now, 0.4, 0.1));
  f.sender.send_once();
  ASSERT_EQ(f.sent.size(), 1u);
  ASSERT_EQ(f.frames.size(), 1u);
  f.up = false;
  for (int i = 0; i < 5; ++i) f.sender.send_once();
  EXPECT_EQ(f.sent.size(), 1u);
  EXPECT_EQ(f.sender.stats().link_down, 5u);
  EXPECT_EQ(f.sender.stats().send_failures, 0u);
  f.up = true;
  f.sender.send_once();
  EXPECT_EQ(f.sent.size(), 2u);
  ASSERT_EQ(f.frames.size(), 2u);
  EXPECT_EQ(f.frames[1].mode_change().mode(), hw::MODE_NAVIGATION);
}

// Issue 9 item 9: an e-stop pressed on the device goes to the robot as an
// EStop frame with a request id (once per press), and one pressed while the
// link is down goes when it is back.
TEST(CommandSender, DeviceEStopGoesAsAnEStopFrameWithARequestId) {
  Fixture f;
  ho::StationSetpoint sp = nav(f.now, 0.4, 0.1);
  f.box.publish(sp);
  f.sender.send_once();
  ASSERT_EQ(f.frames.size(), 1u);  // the mode
  sp.estop_presses = 1;
  f.box.publish(sp);
  f.sender.send_once();
  ASSERT_EQ(f.frames.size(), 2u);
  ASSERT_TRUE(f.frames[1].has_estop());
  EXPECT_TRUE(f.frames[1].estop().engaged());
  const std::uint64_t id = f.frames[1].estop().request_id();
  EXPECT_GT(id, f.frames[0].mode_change().request_id());  // one id sequence for every request
  for (int i = 0; i < 3; ++i) f.sender.send_once();  // the same press is not sent again
  EXPECT_EQ(f.frames.size(), 2u);
  f.up = false;
  sp.estop_presses = 2;
  f.box.publish(sp);
  f.sender.send_once();
  EXPECT_EQ(f.frames.size(), 2u);
  f.up = true;
  f.sender.send_once();
  ASSERT_GE(f.frames.size(), 3u);
  bool sent_after = false;
  for (std::size_t i = 2; i < f.frames.size(); ++i)
    sent_after = sent_after || (f.frames[i].has_estop() && f.frames[i].estop().request_id() > id);
  EXPECT_TRUE(sent_after);
  EXPECT_EQ(f.sender.stats().estops_sent, 2u);
  // A release from the station (control socket, terminal key).
  const std::uint64_t rid = f.sender.send_estop(false, "test");
  EXPECT_GT(rid, id);
  EXPECT_FALSE(f.frames.back().estop().engaged());
  EXPECT_EQ(f.frames.back().estop().request_id(), rid);
  f.up = false;
  EXPECT_EQ(f.sender.send_estop(true, "test"), 0u);
}

TEST(CommandSender, SentCommandsDriveThePrediction) {
  Fixture f;
  hw::RobotState st;
  st.set_stamp_ns(f.now);
  st.mutable_t_w_r_odom()->set_theta(0.0);
  f.model.submit_state(st);
  f.box.publish(nav(f.now, 0.4, 0.0));
  f.sender.send_once();  // v = 0.4 from f.now (delay 0)
  f.model.step(f.now + 1'000'000'000);
  const auto* snap = static_cast<const ho::OperatorModelSnapshot*>(f.channel.acquire());
  ASSERT_NE(snap, nullptr);
  EXPECT_NEAR(snap->T_W_R.x, 0.4, 1e-9);
}

TEST(CommandSender, RateOnTheIoContext) {
  Fixture f;
  f.box.publish(nav(f.now, 0.1, 0.0));
  f.sender.start();
  const auto t0 = std::chrono::steady_clock::now();
  f.io.run_for(std::chrono::milliseconds(500));
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  f.sender.stop();
  const double hz = static_cast<double>(f.sent.size()) / s;
  std::printf("command rate: %.1f Hz (nominal 200)\n", hz);
  EXPECT_GE(hz, 100.0);
  EXPECT_LE(hz, 205.0);  // never bursts above the rate
}

TEST(CommandSender, RejectsRatesOutsideTheWireContract) {
  asio::io_context io;
  hemm::NewestMailbox<ho::StationSetpoint> box;
  auto send = [](const hw::StreamMessage&) { return true; };
  auto clock = [] { return std::int64_t{0}; };
  EXPECT_THROW(ho::CommandSender(io, box, send, nullptr, nullptr, ho::CommandSenderParams{50.0, 0, false, {}}, clock),
               std::invalid_argument);
  EXPECT_THROW(ho::CommandSender(io, box, nullptr, nullptr, nullptr, ho::CommandSenderParams{}, clock),
               std::invalid_argument);
}

}  // namespace
