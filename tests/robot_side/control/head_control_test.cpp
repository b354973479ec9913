// The pan-tilt head's controller (robot_side/control/head_control.h) and the
// SIMULATED head's joints (robot_side/sim/depth_camera.h SimPanTiltHead)
// against closed forms: the aim, the limits, the rate-limited ramp, the
// first-order settling, refusals, and the return home.
#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "robot_side/control/head_control.h"
#include "robot_side/sim/depth_camera.h"

namespace hr = hemm::robot;

namespace {
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kDt = 0.001;
constexpr std::int64_t kDtNs = 1'000'000;

hr::HeadParams params() {
  hr::HeadParams p;
  p.head_R = Eigen::Vector3d(0.12, -0.05, 1.15);  // not the default mast: geometry not tuned on
  return p;
}

// The point at range r along the optical axis of (pan, tilt) from the head.
Eigen::Vector3d point_at(const hr::HeadParams& p, double pan, double tilt, double r) {
  return p.head_R + r * Eigen::Vector3d(std::cos(tilt) * std::cos(pan), std::cos(tilt) * std::sin(pan), -std::sin(tilt));
}

Eigen::Isometry3d pose_W_R(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << x, y, 0.0;
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}
}  // namespace

TEST(HeadControl, AimPutsTheOpticalAxisThroughTheTarget) {
  const hr::HeadParams p = params();
  for (const auto& [pan, tilt, r] : {std::tuple{30.0, 40.0, 1.2}, {-75.0, 12.0, 2.5}, {5.0, -8.0, 0.7}}) {
    const Eigen::Vector3d x_R = point_at(p, pan * kDeg, tilt * kDeg, r);
    const hr::HeadAim a = hr::aim_head(p, x_R);
    ASSERT_EQ(a.refusal, hr::GazeRefusal::kNone);
    EXPECT_NEAR(a.pan, pan * kDeg, 1e-12);
    EXPECT_NEAR(a.tilt, tilt * kDeg, 1e-12);
    // In the sensor frame the target is on z_S at its range.
    const Eigen::Vector3d x_S = hr::head_T_R_S(p.head_R, a.pan, a.tilt).inverse() * x_R;
    EXPECT_NEAR(x_S.x(), 0.0, 1e-12);
    EXPECT_NEAR(x_S.y(), 0.0, 1e-12);
    EXPECT_NEAR(x_S.z(), r, 1e-12);
  }
  // Pan 0, tilt p is the fixed mast camera.
  const Eigen::Isometry3d mast = hr::SimDepthCameraParams::mast_mount(0.3, 0.9, 20 * kDeg);
  EXPECT_TRUE(hr::head_T_R_S({0.3, 0.0, 0.9}, 0.0, 20 * kDeg).isApprox(mast, 1e-15));
}

TEST(HeadControl, RefusesBadTargetsCountsThemAndHolds) {
  const hr::HeadParams p = params();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(hr::aim_head(p, {nan, 0, 0}).refusal, hr::GazeRefusal::kNotFinite);
  EXPECT_EQ(hr::aim_head(p, point_at(p, 0.3, 0.4, 0.2)).refusal, hr::GazeRefusal::kTooNear);
  EXPECT_EQ(hr::aim_head(p, point_at(p, 0.3, 0.4, 4.5)).refusal, hr::GazeRefusal::kTooFar);
  EXPECT_EQ(hr::aim_head(p, point_at(p, 120 * kDeg, 0.4, 1.0)).refusal, hr::GazeRefusal::kPanLimit);
  EXPECT_EQ(hr::aim_head(p, point_at(p, 0.3, 85 * kDeg, 1.0)).refusal, hr::GazeRefusal::kTiltLimit);
  EXPECT_EQ(hr::aim_head(p, point_at(p, 0.3, -15 * kDeg, 1.0)).refusal, hr::GazeRefusal::kTiltLimit);

  // Following a good target, half-way there, a bad one comes: counted, its
  // seq kept, and the setpoints stay where they are.
  const Eigen::Isometry3d T_W_R = pose_W_R(1.0, -0.5, 0.4);
  hr::HeadControlState s = hr::head_control_init(p);
  std::int64_t t = 0;
  EXPECT_EQ(hr::head_gaze_command(p, s, T_W_R * point_at(p, 40 * kDeg, 50 * kDeg, 1.0), true, T_W_R, 7, t),
            hr::GazeRefusal::kNone);
  for (int k = 0; k < 100; ++k) hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  const double pan0 = s.pan_sp, tilt0 = s.tilt_sp;
  EXPECT_GT(pan0, 0.1);
  EXPECT_EQ(hr::head_gaze_command(p, s, {nan, 1, 1}, true, T_W_R, 8, t), hr::GazeRefusal::kNotFinite);
  EXPECT_EQ(hr::head_gaze_command(p, s, T_W_R * point_at(p, 150 * kDeg, 0.2, 1.0), true, T_W_R, 9, t),
            hr::GazeRefusal::kPanLimit);
  EXPECT_EQ(s.refusals, 2u);
  EXPECT_EQ(s.last_refusal, hr::GazeRefusal::kPanLimit);
  EXPECT_EQ(s.last_refused_seq, 9u);
  for (int k = 0; k < 200; ++k) hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  EXPECT_EQ(s.pan_sp, pan0);
  EXPECT_EQ(s.tilt_sp, tilt0);
  // The gaze watchdog was fed only by the accepted target: once it expires
  // (500 ms after it) the head goes home.
  for (int k = 0; k < 2000; ++k) hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  EXPECT_EQ(s.pan_sp, p.home_pan);
  EXPECT_EQ(s.tilt_sp, p.home_tilt);
}

