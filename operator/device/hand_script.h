// Scripted targets for the simulated operator's hand: a function of time
// giving where the hand wants the stylus to be and which buttons it holds.
// at() is evaluated where the device's simulated hardware runs (the servo
// thread in lock-step, its own thread when threaded: simulated_hardware.h),
// so it is const, allocation-free and O(log n). Scripts are built by code (tests, demos); constructors check their
// arguments and throw std::invalid_argument on nonsense.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

namespace hemm::device {

struct HandTarget {
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation_H = Eigen::Quaterniond::Identity();
  std::uint32_t buttons = 0;
  bool deadman = false;  // the hand presses the dead-man (HandleInputs::deadman)
};

class HandScript {
 public:
  virtual ~HandScript() = default;
  virtual HandTarget at(double t_s) const noexcept = 0;
};

// Holds one position for ever.
class HoldScript final : public HandScript {
 public:
  explicit HoldScript(const Eigen::Vector3d& position_H, std::uint32_t buttons = 0, bool deadman = false);
  HandTarget at(double t_s) const noexcept override;

 private:
  HandTarget target_;
};

// Stays at `from` until t_start_s, then moves in a straight line to `to` at
// `speed` [m/s], then stays at `to`.
class LineScript final : public HandScript {
 public:
  LineScript(const Eigen::Vector3d& from_H, const Eigen::Vector3d& to_H, double speed,
             double t_start_s = 0.0);
  HandTarget at(double t_s) const noexcept override;
  double t_end_s() const { return t_start_s_ + duration_s_; }

 private:
  Eigen::Vector3d from_H_, to_H_;
  double t_start_s_, duration_s_;
};

// Piecewise-linear through waypoints at given times; holds the first before
// and the last after. Buttons and the dead-man switch at each waypoint (no
// interpolation).
struct Waypoint {
  double t_s = 0.0;
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;
  bool deadman = false;
};
class WaypointScript final : public HandScript {
 public:
  explicit WaypointScript(std::vector<Waypoint> waypoints);  // non-empty, strictly increasing t
  HandTarget at(double t_s) const noexcept override;

 private:
  std::vector<Waypoint> waypoints_;
};

// Another script with its buttons replaced by events: from each event's time
// on, the buttons are that event's state (0 before the first event).
struct ButtonEvent {
  double t_s = 0.0;
  std::uint32_t buttons = 0;
};
class ButtonEventsScript final : public HandScript {
 public:
  ButtonEventsScript(std::shared_ptr<const HandScript> motion, std::vector<ButtonEvent> events);
  HandTarget at(double t_s) const noexcept override;

 private:
  std::shared_ptr<const HandScript> motion_;
  std::vector<ButtonEvent> events_;
};

// Another script with its dead-man replaced: pressed during each span
// [from_s, to_s) (to_s may be +infinity), released outside them. Spans in
// time order, not overlapping.
struct DeadmanPress {
  double from_s = 0.0;
  double to_s = 0.0;
};
class DeadmanScript final : public HandScript {
 public:
  DeadmanScript(std::shared_ptr<const HandScript> motion, std::vector<DeadmanPress> presses);
  HandTarget at(double t_s) const noexcept override;

 private:
  std::shared_ptr<const HandScript> motion_;
  std::vector<DeadmanPress> presses_;
};

}  // namespace hemm::device
