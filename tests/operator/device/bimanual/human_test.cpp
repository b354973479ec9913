// The simulated human's key script and model validation.
#include "operator/device/bimanual/human.h"

#include <gtest/gtest.h>

namespace hb = hemm::device::bimanual;

TEST(HumanScript, InterpolatesBetweenKeysAndHoldsOutside) {
  hb::HumanTarget a, b;
  a.position_D = Eigen::Vector3d(0, 0, 0);
  b.position_D = Eigen::Vector3d(1, 2, 0);
  b.orientation_D = Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()));
  b.push_force_D = Eigen::Vector3d(10, 0, 0);
  b.deadman = false;
  b.buttons = 3;
  b.finger_position = 0.02;
  const hb::HumanKeyScript s({{1.0, a}, {3.0, b}});
  EXPECT_EQ(s.at(0.0).position_D, a.position_D);
  EXPECT_TRUE(s.at(0.5).deadman);
  const hb::HumanTarget m = s.at(2.0);
  EXPECT_LT((m.position_D - Eigen::Vector3d(0.5, 1.0, 0)).norm(), 1e-12);
  EXPECT_NEAR(m.orientation_D.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()))), 0.0, 1e-12);
  EXPECT_NEAR(m.push_force_D.x(), 5.0, 1e-12);
  EXPECT_NEAR(m.finger_position, 0.01, 1e-12);
  EXPECT_TRUE(m.deadman);  // switches at the key, not in between
  EXPECT_EQ(m.buttons, 0u);
  EXPECT_FALSE(s.at(3.0).deadman);
  EXPECT_EQ(s.at(9.0).buttons, 3u);
  EXPECT_EQ(s.at(9.0).position_D, b.position_D);
}

TEST(HumanScript, RejectsBadKeysAndModels) {
  hb::HumanTarget t;
  EXPECT_THROW(hb::HumanKeyScript({}), std::invalid_argument);
  EXPECT_THROW(hb::HumanKeyScript({{1.0, t}, {1.0, t}}), std::invalid_argument);
  hb::HumanTarget n = t;
  n.push_force_D.x() = NAN;
  EXPECT_THROW(hb::HumanKeyScript({{0.0, n}}), std::invalid_argument);
  EXPECT_FALSE(hb::validate(hb::HumanModel{}));
  hb::HumanModel m;
  m.grasp_stiffness = 0;
  EXPECT_TRUE(hb::validate(m));
  m = hb::HumanModel{};
  m.arm_damping = -1;
  EXPECT_TRUE(hb::validate(m));
}
