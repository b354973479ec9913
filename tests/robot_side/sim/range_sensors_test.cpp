// Range sensor models against an analytic ray caster (a circle of known
// radius around the sensor, or nothing): layout, noise statistics, limits,
// dropouts.
#include "robot_side/sim/range_sensors.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace hr = hemm::robot;

namespace {
// Every ray hits at distance `d` (the sensor inside a cylinder of radius d).
class RingCaster final : public hr::RayCaster {
 public:
  explicit RingCaster(double d) : d_(d) {}
  double cast(const Eigen::Vector3d&, const Eigen::Vector3d& dir) const override {
    EXPECT_NEAR(dir.norm(), 1.0, 1e-12);
    return d_;
  }

 private:
  double d_;
};
class NothingCaster final : public hr::RayCaster {
 public:
  double cast(const Eigen::Vector3d&, const Eigen::Vector3d&) const override { return -1.0; }
};
}  // namespace

TEST(RangeModel, MeasureRangeFlagsNoReturnAndLimits) {
  std::mt19937_64 rng(1);
  float r = 0;
  EXPECT_FALSE(hr::measure_range(-1.0, 0.1, 5.0, 0.01, 0.0, rng, &r));
  EXPECT_EQ(r, 5.0f);
  EXPECT_FALSE(hr::measure_range(0.05, 0.1, 5.0, 0.01, 0.0, rng, &r));
  EXPECT_FALSE(hr::measure_range(6.0, 0.1, 5.0, 0.01, 0.0, rng, &r));
  EXPECT_FALSE(hr::measure_range(std::nan(""), 0.1, 5.0, 0.01, 0.0, rng, &r));
  EXPECT_TRUE(hr::measure_range(2.0, 0.1, 5.0, 0.0, 0.0, rng, &r));
  EXPECT_EQ(r, 2.0f);
  EXPECT_FALSE(hr::measure_range(2.0, 0.1, 5.0, 0.0, 1.0, rng, &r));  // always drops
}

TEST(RangeModel, NoReturnIsToldApartFromDropout) {
  std::mt19937_64 rng(3);
  float r = 0;
  bool none = false;
  EXPECT_FALSE(hr::measure_range(-1.0, 0.1, 5.0, 0.01, 0.0, rng, &r, &none));  // no hit
  EXPECT_TRUE(none);
  EXPECT_FALSE(hr::measure_range(7.0, 0.1, 5.0, 0.01, 0.0, rng, &r, &none));  // beyond range_max
  EXPECT_TRUE(none);
  EXPECT_FALSE(hr::measure_range(0.05, 0.1, 5.0, 0.01, 0.0, rng, &r, &none));  // too near: no information
  EXPECT_FALSE(none);
  EXPECT_FALSE(hr::measure_range(std::nan(""), 0.1, 5.0, 0.01, 0.0, rng, &r, &none));
  EXPECT_FALSE(none);
  EXPECT_FALSE(hr::measure_range(-1.0, 0.1, 5.0, 0.01, 1.0, rng, &r, &none));  // dropout hides "nothing"
  EXPECT_FALSE(none);
  EXPECT_TRUE(hr::measure_range(2.0, 0.1, 5.0, 0.0, 0.0, rng, &r, &none));
  EXPECT_FALSE(none);
  // A whole scan into open space: every beam that did not drop out says
  // "nothing up to range_max"; the dropouts say nothing.
  hr::SimLaserParams p;
  p.dropout_probability = 0.2;
  const hr::RangeScanData s = hr::simulate_laser_scan(p, NothingCaster{}, Eigen::Isometry3d::Identity(), rng);
  ASSERT_EQ(s.no_return.size(), s.ranges.size());
  int none_count = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(s.valid[i], 0);
    none_count += s.no_return[i];
  }
  EXPECT_NEAR(none_count / static_cast<double>(s.size()), 0.8, 0.1);
  const hr::RangeScanData w = hr::simulate_laser_scan(p, RingCaster(2.0), Eigen::Isometry3d::Identity(), rng);
  for (size_t i = 0; i < w.size(); ++i) EXPECT_EQ(w.no_return[i], 0);  // a hit or a dropout, never "nothing"
}

TEST(RangeModel, LaserNoiseHasTheConfiguredSigma) {
  hr::SimLaserParams p;
  p.beams = 361;
  p.sigma = 0.02;
  p.dropout_probability = 0.0;
  std::mt19937_64 rng(2);
  const RingCaster ring(3.0);
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int k = 0; k < 20; ++k) {
    const hr::RangeScanData s = hr::simulate_laser_scan(p, ring, Eigen::Isometry3d::Identity(), rng);
    ASSERT_EQ(s.size(), 361u);
    EXPECT_NEAR(s.angle_min, -p.fov / 2, 1e-12);
    EXPECT_NEAR(s.angle_min + 360 * s.angle_step, p.fov / 2, 1e-12);
    for (size_t i = 0; i < s.size(); ++i) {
      ASSERT_TRUE(s.valid[i]);
      sum += s.ranges[i] - 3.0;
      sum2 += (s.ranges[i] - 3.0) * (s.ranges[i] - 3.0);
      ++n;
    }
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  EXPECT_LT(std::abs(mean), 4 * p.sigma / std::sqrt(n));
  EXPECT_NEAR(sd, p.sigma, 0.05 * p.sigma);
  const hr::RangeScanData none = hr::simulate_laser_scan(p, NothingCaster(), Eigen::Isometry3d::Identity(), rng);
  for (size_t i = 0; i < none.size(); ++i) {
    EXPECT_FALSE(none.valid[i]);
    EXPECT_EQ(none.ranges[i], static_cast<float>(p.range_max));
  }
}

TEST(RangeModel, SonarLimitsApplyFromTheTransducer) {
  hr::SimSonarParams p;
  p.sigma = 0.0;
  p.dropout_probability = 0.0;
  std::mt19937_64 rng(3);
  // Beam 0 (forward) has its transducer 0.245 m out, beam 4 (left) 0.15 m.
  EXPECT_NEAR(p.ring_radius(0), 0.245, 1e-12);
  EXPECT_NEAR(p.ring_radius(4), 0.15, 1e-12);
  // Obstacle 0.3 m from the centre: 0.055 m from the front transducer (below
  // its 0.1 m minimum: invalid), 0.15 m from the side one (valid).
  const hr::RangeScanData s = hr::simulate_sonar_scan(p, RingCaster(0.3), Eigen::Isometry3d::Identity(), rng);
  ASSERT_EQ(s.size(), 16u);
  EXPECT_FALSE(s.valid[0]);
  EXPECT_TRUE(s.valid[4]);
  EXPECT_NEAR(s.ranges[4], 0.3, 1e-6);
  EXPECT_NEAR(s.angle_step, 2 * std::numbers::pi / 16, 1e-12);
  EXPECT_LE(s.range_min, 0.1 + 0.15 + 1e-12);
}
