#include "common/net/clock_sync.h"

#include <algorithm>
#include <vector>

namespace hemm::net {

bool make_clock_sample(int64_t t1, int64_t t2, int64_t t3, int64_t t4, ClockSample* out) {
  // Differences in 128 bits would be exact; hostile time stamps are bounded here instead.
  constexpr int64_t kLimit = int64_t{1} << 62;
  for (int64_t t : {t1, t2, t3, t4})
    if (t > kLimit || t < -kLimit) return false;
  if (t3 < t2 || t4 < t1) return false;
  const int64_t rtt = (t4 - t1) - (t3 - t2);
  if (rtt < 0) return false;
  out->rtt_ns = rtt;
  out->offset_ns = ((t2 - t1) + (t3 - t4)) / 2;
  out->forward_ns = t2 - t1;
  out->backward_ns = t3 - t4;
  return true;
}

bool ClockOffsetEstimator::add(int64_t t1, int64_t t2, int64_t t3, int64_t t4) {
  ClockSample s;
  if (!make_clock_sample(t1, t2, t3, t4, &s)) return false;
  window_.push_back(s);
  while (window_.size() > std::max<size_t>(p_.window, 1)) window_.pop_front();

  int64_t min_forward = window_.front().forward_ns, max_backward = window_.front().backward_ns;
  std::vector<int64_t> rtts;
  rtts.reserve(window_.size());
  for (const ClockSample& w : window_) {
    min_forward = std::min(min_forward, w.forward_ns);
    max_backward = std::max(max_backward, w.backward_ns);
    rtts.push_back(w.rtt_ns);
  }
  const double raw = 0.5 * (static_cast<double>(min_forward) + static_cast<double>(max_backward));
  std::sort(rtts.begin(), rtts.end());

  if (!est_.valid) {
    filtered_ = raw;
  } else {
    filtered_ += p_.smoothing * (raw - filtered_);
  }
  est_.valid = true;
  est_.offset_ns = static_cast<int64_t>(filtered_);
  est_.rtt_min_ns = rtts.front();
  est_.rtt_median_ns = rtts[rtts.size() / 2];
  est_.rtt_last_ns = s.rtt_ns;
  ++est_.samples;
  return true;
}

void ClockOffsetEstimator::reset() {
  window_.clear();
  filtered_ = 0.0;
  est_ = ClockEstimate{};
}

MessageAge judge_message_age(const ClockEstimate& e, int64_t peer_stamp_ns, int64_t local_arrival_ns,
                             int64_t margin_ns) {
  MessageAge a;
  constexpr int64_t kLimit = int64_t{1} << 61;  // hostile stamps: keep the differences exact
  if (!e.valid || e.offset_ns > kLimit || e.offset_ns < -kLimit || peer_stamp_ns > kLimit || peer_stamp_ns < -kLimit || local_arrival_ns > kLimit ||
      local_arrival_ns < -kLimit) {
    return a;
  }
  a.known = true;
  a.age_ns = local_arrival_ns - (peer_stamp_ns - e.offset_ns);
  a.excess_ns = std::max<int64_t>(0, a.age_ns - e.rtt_min_ns / 2);
  a.stale = a.age_ns > e.rtt_median_ns + margin_ns || a.age_ns < -margin_ns;
  return a;
}

}  // namespace hemm::net
