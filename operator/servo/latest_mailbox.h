// A single-producer single-consumer "newest wins" mailbox (a triple buffer).
// The producer (servo thread) overwrites freely; the consumer (network thread)
// gets the newest value written since its last take, or nothing. Neither side
// allocates, locks or waits: each operation is one atomic exchange.
#pragma once

#include <atomic>
#include <cstdint>

namespace hemm::servo {

template <class T>
class LatestMailbox {
 public:
  LatestMailbox() = default;
  LatestMailbox(const LatestMailbox&) = delete;
  LatestMailbox& operator=(const LatestMailbox&) = delete;

  // Producer side.
  void put(const T& v) noexcept {
    buffers_[back_] = v;
    // Hand the filled buffer over as the middle one, marked fresh; take the old
    // middle as the next back buffer.
    const std::uint32_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = old & kIndexMask;
    ++puts_;
  }
  std::uint64_t puts() const noexcept { return puts_; }  // producer side only

  // Consumer side: true and `out` set if a value was put since the last take.
  bool take(T& out) noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) == 0) return false;
    const std::uint32_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndexMask;
    out = buffers_[front_];
    return true;
  }

 private:
  static constexpr std::uint32_t kFresh = 4;
  static constexpr std::uint32_t kIndexMask = 3;
  T buffers_[3]{};
  std::uint32_t back_ = 0;                  // producer-owned
  alignas(64) std::atomic<std::uint32_t> middle_{1};
  alignas(64) std::uint32_t front_ = 2;     // consumer-owned
  std::uint64_t puts_ = 0;
};

}  // namespace hemm::servo
