// Immutable snapshots from one publisher thread (e.g. the model thread) to one
// reader thread (the servo thread), without locks, waits or frees on the
// reader side.
//
// Ownership moves only through atomic exchanges, so no snapshot is ever freed
// while the reader may hold it:
//  - publish(): the new snapshot replaces the pending one; a pending snapshot
//    the reader never took is freed right there (the reader cannot have it).
//  - acquire() (reader): takes the pending snapshot if there is one and hands
//    the one it held so far back through an SPSC "retired" ring; the publisher
//    frees retired snapshots in collect() (called by publish()). The returned
//    pointer stays valid until the reader's next acquire().
//  - If the retired ring were ever full the reader keeps its current snapshot
//    and takes the new one at a later tick rather than free anything itself.
// On destruction (both threads stopped) everything left is freed.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

#include "operator/servo/spsc_ring.h"

namespace hemm::servo {

template <class T>
class SnapshotChannel {
 public:
  explicit SnapshotChannel(std::size_t retire_capacity = 16) : retired_(retire_capacity) {}
  SnapshotChannel(const SnapshotChannel&) = delete;
  SnapshotChannel& operator=(const SnapshotChannel&) = delete;
  ~SnapshotChannel() {
    collect();
    delete pending_.load(std::memory_order_acquire);
    delete current_;
  }

  // Publisher side. Takes ownership; null is ignored.
  void publish(std::unique_ptr<const T> snapshot) {
    collect();
    if (!snapshot) return;
    const T* old = pending_.exchange(snapshot.release(), std::memory_order_acq_rel);
    if (old != nullptr) {
      delete old;  // superseded before the reader took it
      superseded_.fetch_add(1, std::memory_order_relaxed);
    }
    published_.fetch_add(1, std::memory_order_relaxed);
  }

  // Publisher side: frees what the reader has retired. Returns how many.
  std::size_t collect() {
    std::size_t n = 0;
    const T* p = nullptr;
    while (retired_.try_pop(p)) {
      delete p;
      ++n;
    }
    freed_.fetch_add(n, std::memory_order_relaxed);
    return n;
  }

  // Reader side: the newest snapshot, or null before the first publish.
  const T* acquire() noexcept {
    if (pending_.load(std::memory_order_relaxed) == nullptr) return current_;
    if (current_ != nullptr && retired_.full()) {
      retire_stalls_.fetch_add(1, std::memory_order_relaxed);
      return current_;
    }
    const T* fresh = pending_.exchange(nullptr, std::memory_order_acq_rel);
    if (fresh == nullptr) return current_;
    if (current_ != nullptr) retired_.try_push(current_);  // cannot fail: checked not full
    current_ = fresh;
    return current_;
  }

  // Counters, readable from any thread.
  std::uint64_t published() const noexcept { return published_.load(std::memory_order_relaxed); }
  std::uint64_t superseded() const noexcept { return superseded_.load(std::memory_order_relaxed); }
  std::uint64_t freed_by_collect() const noexcept { return freed_.load(std::memory_order_relaxed); }
  std::uint64_t retire_stalls() const noexcept {
    return retire_stalls_.load(std::memory_order_relaxed);
  }

 private:
  std::atomic<const T*> pending_{nullptr};
  const T* current_ = nullptr;  // reader-owned
  SpscRing<const T*> retired_;  // reader -> publisher
  std::atomic<std::uint64_t> published_{0}, superseded_{0}, freed_{0}, retire_stalls_{0};
};

}  // namespace hemm::servo
