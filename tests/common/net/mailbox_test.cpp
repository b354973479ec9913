#include "common/net/mailbox.h"

#include <gtest/gtest.h>

#include <thread>

namespace hemm::net {
namespace {

struct Item {
  uint64_t seq = 0;
  uint64_t check = 0;  // = seq * 3 + 1 when consistent
  std::array<uint64_t, 16> pad{};
};

TEST(MailboxTest, NewestWinsSingleThread) {
  NewestMailbox<int> mb;
  EXPECT_EQ(mb.take(), nullptr);
  EXPECT_EQ(mb.latest(), nullptr);
  mb.publish(1);
  mb.publish(2);
  mb.publish(3);
  const int* v = mb.take();
  ASSERT_NE(v, nullptr);
  EXPECT_EQ(*v, 3);
  EXPECT_EQ(mb.take(), nullptr);
  EXPECT_EQ(*mb.latest(), 3);
  mb.back() = 4;
  mb.publish();
  EXPECT_EQ(*mb.take(), 4);
  EXPECT_EQ(mb.published(), 4u);
}

// One producer, one consumer: the consumer never sees a torn item and never
// goes backwards, and eventually sees the last one.
TEST(MailboxTest, ConcurrentProducerConsumerSeeConsistentMonotonicItems) {
  NewestMailbox<Item> mb;
  constexpr uint64_t kN = 200000;
  std::thread producer([&] {
    for (uint64_t i = 1; i <= kN; ++i) {
      Item& it = mb.back();
      it.seq = i;
      for (auto& p : it.pad) p = i;
      it.check = i * 3 + 1;
      mb.publish();
    }
  });
  uint64_t last = 0, taken = 0;
  bool ok = true;
  while (last < kN) {
    if (const Item* it = mb.take()) {
      ++taken;
      if (it->check != it->seq * 3 + 1 || it->seq <= last) ok = false;
      for (auto p : it->pad)
        if (p != it->seq) ok = false;
      last = it->seq;
    }
  }
  producer.join();
  EXPECT_TRUE(ok);
  EXPECT_EQ(last, kN);
  EXPECT_GT(taken, 0u);
}

}  // namespace
}  // namespace hemm::net
