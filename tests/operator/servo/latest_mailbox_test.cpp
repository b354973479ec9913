#include "operator/servo/latest_mailbox.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

namespace hemm::servo {
namespace {

TEST(LatestMailbox, NewestWinsAndEachValueIsTakenOnce) {
  LatestMailbox<int> m;
  int v = 0;
  EXPECT_FALSE(m.take(v));
  m.put(1);
  m.put(2);
  m.put(3);
  ASSERT_TRUE(m.take(v));
  EXPECT_EQ(v, 3);
  EXPECT_FALSE(m.take(v));
  m.put(4);
  ASSERT_TRUE(m.take(v));
  EXPECT_EQ(v, 4);
  EXPECT_EQ(m.puts(), 4u);
}

TEST(LatestMailbox, ConsumerSeesOnlyWholeValuesInIncreasingOrder) {
  struct Big {
    std::uint64_t seq = 0;
    std::uint64_t fill[31] = {};
  };
  LatestMailbox<Big> m;
  constexpr std::uint64_t kN = 200'000;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    Big b;
    for (std::uint64_t i = 1; i <= kN; ++i) {
      b.seq = i;
      for (auto& f : b.fill) f = i * 2654435761u;
      m.put(b);
    }
    done.store(true);
  });
  std::uint64_t last = 0, torn = 0, backwards = 0, takes = 0;
  Big b;
  while (true) {
    const bool finished = done.load();
    while (m.take(b)) {
      ++takes;
      for (auto f : b.fill) torn += (f != b.seq * 2654435761u);
      backwards += (b.seq <= last);
      last = b.seq;
    }
    if (finished) break;
  }
  producer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(last, kN);  // the final value is never lost
  EXPECT_GT(takes, 0u);
}

}  // namespace
}  // namespace hemm::servo
