// The time-critical budget in time (work_budget.h): the cost-per-unit
// estimate against known costs, the budget a tick gets from its time and
// deadline, the calibration's poses on the surface, and a budget that holds
// a real evaluation to its time.
#include "common/haptics/vps/work_budget.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/sanitizer_build.h"

namespace hemm::vps {
namespace {

TEST(WorkRate, FollowsAConstantCostAndClampsDisturbedTicks) {
  WorkRateParams p;
  WorkRate r;
  update_work_rate(p, 1000, 0, &r);  // no work: nothing to learn
  update_work_rate(p, -5, 100, &r);  // a clock that went back
  EXPECT_EQ(r.samples, 0u);
  update_work_rate(p, 30'000, 1000, &r);  // the first sample: mean 30, spread 15
  EXPECT_DOUBLE_EQ(r.mean_ns, 30.0);
  EXPECT_DOUBLE_EQ(r.deviation_ns, 15.0);
  EXPECT_DOUBLE_EQ(budgeted_ns_per_unit(p, r), 90.0);
  // 20 ns a unit from now on: the mean converges to it, the spread to zero
  // (the gains' geometric series: after 1000 samples both are within 1e-6).
  for (int i = 0; i < 1000; ++i) update_work_rate(p, 20'000, 1000, &r);
  EXPECT_NEAR(r.mean_ns, 20.0, 1e-5);
  EXPECT_NEAR(r.deviation_ns, 0.0, 1e-5);
  // A preempted tick (1 ms for 1000 units) counts as twice the mean.
  const double before = r.mean_ns;
  update_work_rate(p, 1'000'000, 1000, &r);
  EXPECT_NEAR(r.mean_ns, before + p.mean_gain * before, 1e-9);
  EXPECT_NEAR(r.deviation_ns, p.deviation_gain * before, 1e-4);
  // A real rise (every unit now 3 x dearer) is followed all the same: the
  // clamp lets the mean double in ~45 ticks, the gain closes the rest.
  for (int i = 0; i < 45; ++i) update_work_rate(p, 60'000, 1000, &r);
  EXPECT_GT(r.mean_ns, 2 * before * 0.95);
  for (int i = 0; i < 400; ++i) update_work_rate(p, 60'000, 1000, &r);
  EXPECT_NEAR(r.mean_ns, 60.0, 1.0);
}

TEST(WorkRate, SpreadWidensTheBudgetedCostAtOnce) {
  // Costs alternating 10 and 30 ns: mean 20, mean deviation 10, so a unit
  // is budgeted near 20 + 4 x 10 = 60 ns, above every sample.
  WorkRateParams p;
  WorkRate r;
  for (int i = 0; i < 2000; ++i) update_work_rate(p, (i % 2 ? 30 : 10) * 1000, 1000, &r);
  EXPECT_NEAR(r.mean_ns, 20.0, 0.5);
  EXPECT_NEAR(r.deviation_ns, 10.0, 0.5);
  EXPECT_GT(budgeted_ns_per_unit(p, r), 30.0);
}

TEST(TickWorkBudget, BuysTheTimeLeftAtTheBudgetedCost) {
  TimeBudgetParams p;
  p.tick_ns = 200'000;
  p.margin_ns = 100'000;
  p.max_work = 50'000;
  WorkRate r;
  r.mean_ns = 20.0;
  r.deviation_ns = 5.0;  // budgeted at 40 ns a unit
  r.samples = 1;
  TickWorkBudget b(p, r);
  ASSERT_TRUE(b.timed());
  // No deadline known: the tick budget alone, 200 us / 40 ns.
  EXPECT_EQ(b.begin(1'000'000, 0), 5000);
  // A deadline 250 us away: 150 us left before the margin.
  EXPECT_EQ(b.begin(1'000'000, 1'250'000), 3750);
  // Past the deadline already: an eighth of the tick budget (a coarse force).
  EXPECT_EQ(b.begin(1'000'000, 900'000), 625);
  // The work-unit budget caps it.
  p.max_work = 1000;
  EXPECT_EQ(TickWorkBudget(p, r).begin(1'000'000, 0), 1000);
  // An estimate so high that the budget buys a handful of units still comes
  // down: the ticks it binds count, however little work they did.
  WorkRate high;
  high.mean_ns = 5000.0;
  high.samples = 1;
  TimeBudgetParams q;
  q.tick_ns = 200'000;
  TickWorkBudget h(q, high);
  std::int64_t now = 0;
  for (int i = 0; i < 2000; ++i) {
    const std::int64_t u = h.begin(now, 0);
    h.end(now + 1000 + 20 * u, u, 0, false);  // 1 us fixed + 20 ns a unit
    now += 1'000'000;
  }
  EXPECT_LT(h.rate().mean_ns, 25.0);
  EXPECT_GT(h.begin(now, 0), 2000);
  // No time budget, or nothing measured: the work-unit budget.
  p.tick_ns = 0;
  EXPECT_FALSE(TickWorkBudget(p, r).timed());
  EXPECT_EQ(TickWorkBudget(p, r).begin(1'000'000, 0), 1000);
  p.tick_ns = 200'000;
  EXPECT_EQ(TickWorkBudget(p, WorkRate{}).begin(1'000'000, 0), 1000);
  // Bad parameters are refused.
  p.max_work = 0;
  EXPECT_FALSE(validate(p).empty());
  p.max_work = 1;
  p.tick_ns = -1;
  EXPECT_FALSE(validate(p).empty());
}

TEST(TickWorkBudget, CountsEarlyStopsLevelsAndOverTime) {
  TimeBudgetParams p;
  p.tick_ns = 100'000;
  WorkRate r;
  r.mean_ns = 10.0;
  r.samples = 1;
  TickWorkBudget b(p, r);
  EXPECT_EQ(b.begin(0, 0), 10'000);
  b.end(50'000, 5000, 4, true);  // every level done within its time: the estimate is not touched
  EXPECT_EQ(b.rate().samples, 1u);
  EXPECT_DOUBLE_EQ(b.rate().mean_ns, 10.0);
  EXPECT_EQ(b.begin(1'000'000, 0), 10'000);
  b.end(1'150'000, 10'000, 2, false);  // stopped early, and 150 us for 100 us given: learnt from
  const WorkBudgetStats& s = b.stats();
  EXPECT_EQ(s.ticks, 2u);
  EXPECT_EQ(s.stopped_early, 1u);
  EXPECT_EQ(s.over_time, 1u);
  EXPECT_EQ(s.levels[4], 1u);
  EXPECT_EQ(s.levels[2], 1u);
  EXPECT_DOUBLE_EQ(s.calibrated_ns_per_unit, 10.0);
  EXPECT_EQ(b.rate().samples, 2u);
  EXPECT_GT(s.ns_per_unit, 10.0);  // 15 ns a unit measured: the estimate rose
  EXPECT_EQ(s.max_ns_per_unit, s.ns_per_unit);
}

TEST(TickWorkBudget, HoldsASimulatedMachineToItsTime) {
  // A machine whose unit costs 25 ns +- 40 % (uniform) and whose ticks have
  // more work than any budget: with the estimate started from a calibration
  // 3 x too optimistic, the budgeted time overruns only until the estimate
  // has caught up, then (mean + 4 deviations) almost never.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> cost(15.0, 35.0);
  TimeBudgetParams p;
  p.tick_ns = 200'000;
  WorkRate start;
  start.mean_ns = 25.0 / 3;
  start.samples = 1;
  TickWorkBudget b(p, start);
  std::int64_t now = 0;
  std::uint64_t over_after_warmup = 0;
  double elapsed_sum = 0;
  const int ticks = 20000;
  for (int i = 0; i < ticks; ++i) {
    const std::int64_t units = b.begin(now, 0);
    const auto elapsed = static_cast<std::int64_t>(static_cast<double>(units) * cost(rng));
    const std::uint64_t over = b.stats().over_time;
    b.end(now + elapsed, units, 1, false);
    if (i >= 200 && b.stats().over_time > over) ++over_after_warmup;
    if (i >= 200) elapsed_sum += static_cast<double>(elapsed);
    now += 1'000'000;
  }
  EXPECT_LT(over_after_warmup, static_cast<std::uint64_t>(ticks / 1000));  // < 0.1 %
  // It does not give the time away: on average more than half of it is used.
  EXPECT_GT(elapsed_sum / (ticks - 200), 0.5 * static_cast<double>(p.tick_ns));
  EXPECT_NEAR(b.rate().mean_ns, 25.0, 1.5);
}

class WorkBudgetOnAScene : public ::testing::Test {
 protected:
  void SetUp() override {
    VoxmapParams vp;
    vp.voxel_size = 0.004;
    vp.layers_in = vp.layers_out = 4;
    ASSERT_FALSE(build_voxmap(mesh::make_box({0.15, 0.15, 0.05}, 4), vp, &vm_, nullptr));
    PointShellParams pp;
    pp.voxel_size = 0.003;
    ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.04, 4), pp, Eigen::Vector3d(0.001, 0, 0), &ps_));
  }
  Voxmap vm_;
  PointShell ps_;
};

TEST_F(WorkBudgetOnAScene, SurfacePosesPutTheReferencePointOnTheSurface) {
  const std::vector<Eigen::Isometry3d> a = surface_poses(vm_, ps_, 40);
  ASSERT_EQ(a.size(), 40u);
  for (const Eigen::Isometry3d& T : a) {
    EXPECT_TRUE(T.linear().isUnitary(1e-9));
    EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-9);
    // The box's exact distance at the reference point: within a voxel's
    // half diagonal of its surface (a surface voxel's centre).
    const Eigen::Vector3d x = T * ps_.reference_point;
    const Eigen::Vector3d q = x.cwiseAbs() - Eigen::Vector3d(0.15, 0.15, 0.05);
    const double d = q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    EXPECT_LE(std::abs(d), 0.5 * std::sqrt(3.0) * vm_.voxel_size + 1e-9);
  }
  // Spread over the map (top and sides), and the same on every call.
  double zmin = 1, zmax = -1;
  for (const auto& T : a) {
    zmin = std::min(zmin, (T * ps_.reference_point).z());
    zmax = std::max(zmax, (T * ps_.reference_point).z());
  }
  EXPECT_GT(zmax - zmin, 0.08);
  const std::vector<Eigen::Isometry3d> b = surface_poses(vm_, ps_, 40);
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_TRUE(a[i].isApprox(b[i], 0.0));
  Voxmap empty;
  EXPECT_TRUE(surface_poses(empty, ps_, 10).empty());
}

TEST_F(WorkBudgetOnAScene, CalibrationMeasuresTheCostAndTheBudgetHoldsTheTime) {
  ContactParams cp;
  WorkRateParams rp;
  const WorkRateCalibration c = calibrate_work_rate({{&vm_, &ps_}}, cp, rp, 24, &steady_now_ns);
  ASSERT_GT(c.samples, 12);
  EXPECT_GE(c.median_work, rp.min_work);
  // A unit is a node visit or a point test: between a nanosecond and a few
  // microseconds on any machine this runs on, loaded or not; about ten
  // times dearer under the sanitizers (7.0 us seen beside other tests).
  EXPECT_GT(c.median_ns_per_unit, 1.0);
  EXPECT_LT(c.median_ns_per_unit, hemm::test::kSanitizerBuild ? 50000.0 : 5000.0);
  EXPECT_GE(c.p90_ns_per_unit, c.median_ns_per_unit);
  EXPECT_EQ(c.rate.mean_ns, c.median_ns_per_unit);
  // Ticks on poses through the surface, with a budget of a fifth of the
  // median full evaluation's time: the budget stops them early and holds
  // the median tick to its time (wide margin: the machine is shared), and
  // the ticks allocate nothing.
  const double full_ns = c.median_ns_per_unit * static_cast<double>(c.median_work);
  TimeBudgetParams tb;
  tb.tick_ns = std::max<std::int64_t>(static_cast<std::int64_t>(0.2 * full_ns), 2000);
  TickWorkBudget b(tb, c.rate);
  PairState state;
  init_pair_state(ps_, &state);
  const std::vector<Eigen::Isometry3d> poses = surface_poses(vm_, ps_, 50, 3);
  std::vector<double> spent;
  spent.reserve(4 * poses.size());
  int over_budget = 0;
  PairResult r;
  const std::uint64_t allocs = test::counted_allocations();
  test::count_allocations_on_this_thread(true);
  for (int rep = 0; rep < 4; ++rep)
    for (const Eigen::Isometry3d& T : poses) {
      const std::int64_t t0 = steady_now_ns();
      const std::int64_t units = b.begin(t0, 0);
      evaluate_pair_budgeted(vm_, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps_, T, cp, units, &state, &r);
      const std::int64_t t1 = steady_now_ns();
      b.end(t1, r.nodes_visited + r.points_tested, r.levels_completed, r.levels_completed >= ps_.levels);
      // Past the coarsest level (which always completes) the units bound the work.
      if (r.levels_completed > 1 && r.nodes_visited + r.points_tested > units) ++over_budget;
      spent.push_back(static_cast<double>(t1 - t0));
    }
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(test::counted_allocations() - allocs, 0u);
  EXPECT_EQ(over_budget, 0);  // the work never exceeds the units given
  std::sort(spent.begin(), spent.end());
  const double median = spent[spent.size() / 2];
  std::printf("calibration: %d evaluations, median %.1f ns/unit (p90 %.1f), %lld units each; budget %lld ns: median "
              "tick %.0f ns, %llu of %llu stopped early, %llu over time, budgeted %.1f ns/unit at the end\n",
              c.samples, c.median_ns_per_unit, c.p90_ns_per_unit, static_cast<long long>(c.median_work),
              static_cast<long long>(tb.tick_ns), median, static_cast<unsigned long long>(b.stats().stopped_early),
              static_cast<unsigned long long>(b.stats().ticks), static_cast<unsigned long long>(b.stats().over_time),
              b.stats().ns_per_unit);
  EXPECT_GT(b.stats().stopped_early, b.stats().ticks / 2);
  EXPECT_LT(median, 2.0 * static_cast<double>(tb.tick_ns));
}

}  // namespace
}  // namespace hemm::vps
