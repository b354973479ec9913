// The SIMULATED human of telemanipulation (closed loop): per hand a script
// of grasp-frame targets given in A, relative to where the remote G was when
// the dead-man engaged, converted through the task's own mapping
// (arm_mapping.h hand_pose_D with the indexing anchor the servo task
// publishes) into where the hand should be in D. The human pulls its handle
// there with its arm's spring (device/bimanual/human.h), so what the remote
// arm does follows from the hand's real motion, the rendered wrench
// included: the route is what the human wants, not what happens.
//
// Before the mapping engages, and for a hand without a route, the human
// holds its hand where it rests.
//
// The dead-man, when the human watches the robot (robot_safety given: the
// newest ArmsState's flags, TelemanipLink::set_safety_out; kNoRobotState before any): released until the
// robot has been reporting for a reaction time, then pressed; and, as the
// robot asks after any stop (SAFETY_REARM: a neutral command, then a pressed
// one), released for a reaction time and pressed again when the robot has
// asked for it that long. A person at a station does the same from its
// status display. Without robot_safety the rest's dead-man holds throughout. at() is called on the device's hardware
// thread (threaded) or the servo thread (lock-step): allocation-free; it
// takes the newest anchor from a mailbox the servo task fills (the one
// consumer).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "common/concurrency/newest_mailbox.h"
#include "operator/device/bimanual/human.h"
#include "operator/telemanip/arm_mapping.h"

namespace hemm::op::telemanip {

// The robot's status before any ArmsState arrived (MappedHumanScript's robot_safety).
inline constexpr std::uint32_t kNoRobotState = 0xFFFFFFFFu;

// One key: at t_s after the engagement (plus the lead), G offset by dp_A
// from where it was at the engagement, the grip lever at grip_m.
struct GRouteKey {
  double t_s = 0.0;
  Eigen::Vector3d dp_A = Eigen::Vector3d::Zero();
  double grip_m = 0.0;
};

// The SIMULATED human's dead-man habit while watching the robot's status
// (above): released until the robot has been reporting for a reaction time,
// then pressed; released for a reaction time when the robot has asked to be
// re-armed (SAFETY_REARM) for that long, then pressed again. One thread
// (the one that calls at()) owns it; allocation-free.
struct DeadmanHabit {
  static constexpr double kReaction_s = 0.3;  // from seeing the robot's status to acting on it
  bool pressed = false;
  double t_seen = -1.0, t_released = -1e9, t_rearm = -1.0;
  // safety: the newest ArmsState's flags (kNoRobotState before any).
  bool step(std::uint32_t safety, double t_s) noexcept;
};

class MappedHumanScript final : public device::bimanual::HumanScript {
 public:
  // rest: what the human does at rest (its pose, the dead-man held, the
  // grasp). keys: strictly increasing finite times from 0 (may be empty).
  // Throws std::invalid_argument on bad keys or mapping parameters.
  MappedHumanScript(const device::bimanual::HumanTarget& rest, const ArmMappingParams& mapping,
                    std::vector<GRouteKey> keys, NewestMailbox<MappingAnchor>* anchors, double lead_s = 0.5,
                    const std::atomic<std::uint32_t>* robot_safety = nullptr);
  static constexpr double kReaction_s = DeadmanHabit::kReaction_s;
  device::bimanual::HumanTarget at(double t_s) const noexcept override;
  double end_s() const noexcept;  // the route's end after the engagement (0: none)

 private:
  device::bimanual::HumanTarget rest_;
  ArmMappingParams mapping_;
  std::vector<GRouteKey> keys_;
  NewestMailbox<MappingAnchor>* anchors_;
  double lead_s_;
  const std::atomic<std::uint32_t>* robot_safety_;
  // The consumer's side (the one thread that calls at()).
  mutable bool engaged_ = false;
  mutable double t_engaged_ = 0.0;
  mutable MappingAnchor anchor_;
  mutable DeadmanHabit deadman_;
};

// The demo route of the right hand: G 10 cm towards the bench (A +x) over
// 2 s, held 1 s, back over 2 s; then the grip lever closed over 1 s, held
// 1 s, opened over 1 s. Ends 8.5 s after the engagement.
std::vector<GRouteKey> demo_right_route(double grip_travel_m);

}  // namespace hemm::op::telemanip
