// Sliding-bitmap replay window over 64-bit sequence numbers (RFC 4303 style):
// remembers which of the last `size` sequence numbers below the highest seen
// have arrived. Sequence numbers start at 1; 0 is never valid.
//
// check() is pure; accept() records. Callers check, verify the tag, then
// accept, so an unauthenticated datagram never moves the window.
#pragma once

#include <cstdint>
#include <vector>

namespace hemm::net {

class ReplayWindow {
 public:
  enum class Verdict {
    kNewHighest,  // beyond the highest seen
    kInWindow,    // below the highest but inside the window and not seen (reordered)
    kDuplicate,   // inside the window and already seen
    kTooOld,      // behind the window (or 0): cannot tell, reject as replay
  };

  // size is rounded up to a multiple of 64, minimum 64.
  explicit ReplayWindow(uint32_t size = 1024);

  Verdict check(uint64_t seq) const;
  // Records seq; returns the verdict check() would have given. kDuplicate and
  // kTooOld record nothing.
  Verdict accept(uint64_t seq);

  uint64_t highest() const { return highest_; }
  uint32_t size() const { return size_; }

 private:
  bool bit(uint64_t seq) const { return (bits_[(seq % size_) / 64] >> (seq % 64)) & 1u; }
  void set(uint64_t seq) { bits_[(seq % size_) / 64] |= uint64_t{1} << (seq % 64); }
  void clear(uint64_t seq) { bits_[(seq % size_) / 64] &= ~(uint64_t{1} << (seq % 64)); }

  uint32_t size_;
  uint64_t highest_ = 0;
  std::vector<uint64_t> bits_;
};

}  // namespace hemm::net
