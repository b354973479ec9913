// Pose prediction: exact unicycle arcs, and prediction under a synthetic link
// delay against a simulated unicycle's truth.
#include <gtest/gtest.h>
#include <numbers>

#include <cmath>
#include <cstdio>
#include <deque>
#include <optional>

#include "operator/model/pose_prediction.h"

namespace ho = hemm::op;
namespace hm = hemm::math;

namespace {

double pos_err(const hm::Pose2& a, const hm::Pose2& b) { return std::hypot(a.x - b.x, a.y - b.y); }

TEST(IntegrateUnicycle, ClosedForms) {
  // Straight line.
  hm::Pose2 p = ho::integrate_unicycle({1.0, 2.0, 0.5}, 0.4, 0.0, 2.5);
  EXPECT_NEAR(p.x, 1.0 + 1.0 * std::cos(0.5), 1e-12);
  EXPECT_NEAR(p.y, 2.0 + 1.0 * std::sin(0.5), 1e-12);
  EXPECT_NEAR(p.theta, 0.5, 1e-12);
  // Quarter circle of radius v / omega = 2 from the origin heading +x: ends at (2, 2) heading +y.
  p = ho::integrate_unicycle({0, 0, 0}, 1.0, 0.5, std::numbers::pi);
  EXPECT_NEAR(p.x, 2.0, 1e-12);
  EXPECT_NEAR(p.y, 2.0, 1e-12);
  EXPECT_NEAR(p.theta, std::numbers::pi / 2, 1e-12);
  // A full circle returns to the start; split into many steps it agrees too.
  hm::Pose2 q{0.3, -0.2, 1.0};
  for (int i = 0; i < 1000; ++i) q = ho::integrate_unicycle(q, 0.7, 0.35, 2 * std::numbers::pi / 0.35 / 1000);
  EXPECT_NEAR(q.x, 0.3, 1e-9);
  EXPECT_NEAR(q.y, -0.2, 1e-9);
  EXPECT_NEAR(hm::wrap_angle(q.theta - 1.0), 0.0, 1e-9);
  // Turning on the spot.
  p = ho::integrate_unicycle({1, 1, 0}, 0.0, 1.0, 1.0);
  EXPECT_NEAR(p.x, 1.0, 1e-12);
  EXPECT_NEAR(p.theta, 1.0, 1e-12);
}

TEST(CommandHistory, RingAndRejects) {
  ho::CommandHistory h(4);
  for (int i = 0; i < 6; ++i) EXPECT_TRUE(h.push({i * 10, double(i), 0.0}));
  ASSERT_EQ(h.size(), 4u);
  EXPECT_EQ(h[0].t_ns, 20);
  EXPECT_EQ(h[3].t_ns, 50);
  EXPECT_FALSE(h.push({40, 1.0, 0.0}));         // older than newest
  EXPECT_FALSE(h.push({60, std::nan(""), 0.0}));  // non-finite
  EXPECT_EQ(h.size(), 4u);
  EXPECT_EQ(h[3].t_ns, 50);
}

// The operator's command profile (v, omega) at local time t.
ho::SentCommand command_at(std::int64_t t_ns) {
  const double t = static_cast<double>(t_ns) * 1e-9;
  return {t_ns, 0.5 + 0.3 * std::sin(1.3 * t), 0.8 * std::sin(0.7 * t + 0.4)};
}

struct DelayResult {
  double predicted_err_max = 0.0;
  double stale_err_max = 0.0;  // error of just using the newest state's pose
};

// A unicycle robot (truth) follows the commands it receives after the forward
// delay d/2, through a first-order speed lag tau (tau = 0: ideal); it reports
// its pose at 200 Hz, arriving after the backward delay d/2. The operator
// predicts the present pose from the newest arrived state and its own
// command history, assuming the forward delay is RTT/2 = d/2.
DelayResult run_delay(std::int64_t rtt_ns, double tau_s) {
  const std::int64_t dt = 1'000'000;  // 1 ms truth integration
  const std::int64_t cmd_period = 5'000'000, state_period = 5'000'000;
  const std::int64_t fwd = rtt_ns / 2, back = rtt_ns - fwd;
  ho::CommandHistory hist(4096);
  std::deque<ho::SentCommand> in_flight;  // commands on their way to the robot
  struct State {
    std::int64_t stamp, arrive;
    hm::Pose2 pose;
    double v, omega;
  };
  std::deque<State> states;
  hm::Pose2 truth{0, 0, 0};
  double v = 0, w = 0, v_cmd = 0, w_cmd = 0;
  std::optional<State> newest;
  DelayResult r;
  for (std::int64_t t = 0; t <= 8'000'000'000; t += dt) {
    if (t % cmd_period == 0) {
      const ho::SentCommand c = command_at(t);
      hist.push(c);
      in_flight.push_back(c);
    }
    while (!in_flight.empty() && in_flight.front().t_ns + fwd <= t) {
      v_cmd = in_flight.front().v;
      w_cmd = in_flight.front().omega;
      in_flight.pop_front();
    }
    if (t % state_period == 0) states.push_back({t, t + back, truth, v, w});
    while (!states.empty() && states.front().arrive <= t) {
      newest = states.front();
      states.pop_front();
    }
    if (newest && t >= 3'000'000'000) {  // past the start-up transient
      const ho::PredictionInput in{newest->pose, newest->stamp, newest->v, newest->omega};
      const hm::Pose2 pred = ho::predict_pose(in, hist, fwd, t, 2.0);
      r.predicted_err_max = std::max(r.predicted_err_max, pos_err(pred, truth));
      r.stale_err_max = std::max(r.stale_err_max, pos_err(newest->pose, truth));
    }
    // Truth advances over [t, t + dt).
    const double a = tau_s > 0 ? 1.0 - std::exp(-1e-3 / tau_s) : 1.0;
    v += a * (v_cmd - v);
    w += a * (w_cmd - w);
    truth = ho::integrate_unicycle(truth, v, w, 1e-3);
  }
  return r;
}

TEST(PredictPose, IdealRobotIsExactUnderAnyDelay) {
  for (std::int64_t rtt_ms : {0, 100, 300}) {
    const DelayResult r = run_delay(rtt_ms * 1'000'000, 0.0);
    std::printf("ideal robot, rtt %3d ms: predicted max error %.3g m, stale %.3g m\n", int(rtt_ms),
                r.predicted_err_max, r.stale_err_max);
    EXPECT_LT(r.predicted_err_max, 1e-6) << "rtt " << rtt_ms << " ms";
    if (rtt_ms > 0) {
      EXPECT_GT(r.stale_err_max, 0.3 * 0.2 * rtt_ms / 1000.0) << "the delay must matter";
    }
  }
}

TEST(PredictPose, LaggingRobotErrorSmallAgainstStaleState) {
  // The robot's speed follows the command through a 50 ms lag the operator
  // does not model: the prediction error stays within ~v * tau, while the
  // stale pose is off by ~v * rtt.
  for (std::int64_t rtt_ms : {0, 100, 300}) {
    const DelayResult r = run_delay(rtt_ms * 1'000'000, 0.05);
    std::printf("lagging robot, rtt %3d ms: predicted max error %.3g m, stale %.3g m\n", int(rtt_ms),
                r.predicted_err_max, r.stale_err_max);
    EXPECT_LT(r.predicted_err_max, 0.04) << "rtt " << rtt_ms << " ms";
    if (rtt_ms >= 100) {
      EXPECT_LT(r.predicted_err_max, 0.5 * r.stale_err_max) << "rtt " << rtt_ms;
    }
  }
}

TEST(PredictPose, EdgeCases) {
  ho::CommandHistory h;
  const ho::PredictionInput in{{1, 2, 0.3}, 1'000'000'000, 0.5, 0.0};
  // now before the stamp: the state pose.
  hm::Pose2 p = ho::predict_pose(in, h, 0, 500'000'000);
  EXPECT_DOUBLE_EQ(p.x, 1.0);
  // No commands: the state's own speed for the elapsed time, capped by the horizon.
  p = ho::predict_pose(in, h, 0, 11'000'000'000, 2.0);
  EXPECT_NEAR(pos_err(p, {1, 2, 0.3}), 0.5 * 2.0, 1e-9);
  // A stop command acting before the stamp overrides the measured speed.
  h.push({0, 0.0, 0.0});
  p = ho::predict_pose(in, h, 0, 2'000'000'000);
  EXPECT_NEAR(pos_err(p, {1, 2, 0.3}), 0.0, 1e-12);
}

}  // namespace
