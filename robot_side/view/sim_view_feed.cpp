#include "robot_side/view/sim_view_feed.h"

#include <algorithm>

namespace hemm::robot {

bool SimViewFeed::publish(SimViewFrame& frame) {
  std::unique_lock<std::mutex> lk(mu_, std::try_to_lock);
  if (!lk.owns_lock()) {
    busy_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  std::swap(slot_, frame);
  fresh_ = true;
  next_ns_.store(slot_.t_ns + interval_ns_.load(std::memory_order_relaxed), std::memory_order_relaxed);
  frames_.fetch_add(1, std::memory_order_relaxed);
  return true;
}

void SimViewFeed::publish_scans(const std::vector<RangeScanData>& scans) {
  if (scans.empty()) return;
  std::unique_lock<std::mutex> lk(mu_, std::try_to_lock);
  if (!lk.owns_lock()) {
    busy_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  for (const RangeScanData& s : scans) {
    auto it = std::find_if(scans_.begin(), scans_.end(),
                           [&](const RangeScanData& o) { return o.sensor_name == s.sensor_name; });
    if (it == scans_.end()) {
      scans_.push_back(s);
    } else if (s.stamp_ns >= it->stamp_ns) {
      *it = s;
    }
  }
}

bool SimViewFeed::take(SimViewFrame& out) {
  std::lock_guard<std::mutex> lk(mu_);
  if (!fresh_) return false;
  std::swap(out, slot_);
  out.scans = scans_;
  fresh_ = false;
  return true;
}

}  // namespace hemm::robot
