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

// The hole off where the operator believes it (its task: line wrong): the
// peg lands on the rim, the wrist force tells it, the search circle finds
// the hole and the descent goes on where it dropped in: 1 mm (twice the
// clearance a side: it used to enter 6 mm and jam, the target off the axis
// pressing it on a wall) and 4 mm the other way. NOT YET: 8 mm (diagonal)
// at 3 s round trip searched 240 s without getting in - the circle passes
// the hole's +-0.5 mm window in ~15 ms at that radius, too short for the
// peg to drop (docs/telemanipulation_tasks.md).
TEST(TaskFeasibility, PegFindsAHoleItBelievesOffByMillimetres) {
  if (hemm::test::kSanitizerBuild) GTEST_SKIP() << "release pass only (two searching runs; PegAt3sRoundTripLossy runs there)";
  for (const Eigen::Vector3d& off : {Eigen::Vector3d(0.001, 0.0, 0.0), Eigen::Vector3d(0.0, -0.004, 0.0)}) {
    const tf::FeasibilityRun r = tf::feasibility_run(ht::Task::kPeg, 0.0, 0.0, 1, 150.0, off);
    tf::feasibility_print(ht::Task::kPeg, 0.0, 1, r);
    EXPECT_TRUE(r.script_done) << off.transpose() << ": " << r.last_step << " " << r.detail;
    EXPECT_TRUE(r.verdict.success) << off.transpose() << ": " << r.verdict.why;
    EXPECT_GE(r.searches, 1) << off.transpose();  // it did land on the rim
  }
}
