// What the operator's live view reads (DESIGN.md, "Threads of the operator
// station": the view thread reads the same snapshots and never delays the
// servo thread). Three lock-free or never-waiting paths:
//  - the model thread's snapshots: on_snapshot() (model thread, just before
//    each publish) copies the map's pieces and the poses into a slot under a
//    mutex it only try-locks (if the view holds it, that copy is skipped: the
//    next snapshot comes 20 ms later); the servo thread is not involved;
//  - the servo task's per-tick record (the W-frame StationLogRecord: predicted
//    pose, interaction point, proxy, force, mode, scale) through a newest-wins
//    mailbox: one copy and one atomic exchange per tick, no lock, allocation
//    or system call;
//  - the view's keys to the servo task: button bits in an atomic the task
//    exchanges with 0 each tick (a key press is a button press).
// The servo loop's timing is read from its TimingStats (atomics) and the
// link's statistics from the client (thread-safe), both by the view thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/mapping/local_map.h"
#include "common/view/primitives.h"
#include "operator/model/model_thread.h"
#include "common/concurrency/newest_mailbox.h"
#include "operator/servo/timing_stats.h"
#include "operator/station/operator_task.h"
#include "operator/view/voxmap_cubes.h"

namespace hemm::op {

// The view's copy of one model snapshot.
struct ViewModel {
  std::uint64_t version = 0;       // 0: nothing received yet
  std::int64_t stamp_ns = 0;       // local time T_W_R was predicted for
  bool have_state = false;
  math::Pose2 T_W_R;               // predicted robot pose at stamp_ns
  RobotStateSample state;          // the newest RobotState (T_W_R_odom: the last received pose)
  std::vector<mapping::Segment2> segments;  // the snapshot's map pieces (at most max_segments)
  std::size_t pieces_total = 0;    // pieces in the snapshot
  std::size_t map_segments = 0;    // map segments before splitting
  // The live voxmap from the robot's depth clouds (null: none built, or off).
  std::shared_ptr<const vps::Voxmap> voxmap;
  std::uint64_t voxmap_builds = 0;
  // Its surface as cubes (view thread: update_voxmap_cubes), and of which build.
  VoxmapCubes voxmap_cubes;
  std::uint64_t voxmap_cubes_of = 0;
};

// Recomputes model.voxmap_cubes when model.voxmap is a build they were not
// made from (view thread; a build comes at most a few times a second).
void update_voxmap_cubes(ViewModel& model, std::size_t budget);

class ViewFeed {
 public:
  explicit ViewFeed(std::size_t max_segments = 4000) : max_segments_(max_segments) {}
  ViewFeed(const ViewFeed&) = delete;
  ViewFeed& operator=(const ViewFeed&) = delete;

  // ---- model thread ----
  void on_snapshot(const OperatorModelSnapshot& s);
  // ---- servo thread (through OperatorServoTask::set_view_outputs) ----
  NewestMailbox<StationLogRecord>& ticks() noexcept { return ticks_; }
  std::atomic<std::uint32_t>& presses() noexcept { return presses_; }
  // ---- view thread ----
  void press(std::uint32_t buttons) noexcept { presses_.fetch_or(buttons, std::memory_order_relaxed); }
  // The newest copy since the last take (swapped into out), or false.
  bool take_model(ViewModel& out);
  bool take_tick(StationLogRecord& out) noexcept { return ticks_.take(out); }
  // ---- any thread ----
  std::uint64_t copies() const noexcept { return copies_.load(std::memory_order_relaxed); }
  std::uint64_t busy_skips() const noexcept { return busy_.load(std::memory_order_relaxed); }

 private:
  std::size_t max_segments_;
  std::mutex mu_;  // model thread (try_lock only) and view thread
  ViewModel slot_;
  bool fresh_ = false;
  NewestMailbox<StationLogRecord> ticks_;
  std::atomic<std::uint32_t> presses_{0};
  std::atomic<std::uint64_t> copies_{0}, busy_{0};
};

// The servo loop's health over the last window (between two update() calls)
// and since the start, from its histograms (readable while the loop runs).
struct ServoHealth {
  std::uint64_t ticks = 0, misses = 0;
  std::uint64_t window_ticks = 0, window_misses = 0;
  double window_s = 0.0;
  double period_median_ms = 0.0, period_p99_ms = 0.0;  // over the window
  // Since the start: the tick's compute and wake lateness, and the
  // log-spaced histograms of compute, wake lateness and period as a plot
  // (servo_histogram_plot).
  double compute_median_us = 0.0, compute_p99_us = 0.0, compute_max_us = 0.0;
  double wake_p99_us = 0.0, wake_max_us = 0.0;
  view::OverlayPlot histogram;
};

// The servo loop's histograms (compute, wake lateness, period) since the
// start as one plot: x = log10 of each bin's centre in us (0 to 4: 1 us to
// 10 ms), y = log10(1 + ticks in it), from the first to the last non-empty
// bin of each.
view::OverlayPlot servo_histogram_plot(const servo::TimingStats& t);

// The servo loop's figures as one overlay line: "compute median/p99/max ...
// wake p99/max ...".
std::string servo_figures_text(const ServoHealth& h);

class ServoHealthMeter {
 public:
  ServoHealth update(const servo::TimingStats& t, std::int64_t now_ns);

 private:
  std::vector<std::uint64_t> prev_bins_;
  std::uint64_t prev_ticks_ = 0, prev_misses_ = 0;
  std::int64_t prev_ns_ = 0;
};

}  // namespace hemm::op
