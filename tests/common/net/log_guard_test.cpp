#include "common/net/log_guard.h"

#include <gtest/gtest.h>

namespace hemm::net {
namespace {

constexpr int64_t kS = 1'000'000'000;

TEST(LogSafe, KeepsPrintableAsciiAndReplacesEverythingElse) {
  EXPECT_EQ(log_safe("operator-1 A.b_c"), "operator-1 A.b_c");
  EXPECT_EQ(log_safe("a\nb\rc\td\x1b[0m\"q\\e\xc3\xa9"), "a_b_c_d_[0m_q_e__");
  EXPECT_EQ(log_safe(std::string(1000, 'x'), 64).size(), 64u);
  EXPECT_EQ(log_safe(std::string_view("\0z", 2)), "_z");
}

TEST(LogLimiter, LetsABurstThroughThenTheRateAndCountsTheRest) {
  LogLimiter lim(5.0, 20.0);
  uint64_t suppressed = 0;
  int passed = 0;
  uint64_t held_since_last = 0;
  // 10,000 lines asked for within one second: the burst and about 5 more.
  for (int i = 0; i < 10000; ++i) {
    if (lim.allow(i * (kS / 10000), &suppressed)) {
      ++passed;
      held_since_last = 0;
    } else {
      ++held_since_last;
    }
  }
  EXPECT_GE(passed, 20);
  EXPECT_LE(passed, 26);
  EXPECT_EQ(lim.suppressed_total(), static_cast<uint64_t>(10000 - passed));
  // After a quiet second the next line passes and reports what was held back since the last one.
  ASSERT_TRUE(lim.allow(3 * kS, &suppressed));
  EXPECT_EQ(suppressed, held_since_last);
  EXPECT_GT(suppressed, 0u);
  // A sustained flood for 100 s: about 5 lines per second.
  LogLimiter flood(5.0, 20.0);
  int lines = 0;
  for (int64_t t = 0; t < 100 * kS; t += kS / 1000) lines += flood.allow(t);
  EXPECT_GE(lines, 500);
  EXPECT_LE(lines, 521);
}

}  // namespace
}  // namespace hemm::net
