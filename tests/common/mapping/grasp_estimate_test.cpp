// The grasp estimate against synthetic objects of known mass and centre of
// mass: the wrist wrench of gravity alone at several orientations, with
// sensor noise and a constant bias in G; moving samples (m a in the wrench)
// left out; the bench bearing part of the weight gated out; bad samples
// refused without a change.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "common/mapping/grasp_estimate.h"

namespace hemm::mapping {
namespace {

struct GraspTruth {
  double mass;
  Eigen::Vector3d com_G;
  Eigen::Vector3d force_bias_G, torque_bias_G;
};

class GraspSynth {
 public:
  GraspSynth(const GraspTruth& t, double force_sigma, double torque_sigma, unsigned seed)
      : t_(t), nf_(0, force_sigma), nt_(0, torque_sigma), rng_(seed) {}

  // The wrench at G in A of the object at grasp pose T_A_G, accelerating at a_A (m a).
  GraspSample sample(std::int64_t stamp_ns, const Eigen::Isometry3d& T_A_G, const Eigen::Vector3d& a_A,
                     const Eigen::Vector3d& v_A) {
    const Eigen::Vector3d g(0, 0, -9.81);
    const Eigen::Matrix3d& R = T_A_G.linear();
    // The object's inertial force at its centre of mass: m (g - a).
    const Eigen::Vector3d f_A = t_.mass * (g - a_A);
    const Eigen::Vector3d t_A = (R * t_.com_G).cross(f_A);
    GraspSample s;
    s.stamp_ns = stamp_ns;
    s.T_A_G = T_A_G;
    s.v_A = v_A;
    s.force_A = f_A + R * (t_.force_bias_G + noise(nf_));
    s.torque_A = t_A + R * (t_.torque_bias_G + noise(nt_));
    return s;
  }
  GraspSample tare(std::int64_t stamp_ns, const Eigen::Isometry3d& T_A_G) {
    GraspSample s;
    s.stamp_ns = stamp_ns;
    s.T_A_G = T_A_G;
    const Eigen::Matrix3d& R = T_A_G.linear();
    s.force_A = R * (t_.force_bias_G + noise(nf_));
    s.torque_A = R * (t_.torque_bias_G + noise(nt_));
    return s;
  }
  std::mt19937& rng() { return rng_; }

