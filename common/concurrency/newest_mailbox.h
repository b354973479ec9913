// Newest-wins mailbox between exactly one producer thread and one consumer
// thread: a triple buffer. The servo thread publishes setpoints and log
// records to the network and view threads through it; the network thread
// publishes commands and robot states to the simulation and model threads.
// Both sides are wait-free: an operation is a buffer write or read plus one
// atomic exchange; nothing blocks, locks or allocates (copying a T that owns
// heap memory may allocate, on the side that copies).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace hemm {

template <class T>
class NewestMailbox {
 public:
  NewestMailbox() = default;
  NewestMailbox(const NewestMailbox&) = delete;
  NewestMailbox& operator=(const NewestMailbox&) = delete;

  // Producer: fill back() in place, then publish(); or publish(v) to copy.
  // The consumer never reads the back buffer until it is published.
  T& back() noexcept { return buf_[back_]; }
  void publish() noexcept {
    // The filled buffer becomes the middle one, marked fresh; the old middle
    // becomes the next back buffer.
    const std::uint32_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = old & kIndex;
    ++published_;
  }
  void publish(const T& v) {
    back() = v;
    publish();
  }
  std::uint64_t published() const noexcept { return published_; }  // read on the producer thread only

  // Consumer: if something was published since the last take, swaps it in
  // and returns it in place (valid until the next take); else nullptr.
  const T* take() noexcept {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return nullptr;
    const std::uint32_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndex;
    has_value_ = true;
    return &buf_[front_];
  }
  // Consumer: the same, copied into `out`; false (out untouched) if nothing new.
  bool take(T& out) {
    const T* v = take();
    if (v == nullptr) return false;
    out = *v;
    return true;
  }
  // Consumer: the last value taken, or nullptr before the first.
  const T* latest() const noexcept { return has_value_ ? &buf_[front_] : nullptr; }

 private:
  static constexpr std::uint32_t kIndex = 3;
  static constexpr std::uint32_t kFresh = 4;

  std::array<T, 3> buf_{};
  // Producer-owned, consumer-owned and shared state on separate cache lines
  // so the two threads do not invalidate each other's lines on every call.
  std::uint32_t back_ = 0;
  std::uint64_t published_ = 0;
  alignas(64) std::atomic<std::uint32_t> middle_{1};
  alignas(64) std::uint32_t front_ = 2;
  bool has_value_ = false;
};

}  // namespace hemm
