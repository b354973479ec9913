// The TDPA's per-tick calls run on the 1 kHz threads (the operator's servo
// tick, the robot's control tick): none of them allocates.
#include <gtest/gtest.h>

#include "common/haptics/passivity/tdpa_arm.h"
#include "tests/operator/servo/alloc_counter.h"

namespace {

namespace td = hemm::haptics::tdpa;

TEST(TdpaAlloc, TicksAllocateNothing) {
  td::ArmSide op, rob;
  td::ArmWrench w{Eigen::Vector3d(1, -2, 3), Eigen::Vector3d(0.1, 0.2, -0.3)};
  td::ArmTwist v{Eigen::Vector3d(0.05, 0.01, -0.02), Eigen::Vector3d(0.1, -0.1, 0.2)};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  double sink = 0;
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (std::uint64_t k = 1; k <= 2000; ++k) {
    td::receive_peer<6>(op, k, td::Vec6::Constant(1e-7 * static_cast<double>(k)));
    td::receive_peer<6>(rob, k, td::Vec6::Constant(1e-7 * static_cast<double>(k)));
    const td::ArmWrench shown = td::operator_arm_tick(op, w, v, 1e-3);
    const td::ArmTwist tracked = td::robot_arm_tick(rob, v, w, 1e-3);
    T = td::advance_target(T, tracked, 1e-3);
    sink += shown.force.x() + td::summarize(op).min_margin_J + static_cast<double>(td::suggest_mode(0.05, 0.01));
    w.force = -w.force;  // alternate in and out
  }
  const std::uint64_t after = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_TRUE(std::isfinite(sink));
  EXPECT_GT(op.pc_active_ticks, 0u);  // the controller's branch ran
}

}  // namespace
