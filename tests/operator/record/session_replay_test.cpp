// A replay's result JSON (hemm-operator --replay-json) is proto/report.proto's
// SessionReplay: it reads back, strictly (no unknown keys), into that message
// with every value as it was.
#include "operator/record/session_replay.h"

#include <gtest/gtest.h>

#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::op {
namespace {

TEST(SessionReplayJson, ReadsBackIntoTheSessionReplayReport) {
  SessionReplayResult s;
  s.ticks = 12345;
  s.steps = 678;
  s.ticks_missing = 2;
  s.force_mismatches = 1;
  s.max_force_error_N = 2.5e-13;
  s.max_error_tick = 9'000'000'000ULL;  // past 32 bits
  s.recorded_s = 12.345678901234;      // the old writer kept 9 digits
  s.wall_s = 0.5;
  const report::SessionReplay r = test::read_report_json<report::SessionReplay>(to_json(s));
  EXPECT_EQ(r.ticks(), 12345u);
  EXPECT_EQ(r.model_steps(), 678u);
  EXPECT_EQ(r.ticks_missing(), 2u);
  EXPECT_EQ(r.force_mismatches(), 1u);
  EXPECT_EQ(r.max_force_error_n(), 2.5e-13);
  EXPECT_EQ(r.max_error_tick(), 9'000'000'000ULL);
  EXPECT_EQ(r.recorded_s(), 12.345678901234);
  EXPECT_EQ(r.wall_s(), 0.5);
  EXPECT_TRUE(r.complete());
  EXPECT_EQ(r.stopped(), "");
}

TEST(SessionReplayJson, AReplayThatStoppedSaysWhy) {
  SessionReplayResult s;
  s.stopped = "tick 7 rendered with model version 3, the recorded steps reach version 2";
  const report::SessionReplay r = test::read_report_json<report::SessionReplay>(to_json(s));
  EXPECT_FALSE(r.complete());
  EXPECT_EQ(r.stopped(), s.stopped);
}

}  // namespace
}  // namespace hemm::op
