// The 6-DoF probe tool on the live voxmap end to end over real loopback
// sockets (issue 13), held by the RIGHT arm of the SIMULATED bimanual device
// (operator/station/tool6_bimanual.h) with the shipped config's device block
// and mapping (deploy/configs/operator_explore3d_bimanual.pbtxt): the
// SIMULATED human follows the "explore-block" script in D and yields to the
// force, so the logged goal path is the hand's actual path; the truth replays
// that path (explore3d_run.h). Both arms' controllers and the MuJoCo plant
// run inside the servo tick.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "common/config/config.h"
#include "operator/bimanual/bimanual_config.h"
#include "tests/integration/explore3d/explore3d_run.h"

TEST(Explore3dBimanualLoopback, ToolOnTheRightArmRestsOnTheTrueBlockTopAndFollowsTheTrueForce) {
  hemm::config::OperatorConfig ocfg;
  const std::string path = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator_explore3d_bimanual.pbtxt";
  auto e = hemm::config::load_text_config(path, &hemm::op::validate_operator_config_with_bimanual, &ocfg);
  ASSERT_FALSE(e) << e->to_string();
  ASSERT_EQ(ocfg.device().type(), "sim-bimanual");
  hemm::test::Explore3dRun r;
  const auto bimanual = std::make_shared<const hemm::config::BimanualDeviceConfig>(ocfg.device().bimanual());
  hemm::test::run_explore(
      "explore3d_bimanual_loopback_test.csv", ocfg,
      [&](hemm::op::OperatorStationOptions& so) {
        so.device = "sim-bimanual";
        so.bimanual = bimanual;
      },
      "explore-block", 22500, &r);
  if (HasFatalFailure()) return;
  const hemm::op::OperatorStationSummary& sum = r.sum;
  EXPECT_EQ(r.servo_allocs, 0u);  // both arms' controllers and MuJoCo included
  EXPECT_GT(sum.timing.ticks, 15000u);  // 22.5 s; a loaded VM misses ticks
  EXPECT_NEAR(sum.timing.period.median_us, 1000.0, 100.0);

  // Resting pressed on the block's top (t 7.5-8 s): the hand yields, so the
  // depth is the contact's under the force the hand holds, not the rigid
  // hand's 2.4 mm. The truth's rest against the closed form of a sphere
  // pressed into a half-space (pressure K: F = pi K R delta^2), from its own
  // median force there; the live rest within 3 mm of the truth's.
  const hemm::robot::Tool6Truth& t = r.truth;
  const double z_top = hemm::test::kBlockTop_m, a = r.geometry.tip_radius;
  std::vector<double> f_true;
  for (std::size_t i = 7500; i < 8000 && i < t.replay.wrench.size(); ++i)
    f_true.push_back(t.replay.wrench[i].force.norm());
  ASSERT_FALSE(f_true.empty());
  const double F = hemm::test::median(f_true);
  const double depth = std::sqrt(std::max(F, 0.0) / (std::numbers::pi * r.params.contact.stiffness * a));
  std::printf("true rest force %.2f N, closed-form depth %.2f mm\n", F, depth * 1e3);
  EXPECT_GT(F, 1.0);  // the hand presses
  EXPECT_NEAR(r.rest_true_z, z_top + a - depth, 0.0015);
  EXPECT_NEAR(r.rest_live_z, r.rest_true_z, 0.003);  // the 1 cm voxmap of the cloud: within 3 mm
  // The hand yields: its path (the logged goal, which the truth replays) is
  // held above the script's target there (the tip centre 5 mm into the top).
  std::vector<double> goal_z;
  for (std::size_t i = 7500; i < 8000; ++i) goal_z.push_back(r.ticks[i].goal.translation().z());
  std::printf("hand (goal) on the block top %.4f m, the script's target %.4f m\n", hemm::test::median(goal_z),
              z_top + a - 0.005);
  EXPECT_GT(hemm::test::median(goal_z), z_top + a - 0.005 + 0.001);
  ASSERT_GT(t.contact_ticks, 5000u);
  EXPECT_GT(t.true_force_peak, 5.0);
  // The bound: replayed along the hand's path, the truth's tool is held by
  // the coupling (3000 N/m) in series with the contact (~7.5 N/mm at 2 mm
  // depth), ~2.1 N/mm; a live surface within ~1 mm of the true one changes
  // the force by up to ~2 N: RMS under a quarter of the true peak.
  EXPECT_LT(t.force_rms, 0.25 * t.true_force_peak);
}
