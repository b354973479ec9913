#include "operator/device/hand_script.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace hemm::device {
namespace {

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

}  // namespace

HoldScript::HoldScript(const Eigen::Vector3d& position_H, std::uint32_t buttons, bool deadman) {
  if (!finite(position_H)) throw std::invalid_argument("HoldScript: non-finite position");
  target_.position_H = position_H;
  target_.buttons = buttons;
  target_.deadman = deadman;
}

HandTarget HoldScript::at(double) const noexcept { return target_; }

LineScript::LineScript(const Eigen::Vector3d& from_H, const Eigen::Vector3d& to_H, double speed,
                       double t_start_s)
    : from_H_(from_H), to_H_(to_H), t_start_s_(t_start_s) {
  if (!finite(from_H) || !finite(to_H) || !std::isfinite(t_start_s))
    throw std::invalid_argument("LineScript: non-finite argument");
  if (!(speed > 0.0) || !std::isfinite(speed))
    throw std::invalid_argument("LineScript: speed must be finite and > 0");
  duration_s_ = (to_H - from_H).norm() / speed;
}

HandTarget LineScript::at(double t_s) const noexcept {
  HandTarget out;
  if (!(t_s > t_start_s_) || duration_s_ <= 0.0) {
    out.position_H = (t_s > t_start_s_) ? to_H_ : from_H_;
    return out;
  }
  const double s = std::min(1.0, (t_s - t_start_s_) / duration_s_);
  out.position_H = from_H_ + s * (to_H_ - from_H_);
  return out;
}

WaypointScript::WaypointScript(std::vector<Waypoint> waypoints) : waypoints_(std::move(waypoints)) {
  if (waypoints_.empty()) throw std::invalid_argument("WaypointScript: no waypoints");
  for (std::size_t i = 0; i < waypoints_.size(); ++i) {
    if (!std::isfinite(waypoints_[i].t_s) || !finite(waypoints_[i].position_H))
      throw std::invalid_argument("WaypointScript: non-finite waypoint " + std::to_string(i));
    if (i > 0 && !(waypoints_[i].t_s > waypoints_[i - 1].t_s))
      throw std::invalid_argument("WaypointScript: times not strictly increasing at waypoint " +
                                  std::to_string(i));
  }
}

HandTarget WaypointScript::at(double t_s) const noexcept {
  HandTarget out;
  const auto& w = waypoints_;
  if (!(t_s > w.front().t_s)) {  // also catches NaN
    out.position_H = w.front().position_H;
    out.buttons = w.front().buttons;
    out.deadman = w.front().deadman;
    return out;
  }
  if (t_s >= w.back().t_s) {
    out.position_H = w.back().position_H;
    out.buttons = w.back().buttons;
    out.deadman = w.back().deadman;
    return out;
  }
  // First waypoint strictly after t: the segment is [it-1, it].
  const auto it = std::upper_bound(w.begin(), w.end(), t_s,
                                   [](double t, const Waypoint& p) { return t < p.t_s; });
  const Waypoint& b = *it;
  const Waypoint& a = *(it - 1);
  const double s = (t_s - a.t_s) / (b.t_s - a.t_s);
  out.position_H = a.position_H + s * (b.position_H - a.position_H);
  out.buttons = a.buttons;
  out.deadman = a.deadman;
  return out;
}

ButtonEventsScript::ButtonEventsScript(std::shared_ptr<const HandScript> motion,
                                       std::vector<ButtonEvent> events)
    : motion_(std::move(motion)), events_(std::move(events)) {
  if (!motion_) throw std::invalid_argument("ButtonEventsScript: no motion script");
  for (std::size_t i = 0; i < events_.size(); ++i) {
    if (!std::isfinite(events_[i].t_s))
      throw std::invalid_argument("ButtonEventsScript: non-finite time at event " +
                                  std::to_string(i));
    if (i > 0 && !(events_[i].t_s > events_[i - 1].t_s))
      throw std::invalid_argument("ButtonEventsScript: times not strictly increasing at event " +
                                  std::to_string(i));
  }
}

HandTarget ButtonEventsScript::at(double t_s) const noexcept {
  HandTarget out = motion_->at(t_s);
  const auto it = std::upper_bound(events_.begin(), events_.end(), t_s,
                                   [](double t, const ButtonEvent& e) { return t < e.t_s; });
  out.buttons = (it == events_.begin()) ? 0u : (it - 1)->buttons;
  return out;
}

DeadmanScript::DeadmanScript(std::shared_ptr<const HandScript> motion, std::vector<DeadmanPress> presses)
    : motion_(std::move(motion)), presses_(std::move(presses)) {
  if (!motion_) throw std::invalid_argument("DeadmanScript: no motion script");
  for (std::size_t i = 0; i < presses_.size(); ++i) {
    const DeadmanPress& p = presses_[i];
    if (!std::isfinite(p.from_s) || !(p.to_s > p.from_s))
      throw std::invalid_argument("DeadmanScript: press " + std::to_string(i) + " must start at a finite time and end after it");
    if (i > 0 && !(p.from_s >= presses_[i - 1].to_s))
      throw std::invalid_argument("DeadmanScript: press " + std::to_string(i) + " overlaps or precedes the one before");
  }
}

HandTarget DeadmanScript::at(double t_s) const noexcept {
  HandTarget out = motion_->at(t_s);
  // The last press starting at or before t: pressed if t is inside it.
  const auto it = std::upper_bound(presses_.begin(), presses_.end(), t_s,
                                   [](double t, const DeadmanPress& p) { return t < p.from_s; });
  out.deadman = it != presses_.begin() && t_s < (it - 1)->to_s;
  return out;
}

}  // namespace hemm::device
