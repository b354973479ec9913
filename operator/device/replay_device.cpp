#include "operator/device/replay_device.h"

#include <cmath>
#include <stdexcept>

namespace hemm::device {

ReplayDevice::ReplayDevice(Trajectory trajectory, const DeviceLimits& limits, double dt_s,
                           std::size_t command_capacity)
    : trajectory_(std::move(trajectory)), limits_(limits), dt_s_(dt_s) {
  if (trajectory_.samples.empty()) throw std::invalid_argument("ReplayDevice: empty trajectory");
  for (std::size_t i = 1; i < trajectory_.samples.size(); ++i)
    if (!(trajectory_.samples[i].t_s > trajectory_.samples[i - 1].t_s))
      throw std::invalid_argument("ReplayDevice: times not strictly increasing");
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) throw std::invalid_argument("ReplayDevice: dt_s <= 0");
  if (limits_.end_effectors < 1 || limits_.end_effectors > kMaxEndEffectors ||
      trajectory_.end_effectors != limits_.end_effectors)
    throw std::invalid_argument("ReplayDevice: the trajectory's end-effectors do not match the device's");
  for (const TrajectorySample& s : trajectory_.samples)
    if (s.end_effectors != trajectory_.end_effectors)
      throw std::invalid_argument("ReplayDevice: a sample's end-effector count differs from the trajectory's");
  times_.resize(command_capacity);
  wrenches_.resize(command_capacity * static_cast<std::size_t>(limits_.end_effectors));
}

CommandRecord ReplayDevice::command(std::size_t i) const {
  CommandRecord r;
  r.t_s = times_[i];
  const auto n = static_cast<std::size_t>(limits_.end_effectors);
  for (std::size_t k = 0; k < n; ++k) r.command.ee[k] = wrenches_[i * n + k];
  return r;
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
  const bool last = cursor_ + 1 >= s.size();
  const TrajectorySample& b = last ? a : s[cursor_ + 1];
  const double dt = b.t_s - a.t_s;
  const double u = last ? 0.0 : (t - a.t_s) / dt;
  out.end_effectors = trajectory_.end_effectors;
  for (int k = 0; k < trajectory_.end_effectors; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const EndEffectorSample& ea = a.ee[i];
    const EndEffectorSample& eb = b.ee[i];
    EndEffectorSample& e = out.ee[i];
    e.handle = ea.handle;
    e.enabled = ea.enabled;
    if (last) {
      e.position_H = ea.position_H;
      e.orientation_H = ea.orientation_H;
      e.velocity_H.setZero();
      e.angular_velocity_H.setZero();
      continue;
    }
    e.position_H = ea.position_H + u * (eb.position_H - ea.position_H);
    e.orientation_H = ea.orientation_H.slerp(u, eb.orientation_H);
    if (trajectory_.has_twist) {
      e.velocity_H = ea.velocity_H + u * (eb.velocity_H - ea.velocity_H);
      e.angular_velocity_H = ea.angular_velocity_H + u * (eb.angular_velocity_H - ea.angular_velocity_H);
    } else {
      e.velocity_H = (eb.position_H - ea.position_H) / dt;
      e.angular_velocity_H.setZero();
    }
  }
}

void ReplayDevice::write(const DeviceCommand& cmd) noexcept {
  const std::size_t n = command_count_.load(std::memory_order_relaxed);
  if (n < times_.size()) {
    times_[n] = time_s();
    const auto m = static_cast<std::size_t>(limits_.end_effectors);
    for (std::size_t k = 0; k < m; ++k) wrenches_[n * m + k] = cmd.ee[k];
    command_count_.store(n + 1, std::memory_order_release);
  } else {
    commands_dropped_.fetch_add(1, std::memory_order_relaxed);
  }
  ++ticks_;
}

}  // namespace hemm::device
