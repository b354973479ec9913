#include "operator/device/replay_device.h"

#include <cmath>
#include <stdexcept>

namespace hemm::device {

ReplayDevice::ReplayDevice(Trajectory trajectory, const DeviceLimits& limits, double dt_s,
                           std::size_t force_capacity)
    : trajectory_(std::move(trajectory)), limits_(limits), dt_s_(dt_s) {
  if (trajectory_.samples.empty()) throw std::invalid_argument("ReplayDevice: empty trajectory");
  for (std::size_t i = 1; i < trajectory_.samples.size(); ++i)
    if (!(trajectory_.samples[i].t_s > trajectory_.samples[i - 1].t_s))
      throw std::invalid_argument("ReplayDevice: times not strictly increasing");
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) throw std::invalid_argument("ReplayDevice: dt_s <= 0");
  forces_.resize(force_capacity);
}

bool ReplayDevice::finished() const noexcept {
  const auto& s = trajectory_.samples;
  return time_s() >= s.back().t_s - s.front().t_s;
}

void ReplayDevice::read(DeviceSample& out) noexcept {
  const auto& s = trajectory_.samples;
  const double t = s.front().t_s + time_s();
  while (cursor_ + 1 < s.size() && s[cursor_ + 1].t_s <= t) ++cursor_;
  const TrajectorySample& a = s[cursor_];
  out.buttons = a.buttons;
  if (cursor_ + 1 >= s.size()) {
    out.position_H = a.position_H;
    out.orientation_H = a.orientation_H;
    out.velocity_H.setZero();
    return;
  }
  const TrajectorySample& b = s[cursor_ + 1];
  const double dt = b.t_s - a.t_s;
  const double u = (t - a.t_s) / dt;
  out.position_H = a.position_H + u * (b.position_H - a.position_H);
  out.orientation_H = a.orientation_H.slerp(u, b.orientation_H);
  out.velocity_H = (b.position_H - a.position_H) / dt;
}

void ReplayDevice::write(const Eigen::Vector3d& force_H) noexcept {
  const std::size_t n = force_count_.load(std::memory_order_relaxed);
  if (n < forces_.size()) {
    forces_[n].t_s = time_s();
    forces_[n].force_H = force_H;
    force_count_.store(n + 1, std::memory_order_release);
  } else {
    forces_dropped_.fetch_add(1, std::memory_order_relaxed);
  }
  ++ticks_;
}

}  // namespace hemm::device
