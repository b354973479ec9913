#include "common/concurrency/newest_mailbox.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>

namespace hemm {
namespace {

TEST(NewestMailbox, NewestWinsAndEachValueIsTakenOnce) {
  NewestMailbox<int> mb;
  int out = -1;
  EXPECT_EQ(mb.take(), nullptr);
  EXPECT_FALSE(mb.take(out));
  EXPECT_EQ(out, -1);  // untouched when nothing is new
  EXPECT_EQ(mb.latest(), nullptr);
  mb.publish(1);
  mb.publish(2);
  mb.publish(3);
  const int* v = mb.take();
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(*v, 3);
  EXPECT_EQ(mb.take(), nullptr);
  EXPECT_EQ(*mb.latest(), 3);  // the last taken value stays readable
  mb.back() = 4;               // filled in place
  mb.publish();
  ASSERT_TRUE(mb.take(out));
  EXPECT_EQ(out, 4);
  EXPECT_FALSE(mb.take(out));
  EXPECT_EQ(mb.published(), 4u);
}

// Producer, shared and consumer state on distinct cache lines: the servo
// thread publishes every tick while another thread polls.
TEST(NewestMailbox, SharedStateHasItsOwnCacheLine) { EXPECT_GE(alignof(NewestMailbox<char>), 64u); }

struct Item {
  std::uint64_t seq = 0;
  std::uint64_t check = 0;  // = seq * 3 + 1 when whole
  std::array<std::uint64_t, 30> pad{};
};

// One producer, one consumer, both ways of publishing and taking: the
// consumer never sees a torn item, never goes backwards, and sees the last.
void run_concurrent(bool in_place) {
  NewestMailbox<Item> mb;
  constexpr std::uint64_t kN = 200'000;
  std::atomic<bool> done{false};
  std::thread producer([&] {
    Item copy;
    for (std::uint64_t i = 1; i <= kN; ++i) {
      Item& it = in_place ? mb.back() : copy;
      it.seq = i;
      for (auto& p : it.pad) p = i;
      it.check = i * 3 + 1;
      if (in_place) {
        mb.publish();
      } else {
        mb.publish(copy);
      }
    }
    done.store(true);
  });
  std::uint64_t last = 0, taken = 0, torn = 0, backwards = 0;
  Item out;
  while (true) {
    const bool finished = done.load();
    while (true) {
      const Item* it = nullptr;
      if (in_place) {
        it = mb.take();
      } else if (mb.take(out)) {
        it = &out;
      }
      if (it == nullptr) break;
      ++taken;
      torn += it->check != it->seq * 3 + 1;
      for (auto p : it->pad) torn += p != it->seq;
      backwards += it->seq <= last;
      last = it->seq;
    }
    if (finished) break;
  }
  producer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(last, kN);  // the final value is never lost
  EXPECT_GT(taken, 0u);
}

TEST(NewestMailbox, ConcurrentInPlaceItemsAreWholeAndInOrder) { run_concurrent(true); }
TEST(NewestMailbox, ConcurrentCopiedItemsAreWholeAndInOrder) { run_concurrent(false); }

}  // namespace
}  // namespace hemm
