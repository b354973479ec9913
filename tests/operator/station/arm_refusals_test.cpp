// The operator's reading of the robot's arm-target refusals (RobotState
// fields 16-18): each new refusal once, older and bad states change nothing.
#include <gtest/gtest.h>

#include "operator/station/arm_refusals.h"

namespace ho = hemm::op;
namespace hw = hemm::wire;

namespace {
hw::RobotState state(std::uint64_t epoch, std::uint64_t count, int reason, std::uint64_t seq) {
  hw::RobotState s;
  s.set_frame_epoch(epoch);
  s.set_arm_refusals(count);
  s.set_last_arm_refusal(static_cast<hw::ArmRefusalReason>(reason));
  s.set_last_refused_seq(seq);
  return s;
}
}  // namespace

TEST(ArmRefusals, EachNewRefusalIsReportedOnceWithItsReasonAndSequence) {
  ho::ArmRefusalMonitor m;
  std::string err;
  EXPECT_FALSE(ho::observe_arm_refusals(m, state(7, 0, 0, 0), &err));
  EXPECT_TRUE(err.empty());
  auto e = ho::observe_arm_refusals(m, state(7, 1, hw::ARM_REFUSAL_FLOOR, 40), &err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->reason, hw::ARM_REFUSAL_FLOOR);
  EXPECT_EQ(e->seq, 40u);
  EXPECT_EQ(e->new_refusals, 1u);
  // The same state again (the robot sends it at 250 Hz): nothing new.
  EXPECT_FALSE(ho::observe_arm_refusals(m, state(7, 1, hw::ARM_REFUSAL_FLOOR, 40), &err));
  // Two more between states: one report, both counted, the newest reason.
  e = ho::observe_arm_refusals(m, state(7, 3, hw::ARM_REFUSAL_SCENE, 52), &err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->new_refusals, 2u);
  EXPECT_EQ(e->total, 3u);
  // An older state arriving late: ignored.
  EXPECT_FALSE(ho::observe_arm_refusals(m, state(7, 2, hw::ARM_REFUSAL_BASE, 45), &err));
  EXPECT_TRUE(err.empty());
  EXPECT_EQ(m.summary.refused, 3u);
  EXPECT_EQ(m.summary.events, 2u);
  EXPECT_EQ(m.summary.floor, 1u);
  EXPECT_EQ(m.summary.scene, 1u);
  EXPECT_EQ(m.summary.base, 0u);
  EXPECT_EQ(m.summary.last_reason, hw::ARM_REFUSAL_SCENE);
  EXPECT_EQ(m.summary.last_seq, 52u);
  // A restarted robot (new frame epoch) counts from 0 again.
  e = ho::observe_arm_refusals(m, state(9, 1, hw::ARM_REFUSAL_BASE, 3), &err);
  ASSERT_TRUE(e);
  EXPECT_EQ(e->new_refusals, 1u);
  EXPECT_EQ(m.summary.refused, 4u);
  EXPECT_EQ(m.summary.base, 1u);
  EXPECT_STREQ(ho::short_name(hw::ARM_REFUSAL_BASE), "base");
}

TEST(ArmRefusals, BadFieldsAreErrorsAndChangeNothing) {
  ho::ArmRefusalMonitor m;
  std::string err;
  ASSERT_TRUE(ho::observe_arm_refusals(m, state(7, 1, hw::ARM_REFUSAL_BASE, 10), &err));
  const ho::ArmRefusalSummary before = m.summary;
  const std::uint64_t count = m.count, epoch = m.frame_epoch;
  // An unknown reason (proto3 keeps unknown enum values), a count without a
  // reason, a reason without a count, and an unknown reason in a new epoch.
  for (const hw::RobotState& s : {state(7, 2, 17, 11), state(7, 2, 0, 11), state(7, 0, hw::ARM_REFUSAL_SCENE, 11),
                                  state(8, 2, -3, 11)}) {
    err.clear();
    EXPECT_FALSE(ho::observe_arm_refusals(m, s, &err));
    EXPECT_FALSE(err.empty());
  }
  EXPECT_EQ(m.summary.errors, 4u);
  EXPECT_EQ(m.summary.refused, before.refused);
  EXPECT_EQ(m.summary.events, before.events);
  EXPECT_EQ(m.summary.last_seq, before.last_seq);
  EXPECT_EQ(m.count, count);
  EXPECT_EQ(m.frame_epoch, epoch);
}
