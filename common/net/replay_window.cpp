#include "common/net/replay_window.h"

namespace hemm::net {

ReplayWindow::ReplayWindow(uint32_t size) {
  if (size < 64) size = 64;
  size_ = (size + 63) / 64 * 64;
  bits_.assign(size_ / 64, 0);
}

ReplayWindow::Verdict ReplayWindow::check(uint64_t seq) const {
  if (seq == 0) return Verdict::kTooOld;
  if (seq > highest_) return Verdict::kNewHighest;
  if (highest_ - seq >= size_) return Verdict::kTooOld;
  return bit(seq) ? Verdict::kDuplicate : Verdict::kInWindow;
}

ReplayWindow::Verdict ReplayWindow::accept(uint64_t seq) {
  const Verdict v = check(seq);
  switch (v) {
    case Verdict::kNewHighest: {
      const uint64_t d = seq - highest_;
      if (d >= size_) {
        std::fill(bits_.begin(), bits_.end(), 0);
      } else {
        // Slots of highest+1 .. seq-1 held sequence numbers now behind the window.
        for (uint64_t s = highest_ + 1; s < seq; ++s) clear(s);
      }
      clear(seq);
      set(seq);
      highest_ = seq;
      break;
    }
    case Verdict::kInWindow: set(seq); break;
    case Verdict::kDuplicate:
    case Verdict::kTooOld: break;
  }
  return v;
}

}  // namespace hemm::net
