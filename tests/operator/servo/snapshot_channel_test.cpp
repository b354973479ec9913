// SnapshotChannel stress: a publisher and a reader thread; the reader must only
// ever see complete snapshots in publish order, no snapshot may be freed on
// the reader thread, and nothing may leak (live-object count back to zero).
#include "operator/servo/snapshot_channel.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <thread>

namespace hemm::servo {
namespace {

std::atomic<long> g_live{0};
std::atomic<long> g_freed_on_reader{0};
thread_local bool t_is_reader = false;

struct Snap {
  explicit Snap(std::uint64_t v) : version(v) {
    for (std::size_t i = 0; i < kN; ++i) data[i] = v * 1000003u + i;
    g_live.fetch_add(1);
  }
  ~Snap() {
    if (t_is_reader) g_freed_on_reader.fetch_add(1);
    version = 0xdead;  // a reader using a freed snapshot would see this (and ASan would fire)
    g_live.fetch_sub(1);
  }
  bool complete() const {
    for (std::size_t i = 0; i < kN; ++i)
      if (data[i] != version * 1000003u + i) return false;
    return true;
  }
  static constexpr std::size_t kN = 256;
  std::uint64_t version;
  std::uint64_t data[kN];
};

TEST(SnapshotChannel, BeforeFirstPublishReaderGetsNull) {
  SnapshotChannel<Snap> ch;
  EXPECT_EQ(ch.acquire(), nullptr);
  ch.publish(std::make_unique<Snap>(1));
  const Snap* s = ch.acquire();
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->version, 1u);
  EXPECT_EQ(ch.acquire(), s);  // unchanged until the next publish
}

TEST(SnapshotChannel, StressReaderSeesOnlyCompleteSnapshotsAndNothingLeaks) {
  const long live_before = g_live.load();
  {
    SnapshotChannel<Snap> ch(4);  // small retire ring: exercises the stall path too
    constexpr std::uint64_t kPublishes = 20'000;
    std::atomic<bool> done{false};
    std::atomic<std::uint64_t> seen_version{0};
    std::uint64_t incomplete = 0, backwards = 0, seen = 0, distinct = 0, last = 0;
    std::thread reader([&] {
      t_is_reader = true;
      while (!done.load(std::memory_order_acquire)) {
        const Snap* s = ch.acquire();
        if (s == nullptr) continue;
        ++seen;
        if (!s->complete()) ++incomplete;
        if (s->version < last) ++backwards;
        if (s->version != last) ++distinct;
        last = s->version;
        seen_version.store(last, std::memory_order_relaxed);
      }
      // Final look: the newest must be the last published.
      const Snap* s = ch.acquire();
      if (s != nullptr && s->version != kPublishes) ++backwards;
    });
    for (std::uint64_t v = 1; v <= kPublishes; ++v) {
      ch.publish(std::make_unique<Snap>(v));
      // Keep the two threads interleaved even on a loaded machine: let the
      // reader come within 256 versions (or give up after 2 s).
      if (v % 64 == 0) {
        const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
        while (seen_version.load(std::memory_order_relaxed) + 256 < v &&
               std::chrono::steady_clock::now() < until)
          std::this_thread::yield();
      }
    }
    done.store(true, std::memory_order_release);
    reader.join();
    ch.collect();
    EXPECT_EQ(incomplete, 0u);
    EXPECT_EQ(backwards, 0u);
    EXPECT_GT(seen, 0u);
    EXPECT_GT(distinct, 1u);
    EXPECT_EQ(ch.published(), kPublishes);
    // Every snapshot is freed exactly once: superseded, collected, or (at most
    // the pending and the current one) by the destructor.
    EXPECT_LE(g_live.load() - live_before, 2);
    EXPECT_GE(ch.superseded() + ch.freed_by_collect(), kPublishes - 2);
  }
  EXPECT_EQ(g_live.load(), live_before);
  EXPECT_EQ(g_freed_on_reader.load(), 0);
}

}  // namespace
}  // namespace hemm::servo
