// The time-critical mode's budget in time (docs/realtime.md, "Work budgets").
// VPS work is counted in units (a sphere node visited or a point tested,
// contact.h); what a unit costs in nanoseconds depends on the machine, its
// caches and its load, so it is measured, never assumed:
//
//  * at start, off the servo thread: calibrate_work_rate times the pairs the
//    task will run on poses through the loaded voxmaps' surfaces (the object
//    half sunk into the surface: the dearest units, points tested inside the
//    distance layers), and starts the estimate from the median cost and its
//    mean deviation;
//  * every tick the budget bound (it stopped early), on the servo thread (a
//    few multiplications, nothing allocated): the tick's VPS time over its
//    work updates the estimate the way TCP's retransmission timer tracks a
//    round trip (Jacobson/Karels): an exponential mean and an exponential
//    mean deviation, and a unit is budgeted at mean + 4 deviations, so a
//    spread of costs shrinks the budget at once while a steady machine earns
//    the measured mean. Ticks that completed every level do not update it:
//    their cost did not limit them, and a run of them (free space: culled
//    nodes, cheap units) would talk the estimate down before the next
//    contact, whose units cost more.
//
// A tick's budget is then the time it may spend (at most tick_ns, and never
// past the tick's deadline less margin_ns) over the budgeted cost per unit,
// capped by the old work-unit budget. Pure: the caller passes the times (the
// library has no clock).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "common/haptics/vps/contact.h"

