// The SIMULATED interface in one object: a servo period (both controllers
// and the plant) allocates nothing; bad configs are refused.
#include "operator/device/bimanual/simulation.h"

#include <gtest/gtest.h>

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
