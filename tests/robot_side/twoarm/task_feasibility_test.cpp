// Are the three tasks feasible for the SIMULATED robot under the SIMULATED
// human's scripts (task_feasibility_run.h: no network, the truth judges)?
// One run per task at 0 delay and one at 3000 ms round trip with 5 % loss
// each way; the sweep over delays and seeds is the benchmark
// twoarm_task_table (tests/bench/twoarm_task_table.cpp), which prints the
// table of docs/telemanipulation_tasks.md.
#include "tests/robot_side/twoarm/task_feasibility_run.h"

#include <gtest/gtest.h>

#include "tests/sanitizer_build.h"

namespace tf = hemm::test::twoarm_feasibility;
namespace ht = hemm::twoarm;

namespace {

void feasibility_expect(ht::Task task, double rtt_s, double loss, uint64_t seed) {
  const tf::FeasibilityRun r = tf::feasibility_run(task, rtt_s, loss, seed, std::getenv("HEMM_TASK_MAX_S") ? std::atof(std::getenv("HEMM_TASK_MAX_S")) : 150.0);
  tf::feasibility_print(task, rtt_s, seed, r);
  EXPECT_TRUE(r.script_done) << ht::to_string(task) << " at " << rtt_s << " s: stopped at step " << r.steps_done << " ("
                             << r.last_step << ") " << r.detail << " refusals " << r.refusals;
  EXPECT_TRUE(r.verdict.success) << ht::to_string(task) << " at " << rtt_s << " s: " << r.verdict.why;
  EXPECT_EQ(r.refusals, 0u);
}

constexpr double kFeasibilityLoss = 0.05;

}  // namespace

// 0 delay, then 3000 ms round trip with 5 % loss each way (one seed: the
// seeds barely differ, see the benchmark's table).
TEST(TaskFeasibility, BoxWithBothHandsAtZeroDelay) { feasibility_expect(ht::Task::kBox, 0.0, 0.0, 1); }
TEST(TaskFeasibility, PegAtZeroDelay) { feasibility_expect(ht::Task::kPeg, 0.0, 0.0, 1); }
TEST(TaskFeasibility, BarAtZeroDelay) { feasibility_expect(ht::Task::kBar, 0.0, 0.0, 1); }
// Under the sanitizers the peg's run alone takes the delayed, lossy link (the
// same harness code as the other two; tests/sanitizer_build.h).
TEST(TaskFeasibility, BoxWithBothHandsAt3sRoundTripLossy) {
  if (hemm::test::kSanitizerBuild) GTEST_SKIP() << "release pass only (the peg's run covers the delayed link here)";
  feasibility_expect(ht::Task::kBox, 3.0, kFeasibilityLoss, 1);
}
TEST(TaskFeasibility, PegAt3sRoundTripLossy) { feasibility_expect(ht::Task::kPeg, 3.0, kFeasibilityLoss, 1); }
TEST(TaskFeasibility, BarAt3sRoundTripLossy) {
  if (hemm::test::kSanitizerBuild) GTEST_SKIP() << "release pass only (the peg's run covers the delayed link here)";
  feasibility_expect(ht::Task::kBar, 3.0, kFeasibilityLoss, 1);
}

// The hole 1 mm (x) from where the operator believes it (twice the
// clearance a side): the peg should land on the rim, the wrist force tell it,
// and the search circle find the hole. NOT YET: it enters 6 mm and jams (the
// target 1 mm off the axis presses it on a wall); at 2.5 mm it does not get in either
// (docs/telemanipulation_tasks.md).
TEST(TaskFeasibility, DISABLED_PegFindsAHoleItBelievesOffByOneMillimetre) {
  const tf::FeasibilityRun r = tf::feasibility_run(ht::Task::kPeg, 0.0, 0.0, 1, 150.0, Eigen::Vector3d(0.001, 0.0, 0.0));
  tf::feasibility_print(ht::Task::kPeg, 0.0, 1, r);
  EXPECT_TRUE(r.script_done) << r.last_step << " " << r.detail;
  EXPECT_TRUE(r.verdict.success) << r.verdict.why;
}