TEST(HeadControl, SetpointsRampAtTheRateLimit) {
  hr::HeadParams p = params();
  p.max_rate = 70 * kDeg;
  const Eigen::Isometry3d T_W_R = pose_W_R(-2.0, 3.0, -1.0);
  hr::HeadControlState s = hr::head_control_init(p);
  const double pan_goal = -55 * kDeg, tilt_goal = 15 * kDeg;
  std::int64_t t = 0;
  ASSERT_EQ(hr::head_gaze_command(p, s, T_W_R * point_at(p, pan_goal, tilt_goal, 1.7), true, T_W_R, 1, t),
            hr::GazeRefusal::kNone);
  for (int k = 1; k <= 1200; ++k) {
    if (k % 100 == 0) hr::head_gaze_command(p, s, T_W_R * point_at(p, pan_goal, tilt_goal, 1.7), true, T_W_R, 1, t);
    hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
    const double ramp = p.max_rate * kDt * k;
    ASSERT_NEAR(s.pan_sp, std::max(pan_goal, p.home_pan - ramp), 1e-9) << k;
    ASSERT_NEAR(s.tilt_sp, std::max(tilt_goal, p.home_tilt - ramp), 1e-9) << k;
  }
}

TEST(HeadControl, TheHeadSettlesAsTheRampThroughAFirstOrderLag) {
  // A pan step of A through the rate limit w and the joint's lag tau:
  // x(t) = w (t - tau (1 - e^{-t/tau})) until T = A / w, then
  // x(t) = A + (x(T) - A) e^{-(t - T)/tau}.
  hr::HeadParams p = params();
  p.max_rate = 80 * kDeg;
  hr::SimPanTiltHead head;
  head.params.time_constant = 0.12;
  head.pan = p.home_pan;
  head.tilt = p.home_tilt;
  const double A = 50 * kDeg, w = p.max_rate, tau = head.params.time_constant, T = A / w;
  const Eigen::Isometry3d T_W_R = Eigen::Isometry3d::Identity();
  hr::HeadControlState s = hr::head_control_init(p);
  std::int64_t t_ns = 0;
  double settled_at = -1.0;
  for (int k = 1; k <= 2500; ++k) {
    if (k % 100 == 1) hr::head_gaze_command(p, s, point_at(p, A, p.home_tilt, 1.5), true, T_W_R, 1, t_ns);
    hr::head_control_step(p, s, T_W_R, true, false, t_ns += kDtNs, kDt);
    head.step(p, s.pan_sp, s.tilt_sp, kDt);
    const double t = k * kDt;
    const double xT = w * (T - tau * (1 - std::exp(-T / tau)));
    const double x = t < T ? w * (t - tau * (1 - std::exp(-t / tau))) : A + (xT - A) * std::exp(-(t - T) / tau);
    // The discrete setpoint leads the continuous ramp by at most one step.
    ASSERT_NEAR(head.pan, x, 1.1 * w * kDt) << t;
    EXPECT_NEAR(head.tilt, p.home_tilt, 1e-12);
    if (settled_at < 0 && std::abs(head.pan - A) < 0.02 * A) settled_at = t;
  }
  // 2 % settling: T + tau ln((A - x(T)) / (0.02 A)).
  const double xT = w * (T - tau * (1 - std::exp(-T / tau)));
  EXPECT_NEAR(settled_at, T + tau * std::log((A - xT) / (0.02 * A)), 0.01);
}

