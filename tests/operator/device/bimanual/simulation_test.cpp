// The SIMULATED interface in one object: a servo period (both controllers
// and the plant) allocates nothing; bad configs are refused.
#include "operator/device/bimanual/simulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "tests/operator/servo/alloc_counter.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

TEST(BimanualSimulation, StepAllocatesNothing) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kJoystick};
  hb::BimanualSimulation s(c);
  auto h = s.resting_targets();
  h[0].push_force_D = Eigen::Vector3d(5, -5, 0);
  hk::Wrench6 w = hk::Wrench6::Zero();
  w(2) = -10.0;
  s.step({w, w}, {2.0, 0.0}, h);
  const auto before = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(true);
  for (int k = 0; k < 300; ++k) s.step({w, w}, {2.0, 0.0}, h);
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(hemm::test::counted_allocations() - before, 0u)
      << (hemm::test::malloc_is_hooked() ? "(malloc + operator new counted)" : "(operator new counted)");
}

TEST(BimanualSimulation, RejectsBadConfigs) {
  hb::SimulationConfig c;
  c.control[0].inertia_ratio_rotation = 2.0;
  EXPECT_THROW(hb::BimanualSimulation{c}, std::invalid_argument);
  c = hb::SimulationConfig{};
  c.plant.control_period_s = 0.0;
  EXPECT_THROW(hb::BimanualSimulation{c}, std::invalid_argument);
  EXPECT_FALSE(hb::validate(hb::SimulationConfig{}));
}

// The SIMULATED human's voluntary effort (human.h): the right hand is pushed
// down by a steady 3 N (push_force_D) while its target stays at the rest.
// With ideal actuators, an exact model and no elbow force the device holds
// no position, so at rest the human's arm spring alone leaves the hand
// 3 N / 300 N/m = 10 mm low; a voluntary effort of at most 2 N leaves
// (3 - 2) / 300 = 3.33 mm; one of up to 15 N takes the push out entirely.
TEST(BimanualSimulation, VoluntaryEffortTakesOutASteadyPushUpToItsBound) {
  for (const double max_f : {0.0, 2.0, 15.0}) {
    hb::SimulationConfig c;
    c.plant.actuators = hb::ideal_actuators(c.plant.rig.arm);
    c.plant.model_error = hb::ModelError{0.0, 0.0, 0.0, 1};
    for (auto& p : c.control) p.elbow_force = 0.0;
    c.plant.humans[0].max_voluntary_force = max_f;
    hb::BimanualSimulation sim(c);
    auto targets = sim.resting_targets();
    const Eigen::Vector3d rest = targets[0].position_D;
    targets[0].push_force_D = Eigen::Vector3d(0.0, 0.0, -3.0);
    for (int i = 0; i < 6000; ++i) sim.step(targets);
    const hb::HandTruth& h = sim.truth().hands[0];
    const double k = c.plant.humans[0].arm_stiffness;
    const double want = std::max(3.0 - max_f, 0.0) / k;
    std::printf("max voluntary %.0f N: hand %.3f mm below its target (want %.3f), speed %.2g m/s\n", max_f,
                (rest.z() - h.position_D.z()) * 1e3, want * 1e3, h.velocity_D.norm());
    EXPECT_NEAR(rest.z() - h.position_D.z(), want, 2e-4) << max_f;
    EXPECT_LT((rest - h.position_D).head<2>().norm(), 5e-4) << max_f;
    EXPECT_LT(h.velocity_D.norm(), 1e-3) << max_f;
  }
  hb::HumanModel bad;
  bad.max_voluntary_force = -1.0;
  EXPECT_TRUE(hb::validate(bad));
}
