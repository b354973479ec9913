#include "common/math/frames.h"

#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "common/math/geometry2.h"

namespace hemm::math {
namespace {

TEST(Frames, ComposeInverseRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int i = 0; i < 200; ++i) {
    const Pose2 T_A_B{u(rng), u(rng), u(rng)};
    const Pose2 T_B_C{u(rng), u(rng), u(rng)};
    const Eigen::Vector2d p_C(u(rng), u(rng));
    // T_A_C p = T_A_B (T_B_C p)
    const Eigen::Vector2d direct = apply(compose(T_A_B, T_B_C), p_C);
    const Eigen::Vector2d chained = apply(T_A_B, apply(T_B_C, p_C));
    EXPECT_NEAR((direct - chained).norm(), 0.0, 1e-12);
    // Inverse undoes.
    const Eigen::Vector2d back = apply(inverse(T_A_B), apply(T_A_B, p_C));
    EXPECT_NEAR((back - p_C).norm(), 0.0, 1e-12);
    // Matches Eigen's isometries (2D and 3D).
    EXPECT_NEAR((to_isometry2(T_A_B) * p_C - apply(T_A_B, p_C)).norm(), 0.0, 1e-12);
    const Eigen::Vector3d p3(p_C.x(), p_C.y(), u(rng));
    EXPECT_NEAR((to_isometry3(T_A_B) * p3 - apply(T_A_B, p3)).norm(), 0.0, 1e-12);
    EXPECT_NEAR((inverse(to_isometry3(T_A_B)) * (to_isometry3(T_A_B) * p3) - p3).norm(), 0.0, 1e-12);
    const Pose2 back_pose = to_pose2(to_isometry3(T_A_B));
    EXPECT_NEAR(back_pose.x, T_A_B.x, 1e-12);
    EXPECT_NEAR(wrap_angle(back_pose.theta - T_A_B.theta), 0.0, 1e-12);
  }
}

TEST(Frames, WrapAngle) {
  EXPECT_NEAR(wrap_angle(3.0 * std::numbers::pi), std::numbers::pi, 1e-12);
  EXPECT_NEAR(wrap_angle(-3.0 * std::numbers::pi), std::numbers::pi, 1e-12);
  EXPECT_NEAR(wrap_angle(0.5), 0.5, 1e-15);
  EXPECT_NEAR(wrap_angle(2.0 * std::numbers::pi + 0.25), 0.25, 1e-12);
}

TEST(Geometry2, ClosestPointOnSegment) {
  const Eigen::Vector2d a(0, 0), b(2, 0);
  double t = -1;
  EXPECT_NEAR((closest_point_on_segment(a, b, {1, 3}, &t) - Eigen::Vector2d(1, 0)).norm(), 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(t, 0.5);
  EXPECT_DOUBLE_EQ(distance_to_segment(a, b, {-3, 4}), 5.0);  // beyond the end: distance to a
  EXPECT_DOUBLE_EQ(distance_to_segment(a, a, {3, 4}), 5.0);   // degenerate
}

}  // namespace
}  // namespace hemm::math
