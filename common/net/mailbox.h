// Newest-wins mailbox between one producer thread (the network thread) and
// one consumer thread (e.g. the 1 kHz servo thread): a triple buffer. Both
// sides are wait-free: publish() and take() are a buffer write/read plus one
// atomic exchange; neither ever blocks, locks or allocates by itself (copying
// a T may allocate on the producer's side if T owns heap memory; the
// consumer only reads in place). Exactly one producer and one consumer.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace hemm::net {

template <class T>
class NewestMailbox {
 public:
  // Producer: the slot to fill, then publish(). Never read by the consumer
  // until published.
  T& back() { return buf_[back_]; }
  void publish() {
    const uint8_t old = middle_.exchange(static_cast<uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = old & kIndex;
    ++published_;
  }
  void publish(const T& v) {
    back() = v;
    publish();
  }

  // Consumer: if something newer was published since the last take(),
  // swaps it in and returns a pointer to it (valid until the next take());
  // otherwise returns nullptr. latest() always gives the last taken value.
  const T* take() {
    if (!(middle_.load(std::memory_order_acquire) & kFresh)) return nullptr;
    const uint8_t old = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = old & kIndex;
    has_value_ = true;
    return &buf_[front_];
  }
  const T* latest() const { return has_value_ ? &buf_[front_] : nullptr; }

  // Producer side count (read it only on the producer thread).
  uint64_t published() const { return published_; }

 private:
  static constexpr uint8_t kIndex = 3;
  static constexpr uint8_t kFresh = 4;

  std::array<T, 3> buf_{};
  uint8_t back_ = 0;             // producer-owned
  uint8_t front_ = 1;            // consumer-owned
  std::atomic<uint8_t> middle_{2};
  bool has_value_ = false;       // consumer-owned
  uint64_t published_ = 0;       // producer-owned
};

}  // namespace hemm::net
