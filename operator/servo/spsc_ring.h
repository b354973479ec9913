// A bounded single-producer single-consumer ring. Storage is allocated once in
// the constructor; try_push/try_pop never allocate, lock or block (a full ring
// refuses the push, an empty one the pop). Exactly one thread may push and one
// (other) thread may pop.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>

namespace hemm::servo {

// Separates the two indices so producer and consumer do not share a line.
inline constexpr std::size_t kCacheLine = 64;

template <class T>
class SpscRing {
  static_assert(std::is_copy_assignable_v<T> && std::is_default_constructible_v<T>,
                "SpscRing holds default-constructible, copyable values");

 public:
  // capacity: a power of two >= 2.
  explicit SpscRing(std::size_t capacity) : mask_(capacity - 1), slots_(new T[capacity]) {
    if (capacity < 2 || (capacity & (capacity - 1)) != 0)
      throw std::invalid_argument("SpscRing: capacity must be a power of two >= 2");
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  std::size_t capacity() const noexcept { return mask_ + 1; }

  // Producer side.
  bool try_push(const T& v) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ > mask_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ > mask_) return false;
    }
    slots_[head & mask_] = v;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  // Producer side: true if a push would fail now (the consumer can only make room).
  bool full() const noexcept {
    return head_.load(std::memory_order_relaxed) - tail_.load(std::memory_order_acquire) > mask_;
  }

  // Consumer side.
  bool try_pop(T& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail == head_cache_) return false;
    }
    out = slots_[tail & mask_];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Either side; approximate while the other side runs.
  std::size_t size() const noexcept {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }

 private:
  const std::size_t mask_;
  std::unique_ptr<T[]> slots_;
  alignas(kCacheLine) std::atomic<std::size_t> head_{0};  // next slot to write
  std::size_t tail_cache_ = 0;                            // producer's view of tail_
  alignas(kCacheLine) std::atomic<std::size_t> tail_{0};  // next slot to read
  std::size_t head_cache_ = 0;                            // consumer's view of head_
};

}  // namespace hemm::servo