namespace hemm::vps {

struct WorkRateParams {
  double mean_gain = 1.0 / 64;       // the mean follows over ~64 samples
  double deviation_gain = 1.0 / 16;  // the deviation over ~16 (a new spread counts fast)
  double deviations = 4.0;           // budgeted cost = mean + deviations * deviation
  // Evaluations with less work do not count when nothing bound them (the
  // calibration; ticks without a time budget): their fixed cost (the pairs
  // set up, the result summed) would read as a cost per unit. A tick the
  // budget bound always counts, however small its budget: otherwise an
  // estimate high enough to buy fewer units would never come down.
  std::int64_t min_work = 256;
  // A sample above this many times the mean is taken at that: a tick that
  // took more than twice what its units cost on average was disturbed (a
  // preemption, the hypervisor, another core's cache traffic), which no
  // estimate predicts; counting it whole would shrink every later budget
  // for a spike that does not come back on schedule. A real rise still
  // doubles the mean within ~45 ticks.
  double outlier = 2.0;
};

// Cost of a work unit (ns). samples == 0: not measured (no time budget).
struct WorkRate {
  double mean_ns = 0.0;
  double deviation_ns = 0.0;
  std::uint64_t samples = 0;
};

// What a unit is budgeted at.
inline double budgeted_ns_per_unit(const WorkRateParams& p, const WorkRate& r) {
  return r.mean_ns + p.deviations * r.deviation_ns;
}

// One tick's measurement: `elapsed_ns` for `work` units.
void update_work_rate(const WorkRateParams& p, std::int64_t elapsed_ns, std::int64_t work, WorkRate* r) noexcept;

// Poses (P in V's frame) that put the pointshell's reference point on
// `count` surface voxels of `vm` spread over the whole map, each turned at
// random (fixed seed: the same poses on every run). Empty when vm has no
// surface voxel. Allocates.
std::vector<Eigen::Isometry3d> surface_poses(const Voxmap& vm, const PointShell& ps, int count, std::uint32_t seed = 1);

// One pair the task evaluates: a pointshell against a voxmap.
struct CalibrationPair {
  const Voxmap* voxmap = nullptr;
  const PointShell* shell = nullptr;
};

struct WorkRateCalibration {
  WorkRate rate;                      // the estimate to start from
  int samples = 0;                    // timed evaluations with at least min_work units
  double median_ns_per_unit = 0.0, p90_ns_per_unit = 0.0;
  std::int64_t median_work = 0;       // units per timed evaluation
};

// Times evaluate_pair_budgeted (every level, as the time-critical mode runs
// them) of each pair on surface_poses(poses_per_pair), after one untimed
// pass, with the caller's clock `now_ns` (steady nanoseconds). Off the servo
// thread: allocates. rate.samples == 0 when no evaluation did min_work units
// (nothing to measure on: no time budget then).
WorkRateCalibration calibrate_work_rate(const std::vector<CalibrationPair>& pairs, const ContactParams& params,
                                        const WorkRateParams& rp, int poses_per_pair, std::int64_t (*now_ns)());

// The same before a live voxmap exists: `shell` against a box of half
// extents `half` at the live voxmap's voxel size and layers, which stands in
// for the scene until the ticks measure their own. Throws
// std::invalid_argument ("calibration voxmap: ...") for bad voxmap params.
WorkRateCalibration calibrate_work_rate_on_box(const Eigen::Vector3d& half, double voxel_size, int layers,
                                               const PointShell& shell, const ContactParams& params,
                                               const WorkRateParams& rp, int poses, std::int64_t (*now_ns)());

struct TimeBudgetParams {
  std::int64_t tick_ns = 200'000;    // VPS time per tick at most; 0: no time budget
  std::int64_t margin_ns = 100'000;  // ... and the work ends this long before the tick's deadline
  std::int64_t max_work = kUnlimitedWork;  // the work-unit budget (a cap on top)
  WorkRateParams rate;
};

// Empty when usable.
std::string validate(const TimeBudgetParams& p);

// What a task's budget did over a run.
struct WorkBudgetStats {
  std::uint64_t ticks = 0;          // evaluations
  std::uint64_t stopped_early = 0;  // the budget ran out before some pair's finest level
  std::uint64_t over_time = 0;      // took longer than the time they were given
  std::array<std::uint64_t, kMaxShellLevels + 1> levels{};  // evaluations by levels completed (all pairs)
  double calibrated_ns_per_unit = 0.0;  // budgeted cost per unit at start
  double ns_per_unit = 0.0;             // ... at the end
  double min_ns_per_unit = 0.0, max_ns_per_unit = 0.0;  // ... over the run
  double mean_ns_per_unit = 0.0;        // the estimate's mean at the end (what a unit took)
  std::int64_t min_work_budget = 0;     // the smallest budget a tick had (units)
};

// A task's budget, tick by tick. Servo thread: begin() and end() allocate
// nothing.
class TickWorkBudget {
 public:
  TickWorkBudget() = default;
  TickWorkBudget(const TimeBudgetParams& p, const WorkRate& calibrated);

  // The work units this tick may spend, at `now_ns`, with its deadline
  // (steady ns; 0: unknown, the tick budget alone). Without a time budget
  // (tick_ns 0, or nothing measured) the work-unit budget. With one: the
  // time left, and at least tick_ns / 8, over the budgeted cost per unit.
  // However few units that is, the evaluation completes the coarsest level
  // (contact.h): a tick already late renders a coarse but complete force.
  std::int64_t begin(std::int64_t now_ns, std::int64_t deadline_ns) noexcept;
  // After the evaluation (`now_ns` its end): its work, the levels all its
  // pairs completed, whether every pair reached its finest level.
  void end(std::int64_t now_ns, std::int64_t work, int levels_completed, bool complete) noexcept;

  bool timed() const noexcept { return p_.tick_ns > 0 && rate_.samples > 0; }
  const WorkBudgetStats& stats() const noexcept { return stats_; }
  const WorkRate& rate() const noexcept { return rate_; }
  const TimeBudgetParams& params() const noexcept { return p_; }

 private:
  TimeBudgetParams p_;
  WorkRate rate_;
  WorkBudgetStats stats_;
  std::int64_t begin_ns_ = 0;
  std::int64_t given_ns_ = 0;  // time this tick was given (0: none)
};

}  // namespace hemm::vps
