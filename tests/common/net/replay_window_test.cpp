#include "common/net/replay_window.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

namespace hemm::net {
namespace {

using V = ReplayWindow::Verdict;

TEST(ReplayWindowTest, SizeIsAtLeast64AndAMultipleOf64) {
  EXPECT_EQ(ReplayWindow(1).size(), 64u);
  EXPECT_EQ(ReplayWindow(64).size(), 64u);
  EXPECT_EQ(ReplayWindow(65).size(), 128u);
  EXPECT_EQ(ReplayWindow().size(), 1024u);
}

TEST(ReplayWindowTest, InOrderDuplicatesAndZero) {
  ReplayWindow w(64);
  EXPECT_EQ(w.accept(0), V::kTooOld);
  for (uint64_t s = 1; s <= 10; ++s) EXPECT_EQ(w.accept(s), V::kNewHighest);
  for (uint64_t s = 1; s <= 10; ++s) EXPECT_EQ(w.accept(s), V::kDuplicate);
  EXPECT_EQ(w.highest(), 10u);
}

TEST(ReplayWindowTest, WindowEdgeIsExact) {
  ReplayWindow w(64);
  EXPECT_EQ(w.accept(100), V::kNewHighest);
  EXPECT_EQ(w.check(37), V::kInWindow);  // 100 - 37 = 63 < 64
  EXPECT_EQ(w.check(36), V::kTooOld);    // 100 - 36 = 64
  EXPECT_EQ(w.accept(37), V::kInWindow);
  EXPECT_EQ(w.accept(37), V::kDuplicate);
  // Slide by one: 37 is now exactly at the edge and falls out.
  EXPECT_EQ(w.accept(101), V::kNewHighest);
  EXPECT_EQ(w.check(37), V::kTooOld);
  EXPECT_EQ(w.check(38), V::kInWindow);
}

TEST(ReplayWindowTest, LargeJumpForgetsEverything) {
  ReplayWindow w(64);
  for (uint64_t s = 1; s <= 64; ++s) w.accept(s);
  EXPECT_EQ(w.accept(64 + 1000), V::kNewHighest);
  // Slots reused by the ring must not report old sequence numbers as seen.
  for (uint64_t s = 1064 - 63; s < 1064; ++s) EXPECT_EQ(w.check(s), V::kInWindow) << s;
}

TEST(ReplayWindowTest, CheckDoesNotChangeState) {
  ReplayWindow w(64);
  w.accept(5);
  EXPECT_EQ(w.check(9), V::kNewHighest);
  EXPECT_EQ(w.check(3), V::kInWindow);
  EXPECT_EQ(w.highest(), 5u);
  EXPECT_EQ(w.accept(3), V::kInWindow);
}

// Against a reference model that remembers everything.
TEST(ReplayWindowTest, MatchesReferenceModelOnRandomTraffic) {
  for (uint32_t size : {64u, 128u, 1024u}) {
    ReplayWindow w(size);
    std::set<uint64_t> seen;
    uint64_t highest = 0;
    std::mt19937_64 rng(size);
    for (int i = 0; i < 100000; ++i) {
      uint64_t s;
      const int r = static_cast<int>(rng() % 10);
      if (r < 5) {
        s = highest + 1 + rng() % 3;
      } else if (r < 9) {
        s = highest > 0 ? highest - std::min<uint64_t>(highest - 1, rng() % (size + 40)) : 1;
      } else {
        s = highest + rng() % (3 * size);
      }
      V expect;
      if (s == 0) expect = V::kTooOld;
      else if (s > highest) expect = V::kNewHighest;
      else if (highest - s >= w.size()) expect = V::kTooOld;
      else expect = seen.count(s) ? V::kDuplicate : V::kInWindow;
      ASSERT_EQ(w.accept(s), expect) << "i=" << i << " s=" << s << " highest=" << highest;
      if (expect == V::kNewHighest || expect == V::kInWindow) seen.insert(s);
      if (expect == V::kNewHighest) highest = s;
    }
  }
}

}  // namespace
}  // namespace hemm::net
