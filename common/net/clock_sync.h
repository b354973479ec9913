// Clock offset and round-trip time from NTP-style ping/pong samples.
//
// For one exchange (t1, t4 on our clock, t2, t3 on the peer's):
//   rtt    = (t4 - t1) - (t3 - t2)
//   offset = ((t2 - t1) + (t3 - t4)) / 2      (peer clock minus ours)
// A single sample's offset error is half the difference between its forward
// and backward one-way delays, so jitter (and jitter that differs per
// direction) makes single samples unreliable. Writing theta for the true
// offset and d_f, d_b for the one-way delays:
//   t2 - t1 = theta + d_f        t3 - t4 = theta - d_b
// so over a sliding window, min(t2 - t1) = theta + min d_f and
// max(t3 - t4) = theta - min d_b. The estimate is their midpoint: the
// minimum delay of each direction is picked independently (from different
// samples), which makes it robust to asymmetric jitter, then smoothed by a
// first-order filter. Its error is (min d_f - min d_b)/2: a constant
// asymmetry of the base delays is unobservable by any two-way method and
// shows up as half that asymmetry. RTT statistics (min/median/last) come
// from the same window.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>

namespace hemm::net {

struct ClockSample {
  int64_t rtt_ns = 0;
  int64_t offset_ns = 0;
  int64_t forward_ns = 0;   // t2 - t1 = offset + forward delay
  int64_t backward_ns = 0;  // t3 - t4 = offset - backward delay
};

// Returns false if the times are inconsistent (negative rtt or t3 < t2).
bool make_clock_sample(int64_t t1, int64_t t2, int64_t t3, int64_t t4, ClockSample* out);

struct ClockEstimatorParams {
  size_t window = 256;     // samples kept (at 20 Hz pings: 12.8 s)
  double smoothing = 0.2;  // filter gain per new estimate (1: no smoothing)
};

struct ClockEstimate {
  bool valid = false;
  int64_t offset_ns = 0;      // filtered peer-minus-local offset
  int64_t rtt_min_ns = 0;     // minimum over the window
  int64_t rtt_median_ns = 0;  // median over the window
  int64_t rtt_last_ns = 0;
  uint64_t samples = 0;       // total samples accepted
};

class ClockOffsetEstimator {
 public:
  explicit ClockOffsetEstimator(ClockEstimatorParams p = {}) : p_(p) {}
  // Adds one sample; returns false (no state change) if it is inconsistent.
  bool add(int64_t t1, int64_t t2, int64_t t3, int64_t t4);
  // Forgets every sample: a new peer (a new session) has its own clock and path.
  void reset();
  const ClockEstimate& estimate() const { return est_; }
  // Maps a peer time stamp to our clock.
  int64_t peer_to_local(int64_t peer_ns) const { return peer_ns - est_.offset_ns; }

 private:
  ClockEstimatorParams p_;
  std::deque<ClockSample> window_;
  double filtered_ = 0.0;
  ClockEstimate est_;
};

// How old a message stamped on the peer's clock is when it arrives, judged
// with the link's clock estimate. Mapped with the midpoint offset, a message
// that took the least delay in its direction appears rtt_min / 2 old whatever
// the asymmetry of the path (the offset error and the one-way delay cancel),
// so `excess` is exactly how much longer than the fastest message this one
// took: the time something on the path held it.
struct MessageAge {
  bool known = false;     // false: no clock estimate yet
  int64_t age_ns = 0;     // arrival minus the stamp mapped to our clock
  int64_t excess_ns = 0;  // age - rtt_min / 2, at least 0
  bool stale = true;      // unknown, older than rtt_median + margin, or from the future by more than the margin
};
MessageAge judge_message_age(const ClockEstimate& e, int64_t peer_stamp_ns, int64_t local_arrival_ns,
                             int64_t margin_ns);

}  // namespace hemm::net