TEST(HeadControl, GoesHomeOnLinkLossAndHoldsAtTheEStop) {
  const hr::HeadParams p = params();
  const Eigen::Isometry3d T_W_R = pose_W_R(0.5, 0.5, 0.0);
  hr::HeadControlState s = hr::head_control_init(p);
  std::int64_t t = 0;
  const auto target = T_W_R * point_at(p, 60 * kDeg, 10 * kDeg, 1.3);
  for (int k = 0; k < 1500; ++k) {
    if (k % 50 == 0) hr::head_gaze_command(p, s, target, true, T_W_R, 2, t);
    hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  }
  EXPECT_NEAR(s.pan_sp, 60 * kDeg, 1e-9);
  EXPECT_NEAR(s.tilt_sp, 10 * kDeg, 1e-9);
  // E-stop: nothing moves, the gaze commands notwithstanding.
  for (int k = 0; k < 300; ++k) {
    if (k % 50 == 0) hr::head_gaze_command(p, s, T_W_R * point_at(p, -60 * kDeg, 10 * kDeg, 1.3), true, T_W_R, 3, t);
    hr::head_control_step(p, s, T_W_R, true, true, t += kDtNs, kDt);
  }
  EXPECT_NEAR(s.pan_sp, 60 * kDeg, 1e-9);
  // Link lost (may_follow false), though the gaze watchdog has not expired:
  // home at the rate limit, 60 deg at 90 deg/s = 0.667 s.
  hr::head_control_step(p, s, T_W_R, false, false, t += kDtNs, kDt);
  EXPECT_FALSE(s.following);
  for (int k = 0; k < 600; ++k) hr::head_control_step(p, s, T_W_R, false, false, t += kDtNs, kDt);
  EXPECT_NEAR(s.pan_sp, 60 * kDeg - p.max_rate * 0.601, 1e-9);
  for (int k = 0; k < 100; ++k) hr::head_control_step(p, s, T_W_R, false, false, t += kDtNs, kDt);
  EXPECT_EQ(s.pan_sp, p.home_pan);
  EXPECT_EQ(s.tilt_sp, p.home_tilt);
  // An inactive gaze also sends it home.
  hr::head_gaze_command(p, s, target, true, T_W_R, 4, t);
  for (int k = 0; k < 100; ++k) hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  EXPECT_GT(s.pan_sp, 0.1);
  hr::head_gaze_command(p, s, target, false, T_W_R, 5, t);
  for (int k = 0; k < 1000; ++k) hr::head_control_step(p, s, T_W_R, true, false, t += kDtNs, kDt);
  EXPECT_EQ(s.pan_sp, p.home_pan);
}

TEST(HeadControl, KeepsLookingAtAWorldPointWhileTheBaseTurns) {
  const hr::HeadParams p = params();
  hr::HeadControlState s = hr::head_control_init(p);
  const Eigen::Isometry3d T0 = pose_W_R(0, 0, 0);
  const Eigen::Vector3d target_W = T0 * point_at(p, 20 * kDeg, 30 * kDeg, 1.4);
  std::int64_t t = 0;
  hr::head_gaze_command(p, s, target_W, true, T0, 1, t);
  const Eigen::Isometry3d T1 = pose_W_R(0, 0, 25 * kDeg);  // the base turned left: the head pans right
  for (int k = 0; k < 1000; ++k) {
    if (k % 100 == 99) hr::head_gaze_command(p, s, target_W, true, T1, 2, t);  // the operator keeps sending it
    hr::head_control_step(p, s, T1, true, false, t += kDtNs, kDt);
  }
  const hr::HeadAim want = hr::aim_head(p, T1.inverse() * target_W);
  EXPECT_NEAR(s.pan_sp, want.pan, 1e-9);
  EXPECT_NEAR(s.tilt_sp, want.tilt, 1e-9);
  EXPECT_LT(s.pan_sp, 0.0);
}

TEST(SimPanTiltHead, EncodersReadBiasPlusNoise) {
  hr::SimPanTiltHead h;
  h.params.pan_bias = 0.004;
  h.params.tilt_bias = -0.003;
  h.params.encoder_sigma = 0.001;
  h.pan = 0.3;
  h.tilt = 0.6;
  std::mt19937_64 rng(5);
  Eigen::Vector2d sum = Eigen::Vector2d::Zero(), sq = Eigen::Vector2d::Zero();
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d e = h.read_encoders(rng) - Eigen::Vector2d(h.pan, h.tilt);
    sum += e;
    sq += e.cwiseProduct(e);
  }
  const Eigen::Vector2d mean = sum / n;
  EXPECT_NEAR(mean.x(), 0.004, 4 * 0.001 / std::sqrt(n));
  EXPECT_NEAR(mean.y(), -0.003, 4 * 0.001 / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(sq.x() / n - mean.x() * mean.x()), 0.001, 0.00005);
}
