#include "operator/servo/spsc_ring.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <thread>

namespace hemm::servo {
namespace {

TEST(SpscRing, FifoOrderFullAndEmpty) {
  SpscRing<int> r(4);
  int v = -1;
  EXPECT_FALSE(r.try_pop(v));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(r.try_push(i));
  EXPECT_TRUE(r.full());
  EXPECT_FALSE(r.try_push(99));
  EXPECT_EQ(r.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(r.try_pop(v));
  // Wrap around many times.
  for (int i = 0; i < 100; ++i) {
    ASSERT_TRUE(r.try_push(i));
    ASSERT_TRUE(r.try_push(i + 1000));
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i);
    ASSERT_TRUE(r.try_pop(v));
    EXPECT_EQ(v, i + 1000);
  }
}

TEST(SpscRing, RejectsCapacityThatIsNotAPowerOfTwo) {
  EXPECT_THROW(SpscRing<int>(3), std::invalid_argument);
  EXPECT_THROW(SpscRing<int>(1), std::invalid_argument);
  EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
}

TEST(SpscRing, TwoThreadsDeliverEveryValueInOrder) {
  struct Item {
    std::uint64_t seq = 0, check = 0;
  };
  SpscRing<Item> r(64);
  constexpr std::uint64_t kN = 300'000;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kN;) {
      if (r.try_push(Item{i, ~i})) ++i;
      else std::this_thread::yield();
    }
  });
  std::uint64_t expect = 0, bad = 0;
  Item it;
  while (expect < kN) {
    if (r.try_pop(it)) {
      if (it.seq != expect || it.check != ~expect) ++bad;
      ++expect;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_EQ(bad, 0u);
  EXPECT_FALSE(r.try_pop(it));
}

}  // namespace
}  // namespace hemm::servo
