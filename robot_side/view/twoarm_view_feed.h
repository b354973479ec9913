// SIMULATION ONLY. What the two-arm station's live view (twoarm_view.h)
// reads from the control thread: at a state publication, once the view's
// interval of robot time has passed, the control thread copies the MuJoCo
// state (qpos), the newest snapshot (targets, wrist wrenches, grippers,
// safety), the true contacts on the grippers and objects, and the task
// judge's last look into a fixed-size frame and publishes it through a
// newest-wins mailbox. Everything is fixed-size, so the control thread
// neither allocates nor locks for it (unlike the mobile robot's feed,
// sim_view_feed.h, which try-locks).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "common/concurrency/newest_mailbox.h"
#include "robot_side/sim/sim_types.h"
#include "robot_side/twoarm/task_truth.h"
#include "robot_side/twoarm/twoarm_robot.h"

namespace hemm::robot {

struct TwoArmViewFrame {
  static constexpr int kMaxQpos = 256;
  static constexpr int kMaxContacts = 48;
  std::int64_t t_ns = 0;  // robot time
  int nq = 0;
  std::array<double, kMaxQpos> qpos{};
  int ncontacts = 0;      // drawn (at most kMaxContacts)
  int contacts_seen = 0;  // in the simulation this tick
  std::array<SimContact, kMaxContacts> contacts{};
  twoarm::TwoArmSnapshot snapshot;
  bool link_up = false, in_control = false;
  bool has_task = false;
  twoarm::TaskTruthSample task;
  bool lifted = false, dropped = false;
};

class TwoArmViewFeed {
 public:
  explicit TwoArmViewFeed(std::int64_t interval_ns = 33'000'000) : interval_ns_(interval_ns) {}
  TwoArmViewFeed(const TwoArmViewFeed&) = delete;
  TwoArmViewFeed& operator=(const TwoArmViewFeed&) = delete;

  // ---- control thread ----
  bool due(std::int64_t now_ns) const noexcept { return now_ns >= next_ns_; }
  TwoArmViewFrame& back() noexcept { return frames_.back(); }
  void publish() noexcept {
    next_ns_ = frames_.back().t_ns + interval_ns_;
    frames_.publish();
    published_.fetch_add(1, std::memory_order_relaxed);
  }

  // ---- view thread ----
  const TwoArmViewFrame* take() noexcept { return frames_.take(); }  // newest since the last take, or null
  std::uint64_t published() const noexcept { return published_.load(std::memory_order_relaxed); }

 private:
  const std::int64_t interval_ns_;
  std::int64_t next_ns_ = 0;  // control thread only
  NewestMailbox<TwoArmViewFrame> frames_;
  std::atomic<std::uint64_t> published_{0};
};

}  // namespace hemm::robot