 private:
  Eigen::Vector3d noise(std::normal_distribution<double>& n) { return {n(rng_), n(rng_), n(rng_)}; }
  GraspTruth t_;
  std::normal_distribution<double> nf_, nt_;
  std::mt19937 rng_;
};

Eigen::Isometry3d grasp_pose(const Eigen::Vector3d& rotvec, const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (rotvec.norm() > 0) T.linear() = Eigen::AngleAxisd(rotvec.norm(), rotvec.normalized()).toRotationMatrix();
  T.translation() = p;
  return T;
}

const Eigen::Vector3d kZero3 = Eigen::Vector3d::Zero();
constexpr std::int64_t kStateNs = 4'000'000;  // 250 Hz

// Chi-square 99.9 % for 3 DoF.
constexpr double kChi2_3 = 16.27;

TEST(GraspEstimate, ConvergesOnObjectsOfKnownMassAndCentreOfMass) {
  const GraspTruth objects[] = {
      {2.0, {0.0, 0.02, 0.08}, {0.4, -0.6, 0.9}, {0.03, -0.02, 0.05}},      // the box
      {0.35, {0.01, -0.03, 0.06}, {-0.3, 0.2, 0.5}, {-0.01, 0.02, 0.0}},    // the peg
      {0.8, {0.12, 0.0, 0.02}, {0.0, 0.5, -0.4}, {0.02, 0.0, -0.03}},       // a bar held off centre
  };
  const Eigen::Vector3d orientations[] = {
      {0, 0, 0}, {0.9, 0, 0}, {0, -0.8, 0}, {0.5, 0.5, 0.3}, {-0.7, 0.2, 1.2}, {0, 1.0, -0.6},
  };
  const GraspEstimateParams params;
  ASSERT_FALSE(validate(params).has_value());
  unsigned seed = 11;
  for (const GraspTruth& t : objects) {
    GraspSynth synth(t, 0.3, 0.02, seed++);
    std::uniform_real_distribution<double> small(-0.05, 0.05);
    GraspEstimator e = make_grasp_estimator(params);
    std::int64_t stamp = 0;
    for (const Eigen::Vector3d& rv : orientations) {
      const Eigen::Isometry3d T = grasp_pose(rv, {0.5, 0.1, 1.0});
      for (int i = 0; i < 60; ++i) {
        stamp += kStateNs;
        // A hand at rest trembles a little: accelerations well below the gate.
        const Eigen::Vector3d a(small(synth.rng()), small(synth.rng()), small(synth.rng()));
        add_grasp_sample(params, &e, synth.sample(stamp, T, a, Eigen::Vector3d::Zero()));
      }
      stamp += 500'000'000;  // moving to the next orientation: a gap
    }
    const GraspEstimate est = current_estimate(e);
    const double sm = std::sqrt(est.mass_variance);
    const Eigen::Vector3d dc = est.com_G - t.com_G;
    const double mahal = dc.dot(est.com_covariance.inverse() * dc);
    std::printf("m %.3f kg: %.4f +- %.4f kg; com err %.2f mm (sigma %.2f mm, chi2 %.2f); bias err %.3f N; %lu used\n",
                t.mass, est.mass_kg, sm, 1e3 * dc.norm(), 1e3 * std::sqrt(est.com_covariance.trace()), mahal,
                (est.force_bias_G - t.force_bias_G).norm(), static_cast<unsigned long>(est.samples));
    EXPECT_TRUE(est.valid);
    EXPECT_NEAR(est.mass_kg, t.mass, 0.02);
    EXPECT_LT(dc.norm(), 0.003);
    // The reported variance is honest: the truth lies within it.
    EXPECT_LT(std::abs(est.mass_kg - t.mass), 4 * sm);
    EXPECT_LT(mahal, kChi2_3);
    EXPECT_LT((est.force_bias_G - t.force_bias_G).norm(), 0.1);
  }
}

TEST(GraspEstimate, TareSamplesLetOneOrientationSuffice) {
  const GraspTruth t{1.4, {0.02, 0.01, 0.07}, {0.6, 0.3, -0.8}, {0.02, 0.03, -0.01}};
  const GraspEstimateParams params;
  GraspSynth synth(t, 0.3, 0.02, 5);
  const Eigen::Isometry3d T = grasp_pose({0.2, -0.1, 0.4}, {0.4, -0.2, 0.9});
  std::int64_t stamp = 0;
  // Without tare: one orientation cannot tell the mass from the force bias.
  GraspEstimator alone = make_grasp_estimator(params), tared = make_grasp_estimator(params);
  for (int i = 0; i < 100; ++i) {
    stamp += kStateNs;
    add_tare_sample(params, &tared, synth.tare(stamp, T));
  }
  for (int i = 0; i < 300; ++i) {
    stamp += kStateNs;
    const GraspSample s = synth.sample(stamp, T, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    add_grasp_sample(params, &alone, s);
    add_grasp_sample(params, &tared, s);
  }
  const GraspEstimate a = current_estimate(alone), b = current_estimate(tared);
  std::printf("one orientation: mass %.3f +- %.3f kg untared, %.4f +- %.4f kg tared (truth %.2f)\n", a.mass_kg,
              std::sqrt(a.mass_variance), b.mass_kg, std::sqrt(b.mass_variance), t.mass);
  EXPECT_NEAR(b.mass_kg, t.mass, 0.02);
  // One orientation tells the centre of mass only across gravity: along
  // g_G it produces no torque, and the estimate says so.
  const Eigen::Vector3d g_G = (T.linear().transpose() * params.gravity_A).normalized();
  const Eigen::Vector3d dc = b.com_G - t.com_G;
  EXPECT_LT((dc - dc.dot(g_G) * g_G).norm(), 0.003);
  EXPECT_GT(g_G.dot(b.com_covariance * g_G), 100 * (b.com_covariance.trace() - g_G.dot(b.com_covariance * g_G)));
  // The untared estimate says it does not know as much.
  EXPECT_GT(a.mass_variance, 10 * b.mass_variance);
  EXPECT_LT(std::abs(a.mass_kg - t.mass), 4 * std::sqrt(a.mass_variance));
}

TEST(GraspEstimate, MovingSamplesAndTheBenchAreLeftOut) {
  const GraspTruth t{2.0, {0.0, 0.0, 0.075}, {0.2, 0.1, 0.3}, {0.0, 0.01, 0.0}};
  const GraspEstimateParams params;
  GraspSynth synth(t, 0.3, 0.02, 9);
  GraspEstimator e = make_grasp_estimator(params);
  std::int64_t stamp = 0;
  const Eigen::Vector3d orientations[] = {{0, 0, 0}, {0.8, 0, 0}, {0, 0.8, 0}, {0.4, -0.4, 0.8}};
  for (const Eigen::Vector3d& rv : orientations) {
    const Eigen::Isometry3d T = grasp_pose(rv, {0.5, 0, 1.0});
    for (int i = 0; i < 60; ++i) {
      stamp += kStateNs;
      add_grasp_sample(params, &e, synth.sample(stamp, T, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()));
    }
    // A lift: 3 m/s^2 up for 0.2 s (the wrench carries m a = 6 N).
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    int used_while_moving = 0;
    for (int i = 0; i < 50; ++i) {
      stamp += kStateNs;
      const Eigen::Vector3d a(0, 0, i < 25 ? 3.0 : -3.0);
      v += a * 4e-3;
      const GraspEstimator before = e;
      const GraspSampleResult r = add_grasp_sample(params, &e, synth.sample(stamp, T, a, v));
      if (r == GraspSampleResult::kUsed) ++used_while_moving;
      if (r == GraspSampleResult::kMoving) {
        EXPECT_EQ(e.theta, before.theta);
      }
    }
    EXPECT_EQ(used_while_moving, 0);
  }
  EXPECT_GE(e.moving, 4u * 49u);
  // Set down on the bench while still gripped: the bench bears 80 % of the
  // weight. The gate leaves those samples out.
  const Eigen::Isometry3d T = grasp_pose({0, 0, 0}, {0.5, 0, 0.85});
  GraspTruth resting = t;
  resting.mass = 0.2 * t.mass;
  GraspSynth bench(resting, 0.3, 0.02, 10);
  for (int i = 0; i < 100; ++i) {
    stamp += kStateNs;
    add_grasp_sample(params, &e, bench.sample(stamp, T, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()));
  }
  const GraspEstimate est = current_estimate(e);
  std::printf("with lifts and the bench: mass %.4f kg, com err %.2f mm; %lu used, %lu moving, %lu outliers\n",
              est.mass_kg, 1e3 * (est.com_G - t.com_G).norm(), static_cast<unsigned long>(e.used),
              static_cast<unsigned long>(e.moving), static_cast<unsigned long>(e.outliers));
  EXPECT_GE(e.outliers, 99u);
  EXPECT_NEAR(est.mass_kg, t.mass, 0.02);
  EXPECT_LT((est.com_G - t.com_G).norm(), 0.003);
}

TEST(GraspEstimate, BadSamplesAreRefusedAndChangeNothing) {
  const GraspTruth t{1.0, {0.0, 0.0, 0.05}, {0, 0, 0}, {0, 0, 0}};
  const GraspEstimateParams params;
  GraspSynth synth(t, 0.1, 0.01, 3);
  GraspEstimator e = make_grasp_estimator(params);
  const Eigen::Isometry3d T = grasp_pose({0.3, 0, 0}, {0.5, 0, 1});
  for (int i = 1; i <= 20; ++i) add_grasp_sample(params, &e, synth.sample(i * kStateNs, T, kZero3, kZero3));
  auto same = [](const GraspEstimator& a, const GraspEstimator& b) {
    return a.theta == b.theta && a.P == b.P && a.used == b.used && a.previous_stamp_ns == b.previous_stamp_ns;
  };
  const GraspEstimator before = e;
  GraspSample bad = synth.sample(21 * kStateNs, T, kZero3, kZero3);
  bad.force_A.y() = std::nan("");
  EXPECT_EQ(add_grasp_sample(params, &e, bad), GraspSampleResult::kNonFinite);
  EXPECT_TRUE(same(e, before));
  bad = synth.sample(21 * kStateNs, T, kZero3, kZero3);
  bad.T_A_G.translation().z() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(add_grasp_sample(params, &e, bad), GraspSampleResult::kNonFinite);
  bad = synth.sample(21 * kStateNs, T, kZero3, kZero3);
  bad.omega_A.x() = std::nan("");
  EXPECT_EQ(add_tare_sample(params, &e, bad), GraspSampleResult::kNonFinite);
  bad = synth.sample(21 * kStateNs, T, kZero3, kZero3);
  bad.T_A_G.linear() *= 2.0;
  EXPECT_EQ(add_grasp_sample(params, &e, bad), GraspSampleResult::kNotRotation);
  bad = synth.sample(20 * kStateNs, T, kZero3, kZero3);  // not after the previous
  EXPECT_EQ(add_grasp_sample(params, &e, bad), GraspSampleResult::kNotMonotonic);
  EXPECT_TRUE(same(e, before));
  EXPECT_EQ(e.refused, 5u);
  EXPECT_STREQ(to_string(GraspSampleResult::kNotMonotonic), "stamp not after the previous sample");

  GraspEstimateParams p = params;
  p.force_sigma_n = 0;
  ASSERT_TRUE(validate(p).has_value());
  EXPECT_NE(validate(p)->find("positive"), std::string::npos);
  p = params;
  p.gravity_A.z() = std::nan("");
  EXPECT_TRUE(validate(p).has_value());
  p = params;
  p.prior_force_bias_sigma_n = -1;
  EXPECT_TRUE(validate(p).has_value());
}

TEST(GraspEstimate, TheEstimateIsAHeldBody) {
  GraspEstimate e;
  e.mass_kg = 2.0;
  e.com_G = Eigen::Vector3d(0, 0.01, 0.07);
  const mesh::MassProperties b = body_from_estimate(e, {0.3, 0.2, 0.15});
  EXPECT_EQ(b.mass, 2.0);
  EXPECT_EQ(b.centre_of_mass, e.com_G);
  // Solid box: m (b^2 + c^2) / 12 about x.
  EXPECT_NEAR(b.inertia_com(0, 0), 2.0 * (0.04 + 0.0225) / 12, 1e-12);
  EXPECT_NEAR(b.inertia_com(2, 2), 2.0 * (0.09 + 0.04) / 12, 1e-12);
}

}  // namespace
}  // namespace hemm::mapping
