#include "operator/device/hand_script.h"
#include "operator/device/haptic_device.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hemm::device {
namespace {

using Eigen::Vector3d;

TEST(HandScript, HoldIsConstant) {
  HoldScript h(Vector3d(0.01, 0.02, 0.03), kButton2);
  for (double t : {-1.0, 0.0, 5.0}) {
    EXPECT_EQ(h.at(t).position_H, Vector3d(0.01, 0.02, 0.03));
    EXPECT_EQ(h.at(t).buttons, kButton2);
  }
}

TEST(HandScript, LineMovesAtTheGivenSpeedThenHolds) {
  const Vector3d a(0, 0, 0), b(0.03, 0.04, 0);  // 5 cm
  LineScript l(a, b, 0.1, 0.5);                // 0.1 m/s from t = 0.5 s
  EXPECT_NEAR(l.t_end_s(), 1.0, 1e-12);
  EXPECT_EQ(l.at(0.2).position_H, a);
  EXPECT_LT((l.at(0.75).position_H - Vector3d(0.015, 0.02, 0)).norm(), 1e-12);
  EXPECT_LT((l.at(0.6).position_H - a).norm() - 0.01, 1e-12);
  EXPECT_EQ(l.at(3.0).position_H, b);
  EXPECT_THROW(LineScript(a, b, 0.0), std::invalid_argument);
  EXPECT_THROW(LineScript(a, Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0), 1.0),
               std::invalid_argument);
}

TEST(HandScript, WaypointsArePiecewiseLinearWithButtonsPerSegment) {
  WaypointScript w({{0.0, Vector3d(0, 0, 0), 0},
                    {1.0, Vector3d(0.01, 0, 0), kButton1},
                    {3.0, Vector3d(0.01, 0.02, 0), 0}});
  EXPECT_EQ(w.at(-1.0).position_H, Vector3d::Zero());
  EXPECT_LT((w.at(0.25).position_H - Vector3d(0.0025, 0, 0)).norm(), 1e-15);
  EXPECT_EQ(w.at(0.25).buttons, 0u);
  EXPECT_LT((w.at(2.0).position_H - Vector3d(0.01, 0.01, 0)).norm(), 1e-15);
  EXPECT_EQ(w.at(2.0).buttons, kButton1);
  EXPECT_EQ(w.at(1.0).position_H, Vector3d(0.01, 0, 0));
  EXPECT_EQ(w.at(9.0).position_H, Vector3d(0.01, 0.02, 0));
  EXPECT_EQ(w.at(std::numeric_limits<double>::quiet_NaN()).position_H, Vector3d::Zero());
  EXPECT_THROW(WaypointScript({}), std::invalid_argument);
  EXPECT_THROW(WaypointScript({{1.0, Vector3d::Zero(), 0}, {1.0, Vector3d::Zero(), 0}}),
               std::invalid_argument);
}

TEST(HandScript, ButtonEventsOverrideButtons) {
  auto motion = std::make_shared<HoldScript>(Vector3d(0.01, 0, 0), kButton2);
  ButtonEventsScript s(motion, {{1.0, kButton1}, {2.0, 0}});
  EXPECT_EQ(s.at(0.5).buttons, 0u);
  EXPECT_EQ(s.at(1.0).buttons, kButton1);
  EXPECT_EQ(s.at(1.5).buttons, kButton1);
  EXPECT_EQ(s.at(2.5).buttons, 0u);
  EXPECT_EQ(s.at(1.5).position_H, Vector3d(0.01, 0, 0));
  EXPECT_THROW(ButtonEventsScript(nullptr, {}), std::invalid_argument);
  EXPECT_THROW(ButtonEventsScript(motion, {{2.0, 0}, {1.0, 0}}), std::invalid_argument);
}

// Issue 23 item 2: a SIMULATED hand presses the dead-man where its script
// says: per waypoint (switching there, like the buttons) or in spans laid
// over another script's motion.
TEST(HandScript, TheDeadManIsPressedWhereTheScriptSays) {
  WaypointScript w({{0.0, Vector3d::Zero(), 0, false}, {1.0, Vector3d(0.01, 0, 0), 0, true}, {2.0, Vector3d::Zero(), 0}});
  EXPECT_FALSE(w.at(0.5).deadman);
  EXPECT_TRUE(w.at(1.0).deadman);
  EXPECT_TRUE(w.at(1.5).deadman);
  EXPECT_FALSE(w.at(2.5).deadman);
  EXPECT_FALSE(HoldScript(Vector3d::Zero()).at(1.0).deadman);
  EXPECT_TRUE(HoldScript(Vector3d::Zero(), 0, true).at(1.0).deadman);
  auto motion = std::make_shared<HoldScript>(Vector3d(0.01, 0, 0), kButton1, true);
  const double inf = std::numeric_limits<double>::infinity();
  DeadmanScript d(motion, {{1.0, 2.0}, {3.0, inf}});
  EXPECT_FALSE(d.at(0.5).deadman);  // the spans replace the motion's own press
  EXPECT_TRUE(d.at(1.0).deadman);
  EXPECT_FALSE(d.at(2.0).deadman);
  EXPECT_FALSE(d.at(2.5).deadman);
  EXPECT_TRUE(d.at(1e9).deadman);
  EXPECT_FALSE(d.at(std::nan("")).deadman);
  EXPECT_EQ(d.at(1.5).buttons, kButton1);
  EXPECT_EQ(d.at(1.5).position_H, Vector3d(0.01, 0, 0));
  // The buttons' events keep the motion's dead-man.
  EXPECT_TRUE(ButtonEventsScript(motion, {}).at(0.5).deadman);
  EXPECT_THROW(DeadmanScript(nullptr, {}), std::invalid_argument);
  EXPECT_THROW(DeadmanScript(motion, {{2.0, 1.0}}), std::invalid_argument);
  EXPECT_THROW(DeadmanScript(motion, {{1.0, 3.0}, {2.0, 4.0}}), std::invalid_argument);
  EXPECT_THROW(DeadmanScript(motion, {{std::nan(""), 1.0}}), std::invalid_argument);
}

}  // namespace
}  // namespace hemm::device
