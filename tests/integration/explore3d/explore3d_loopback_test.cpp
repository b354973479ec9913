// The 6-DoF probe tool on the live voxmap end to end over real loopback
// sockets (issue 13): the SIMULATED robot station (MuJoCo home scene, real
// time) stands before the table with its SIMULATED mast depth camera; the
// operator station builds the live voxmap and renders the robot's probe tool
// (a pointshell, tool6_explorer.h) held by the SIMULATED rigid 6-DoF scripted
// hand "explore-block": it waits 5 s for the voxmap, presses the tool 5 mm
// past the block's top, slides, tilts it, lifts, and presses and slides on
// the block's front side.
//
// Asserted against simulation truth (SIMULATION ONLY: the scene's table,
// block, book and mug meshed from MuJoCo's model and voxelised exactly at
// 2.5 mm, the same hand path replayed with the same tool, contact and
// coupling, robot_side/truth/tool6_truth.h): the tool resting on the block's
// top sits at the true height, the force error RMS over contact ticks is
// within the bound below, the servo held its period, and no heap allocation
// happened on the servo thread.
#include <gtest/gtest.h>

#include "tests/integration/explore3d/explore3d_run.h"

TEST(Explore3dLoopback, ToolRestsOnTheTrueBlockTopAndFollowsTheTrueForce) {
  hemm::config::OperatorConfig ocfg;
  ocfg.mutable_probe_3d()->set_origin_x_m(0.85);
  ocfg.mutable_probe_3d()->set_origin_z_m(0.95);
  hemm::test::Explore3dRun r;
  hemm::test::run_explore("explore3d_loopback_test.csv", ocfg,
                                [](hemm::op::OperatorStationOptions& so) { so.device = "sim-hand6"; }, "explore-block",
                          22500, &r);
  if (HasFatalFailure()) return;
  const hemm::op::OperatorStationSummary& sum = r.sum;
  EXPECT_EQ(r.servo_allocs, 0u);
  EXPECT_GT(sum.timing.ticks, 15000u);  // 22.5 s; a loaded VM misses ticks
  EXPECT_NEAR(sum.timing.period.median_us, 1000.0, 100.0);

  // Resting pressed on the block's top (t 7.5-8 s of the script, before the
  // slide): the tool's tip centre at the true top + the tip radius, from the
  // live model and from the truth.
  const double z_top = hemm::test::kBlockTop_m, a = r.geometry.tip_radius;
  const hemm::robot::Tool6Truth& t = r.truth;
  EXPECT_NEAR(r.rest_true_z, z_top + a - 0.0024, 0.0015);  // the truth's own depth (~2.4 mm at ~10 N)
  EXPECT_NEAR(r.rest_live_z, r.rest_true_z, 0.003);  // the 1 cm voxmap of the cloud: within 3 mm
  ASSERT_GT(t.contact_ticks, 5000u);
  EXPECT_GT(t.true_force_peak, 5.0);
  // The bound: the tool pressed on a surface is held by the coupling
  // (3000 N/m) in series with the contact (the tip sphere at ~2 mm depth:
  // 2 pi R K delta = 7.5 N/mm), about 2.1 N/mm together; a live surface
  // within 1 mm of the true one (the rest heights above) then changes the
  // force by up to ~2 N: RMS under a quarter of the true peak (~8.5 N).
  EXPECT_LT(t.force_rms, 0.25 * t.true_force_peak);
}

// The whole "explore-table" script (58.5 s): the block's top, front and left
// side, the book's top and front side, the mug's top and front side, with H's
// origin as in deploy/configs/operator_explore3d.pbtxt. The force error over
// each feature's contact ticks is held to what the live model does today,
// with a margin: the weak features (the block's left side, which the mast
// camera sees edge-on; the book's and the mug's front sides, whose live
// surface lies behind the true one; the mug's top) get bounds of their own,
// so a change that makes one of them worse fails here. Measured in 5 runs
// (2026-11-27, beside other builds; two of them cut short by missed ticks
// before the run waited for them) and the README's 0 and 300 ms runs, force
// error RMS, N: block top 1.05-1.15, block front 0.36-0.40, block left side
// 5.85-5.96, book top 0.12-0.13, book front 5.66-5.82, mug top 2.19-2.25, mug
// front 3.05-3.32 (true peaks 7.6-8.7 N). To be tightened as the live model
// improves.
TEST(Explore3dLoopback, TableScriptEachFeatureWithinItsMeasuredBound) {
  hemm::config::OperatorConfig ocfg;
  ocfg.mutable_probe_3d()->set_origin_x_m(0.85);
  ocfg.mutable_probe_3d()->set_origin_z_m(0.95);
  hemm::test::Explore3dRun r;
  // The script ends at 58.5 s of its own time, one period per servo tick: on
  // past 59 s until 58,700 ticks (beside other builds the servo dropped up to
  // 14,000 periods in 68 s), for at most 100 s.
  hemm::test::run_explore("explore3d_table_loopback_test.csv", ocfg,
                          [](hemm::op::OperatorStationOptions& so) { so.device = "sim-hand6"; }, "explore-table",
                          59000, &r, 58700, 100000);
  if (HasFatalFailure()) return;
  EXPECT_EQ(r.servo_allocs, 0u);
  EXPECT_NEAR(r.sum.timing.period.median_us, 1000.0, 100.0);
  const std::vector<hemm::test::FeatureError> f = hemm::test::table_feature_errors(r);
  ASSERT_GT(r.ticks.size(), 58500u) << "the script did not reach its end (ticks missed)";
  constexpr double kMaxRms[] = {1.6, 0.6, 7.5, 0.3, 7.0, 3.0, 4.2};  // N, in the order above
  ASSERT_EQ(f.size(), std::size(kMaxRms));
  for (std::size_t k = 0; k < f.size(); ++k) {
    SCOPED_TRACE(f[k].name);
    // The live voxmap was there (once, beside other builds, its first
    // snapshot came after the block's top: then nothing here says anything).
    EXPECT_GT(f[k].with_model, 0.9) << "no live voxmap for most of this feature";
    EXPECT_GT(f[k].ticks, 500u);      // it was touched (1,200-7,400 contact ticks)
    EXPECT_GT(f[k].true_peak, 5.0);   // and pressed (N)
    EXPECT_LT(f[k].rms, kMaxRms[k]);  // N
  }
}
