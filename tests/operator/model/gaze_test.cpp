// The gaze chooser (operator/model/gaze.h) against closed forms: the
// look-ahead point of a tool moving at constant velocity, its cap, the pull
// toward unseen candidates near it, the region of interest, the hysteresis.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "operator/model/gaze.h"

namespace ho = hemm::op;

namespace {
constexpr std::int64_t kPeriodNs = 5'000'000;  // the command sender's 200 Hz
}

TEST(Gaze, LooksAheadOfAToolMovingAtConstantVelocity) {
  ho::GazeParams p;
  p.lookahead_s = 0.5;
  p.max_lookahead_m = 1.0;
  ho::GazeChooserState s;
  const Eigen::Vector3d x0(1.3, 1.9, 0.82), v(0.08, -0.05, 0.02);  // m/s
  ho::GazeChoice c;
  double travelled = 0.0;
  for (int k = 0; k <= 600; ++k) {  // 3 s
    const Eigen::Vector3d x = x0 + v * (k * kPeriodNs * 1e-9);
    c = ho::choose_gaze(p, s, x, k * kPeriodNs, {});
    ASSERT_TRUE(c.active);
    // The sent point is never farther than the hysteresis from the wanted one.
    ASSERT_LE((c.point_W - c.wanted_W).norm(), p.hysteresis_m + 1e-12);
    if (k == 600) {
      EXPECT_LT((c.predicted_W - (x + v * p.lookahead_s)).norm(), 1e-9);
      travelled = (v * (3.0 + p.lookahead_s)).norm();  // the wanted point also ran ahead by v L
    }
  }
  // The point moved in steps just over the hysteresis, not every command.
  EXPECT_NEAR(static_cast<double>(s.moves), travelled / p.hysteresis_m, 1.0);
}

TEST(Gaze, CapsTheLookAheadStep) {
  ho::GazeParams p;
  p.lookahead_s = 1.0;
  p.max_lookahead_m = 0.2;
  ho::GazeChooserState s;
  const Eigen::Vector3d v(0.0, 0.6, 0.0);
  ho::GazeChoice c;
  for (int k = 0; k <= 400; ++k) c = ho::choose_gaze(p, s, Eigen::Vector3d(1, 0, 1) + v * (k * 0.005), k * kPeriodNs, {});
  const Eigen::Vector3d x = Eigen::Vector3d(1, 0, 1) + v * 2.0;
  EXPECT_NEAR((c.predicted_W - x).norm(), 0.2, 1e-9);
  EXPECT_NEAR((c.predicted_W - x).normalized().dot(v.normalized()), 1.0, 1e-9);
}

TEST(Gaze, IsPulledTowardUnseenSpaceNearTheTool) {
  ho::GazeParams p;
  p.unseen_gain = 0.1;
  p.unseen_radius_m = 0.3;
  p.hysteresis_m = 0.0;
  const Eigen::Vector3d tool(2.0, 1.0, 0.9);  // at rest: predicted = tool
  // 30 unseen cells around c (weight 1 each), and 50 far ones (ignored).
  std::vector<ho::GazeCandidate> unseen;
  const Eigen::Vector3d c(2.1, 1.15, 0.8);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d q = c + Eigen::Vector3d(u(rng), u(rng), u(rng));
    unseen.push_back({q, 1.0});
    sum += q;
  }
  for (int i = 0; i < 50; ++i) unseen.push_back({tool + Eigen::Vector3d(0.5 + 0.01 * i, 0, 0), 1.0});
  unseen.push_back({tool, std::nan("")});  // ignored
  unseen.push_back({tool, -3.0});          // ignored
  ho::GazeChooserState s;
  const ho::GazeChoice g = ho::choose_gaze(p, s, tool, 0, unseen);
  const Eigen::Vector3d centroid = sum / 30.0;
  const double a = 0.1 * 30 / (1 + 0.1 * 30);  // 0.75
  EXPECT_LT((g.point_W - (tool + a * (centroid - tool))).norm(), 1e-12);
  // None near: the tool's own point.
  ho::GazeChooserState s2;
  std::vector<ho::GazeCandidate> far(unseen.begin() + 30, unseen.end());
  EXPECT_LT((ho::choose_gaze(p, s2, tool, 0, far).point_W - tool).norm(), 1e-12);
  // Kept in the region of interest.
  ho::GazeChooserState s3;
  const Eigen::AlignedBox3d roi(Eigen::Vector3d(1.5, 0.5, 0.85), Eigen::Vector3d(2.05, 1.5, 1.2));
  const ho::GazeChoice r = ho::choose_gaze(p, s3, tool, 0, unseen, roi);
  EXPECT_DOUBLE_EQ(r.point_W.x(), 2.05);
  EXPECT_DOUBLE_EQ(r.point_W.z(), 0.85);
}

TEST(Gaze, HysteresisKeepsTheHeadStillForATremblingHand) {
  ho::GazeParams p;
  p.hysteresis_m = 0.05;
  p.lookahead_s = 0.0;  // the tremor's velocity would otherwise add to it
  ho::GazeChooserState s;
  const Eigen::Vector3d x0(1.0, 2.0, 0.8);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.014, 0.014);  // |offset| < 2.5 cm: always within 5 cm of the first
  ho::GazeChoice first = ho::choose_gaze(p, s, x0, 0, {});
  for (int k = 1; k < 400; ++k) {
    const ho::GazeChoice c = ho::choose_gaze(p, s, x0 + Eigen::Vector3d(u(rng), u(rng), u(rng)), k * kPeriodNs, {});
    ASSERT_EQ(c.point_W, first.point_W) << k;
  }
  EXPECT_EQ(s.moves, 0u);
  // A real move goes through at once.
  const Eigen::Vector3d x1 = x0 + Eigen::Vector3d(0.08, 0, 0);
  const ho::GazeChoice moved = ho::choose_gaze(p, s, x1, 400 * kPeriodNs, {});
  EXPECT_EQ(moved.point_W, x1);
  EXPECT_EQ(s.moves, 1u);
  // No tool: inactive (the head goes home), and the next tool starts afresh.
  EXPECT_FALSE(ho::choose_gaze(p, s, std::nullopt, 401 * kPeriodNs, {}).active);
  EXPECT_FALSE(ho::choose_gaze(p, s, Eigen::Vector3d(std::nan(""), 0, 0), 402 * kPeriodNs, {}).active);
  const ho::GazeChoice again = ho::choose_gaze(p, s, x0, 403 * kPeriodNs, {});
  EXPECT_TRUE(again.active);
  EXPECT_EQ(again.point_W, x0);
}

TEST(Gaze, ParamsAreChecked) {
  EXPECT_FALSE(ho::check(ho::GazeParams{}).has_value());
  ho::GazeParams p;
  p.velocity_tau_s = 0.0;
  EXPECT_TRUE(ho::check(p).has_value());
  p = {};
  p.hysteresis_m = std::nan("");
  EXPECT_TRUE(ho::check(p).has_value());
}
