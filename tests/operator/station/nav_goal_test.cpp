// The SIMULATED "nav-to-goal" operator: the pure controller
// (hand_target_for_goal: direction in H, dead band, tolerance, hysteresis,
// bounds, degenerate input), the NavGoalHand (rate limit, route), and the
// closed loop through the real OperatorServoTask, SimulatedOmni and
// ModelThread prediction over a simulated unicycle robot whose commands and
// states are delayed (0 and 500 ms one way, the prediction told the same
// delay): the robot reaches the goal within the tolerance, stops there, and
// its footprint stays clear of home.xml's bin, walls and sofa. Also the
// station summary's JSON. Simulated time only: nothing sleeps.
#include <google/protobuf/util/json_util.h>
#include <gtest/gtest.h>
#include <numbers>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <random>
#include <string>
#include <vector>

#include "operator/device/simulated_omni.h"
#include "operator/model/model_thread.h"
#include "operator/station/demo_scripts.h"
#include "operator/station/operator_station.h"
#include "report.pb.h"

namespace ho = hemm::op;
namespace hm = hemm::math;
namespace hd = hemm::device;
namespace hs = hemm::servo;

namespace {

ho::OperatorView view_at(double x, double y, double theta) {
  ho::OperatorView v;
  v.T_W_R = {x, y, theta};
  v.mode = hm::Mode::kNavigation;
  v.valid = true;
  return v;
}

// The command the station derives from a stylus held at p_H (free space: the
// proxy sits on the stylus), computed with the station's own map.
hm::BaseCommand command_for(const ho::NavGoalParams& p, const Eigen::Vector3d& p_H) {
  return hm::navigation_command(p.nav, ho::R_B_H() * p_H);
}

// ---------------------------------------------------------------- controller

TEST(HandTarget, GoalAheadPushesForwardWithTheSpeedProportionalToDistance) {
  const ho::NavGoalParams p;
  for (double d : {0.06, 0.3, 0.5, 0.6, 2.0}) {
    const ho::NavHandTarget t = ho::hand_target_for_goal(view_at(0, 0, 0), {d, 0}, p);
    EXPECT_FALSE(t.arrived);
    EXPECT_NEAR(t.distance, d, 1e-12);
    EXPECT_LT(t.position_H.z(), -p.nav.dead_band);  // forward = -z_H, past the dead band
    EXPECT_EQ(t.position_H.x(), 0.0);
    EXPECT_EQ(t.position_H.y(), 0.0);
    const hm::BaseCommand c = command_for(p, t.position_H);
    EXPECT_NEAR(c.v, std::clamp(p.k_distance * d, p.v_min, p.v_cruise), 1e-9) << "d = " << d;
    EXPECT_EQ(c.omega, 0.0);
  }
}

TEST(HandTarget, GoalLeftOrRightTurnsTheRightWayFirst) {
  const ho::NavGoalParams p;
  // Left (+y in W for a robot heading +x): counter-clockwise, stylus to the left (-x_H).
  ho::NavHandTarget t = ho::hand_target_for_goal(view_at(0, 0, 0), {0, 2}, p);
  EXPECT_LT(t.position_H.x(), -p.nav.dead_band);
  EXPECT_NEAR(t.heading_error, std::numbers::pi / 2, 1e-12);
  hm::BaseCommand c = command_for(p, t.position_H);
  EXPECT_NEAR(c.omega, p.omega_cruise, 1e-9);  // k * pi/2 > cruise: capped
  EXPECT_EQ(c.v, 0.0);                         // 90 deg > turn_in_place: no forward push
  // Right.
  t = ho::hand_target_for_goal(view_at(0, 0, 0), {0, -2}, p);
  EXPECT_GT(t.position_H.x(), p.nav.dead_band);
  c = command_for(p, t.position_H);
  EXPECT_NEAR(c.omega, -p.omega_cruise, 1e-9);
  EXPECT_EQ(c.v, 0.0);
  // Small heading error: both, forward cut by (1 - |e| / turn_in_place), turn k * e.
  const double e = 0.3;
  t = ho::hand_target_for_goal(view_at(0, 0, 0), {2 * std::cos(e), 2 * std::sin(e)}, p);
  c = command_for(p, t.position_H);
  EXPECT_NEAR(c.omega, p.k_heading * e, 1e-9);
  EXPECT_NEAR(c.v, p.v_cruise * (1.0 - e / p.turn_in_place), 1e-9);
}

TEST(HandTarget, FramesFollowTheRobotsHeading) {
  const ho::NavGoalParams p;
  // Robot at (1, 1) heading +y: a goal at (1, 3) is straight ahead, (3, 1) is to its right.
  ho::NavHandTarget t = ho::hand_target_for_goal(view_at(1, 1, std::numbers::pi / 2), {1, 3}, p);
  hm::BaseCommand c = command_for(p, t.position_H);
  EXPECT_NEAR(c.v, p.v_cruise, 1e-9);
  EXPECT_NEAR(c.omega, 0.0, 1e-9);
  t = ho::hand_target_for_goal(view_at(1, 1, std::numbers::pi / 2), {3, 1}, p);
  c = command_for(p, t.position_H);
  EXPECT_LT(c.omega, 0.0);
  // Heading wraps: theta = 3 pi and theta = pi are the same robot.
  const ho::NavHandTarget a = ho::hand_target_for_goal(view_at(0, 0, 3 * std::numbers::pi), {-1, 0.5}, p);
  const ho::NavHandTarget b = ho::hand_target_for_goal(view_at(0, 0, std::numbers::pi), {-1, 0.5}, p);
  EXPECT_TRUE(a.position_H.isApprox(b.position_H, 1e-9));
}

TEST(HandTarget, GoalBehindTurnsRoundWhenFarAndBacksUpWhenClose) {
  const ho::NavGoalParams p;
  ho::NavHandTarget t = ho::hand_target_for_goal(view_at(0, 0, 0), {-2, 0.01}, p);
  hm::BaseCommand c = command_for(p, t.position_H);
  EXPECT_EQ(c.v, 0.0);
  EXPECT_NEAR(std::abs(c.omega), p.omega_cruise, 1e-9);
  t = ho::hand_target_for_goal(view_at(0, 0, 0), {-0.3, 0}, p);
  c = command_for(p, t.position_H);
  EXPECT_GT(t.position_H.z(), p.nav.dead_band);  // stylus pulled back (+z_H)
  EXPECT_NEAR(c.v, -p.k_distance * 0.3, 1e-9);
  EXPECT_NEAR(c.omega, 0.0, 1e-9);
  // An intermediate goal is never reached backwards.
  t = ho::hand_target_for_goal(view_at(0, 0, 0), {-0.3, 0.01}, p, /*final_goal=*/false);
  c = command_for(p, t.position_H);
  EXPECT_EQ(c.v, 0.0);
  EXPECT_NE(c.omega, 0.0);
}

TEST(HandTarget, CentredWithinTheToleranceWithHysteresis) {
  const ho::NavGoalParams p;
  for (double d : {0.0, 0.03, 0.049}) {
    for (double dir : {0.0, 1.0, 2.5, -2.0}) {
      const ho::NavHandTarget t =
          ho::hand_target_for_goal(view_at(1, -1, 0.7), {1 + d * std::cos(dir), -1 + d * std::sin(dir)}, p);
      EXPECT_TRUE(t.arrived);
      EXPECT_EQ(t.position_H, Eigen::Vector3d::Zero());
    }
  }
  // Between stop_distance and tolerance: stays centred once arrived, drives if not yet there.
  const double d = 0.5 * (p.stop_distance + p.tolerance);
  EXPECT_TRUE(ho::hand_target_for_goal(view_at(0, 0, 0), {d, 0}, p, true, true).arrived);
  const ho::NavHandTarget t = ho::hand_target_for_goal(view_at(0, 0, 0), {d, 0}, p, true, false);
  EXPECT_FALSE(t.arrived);
  EXPECT_NEAR(command_for(p, t.position_H).v, p.v_min, 1e-9);
  // Beyond the tolerance: drives again (corrects a drift).
  EXPECT_FALSE(ho::hand_target_for_goal(view_at(0, 0, 0), {p.tolerance + 0.01, 0}, p, true, true).arrived);
  // An intermediate goal is never "arrived".
  EXPECT_FALSE(ho::hand_target_for_goal(view_at(0, 0, 0), {0.01, 0}, p, false, false).arrived);
}

TEST(HandTarget, StaysInsideTheDeviceWorkspace) {
  ho::NavGoalParams p;
  p.v_cruise = 5.0;  // ask for more than the map gives: the offsets clamp
  p.omega_cruise = 5.0;
  const hd::EndEffectorLimits lim = hd::phantom_omni_limits().ee[0];
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  for (int i = 0; i < 2000; ++i) {
    const ho::NavHandTarget t = ho::hand_target_for_goal(view_at(u(rng), u(rng), u(rng)), {u(rng), u(rng)}, p);
    ASSERT_TRUE(t.position_H.allFinite());
    EXPECT_LE(t.position_H.cwiseAbs().maxCoeff(), p.max_offset + 1e-15);
    EXPECT_EQ(t.position_H.y(), 0.0);
    EXPECT_TRUE(lim.contains(t.position_H));
  }
}

TEST(HandTarget, DegenerateInputCentresTheStylus) {
  const ho::NavGoalParams p;
  const double nan = std::nan(""), inf = INFINITY;
  ho::OperatorView invalid = view_at(0, 0, 0);
  invalid.valid = false;
  ho::OperatorView exploring = view_at(0, 0, 0);
  exploring.mode = hm::Mode::kExploration;
  const std::vector<std::pair<ho::OperatorView, Eigen::Vector2d>> cases = {
      {invalid, {2, 0}},        {exploring, {2, 0}},         {view_at(nan, 0, 0), {2, 0}},
      {view_at(0, 0, inf), {2, 0}}, {view_at(0, 0, 0), {nan, 0}}, {view_at(0, 0, 0), {0, -inf}},
  };
  for (const auto& [v, g] : cases) {
    const ho::NavHandTarget t = ho::hand_target_for_goal(v, g, p);
    EXPECT_EQ(t.position_H, Eigen::Vector3d::Zero());
    EXPECT_FALSE(t.arrived);
    EXPECT_EQ(t.distance, -1.0);
  }
  // On the goal exactly (atan2(0, 0)): arrived, centred, finite.
  const ho::NavHandTarget t = ho::hand_target_for_goal(view_at(1, 2, 0.3), {1, 2}, p);
  EXPECT_TRUE(t.arrived);
  EXPECT_EQ(t.position_H, Eigen::Vector3d::Zero());
}

TEST(NavGoalParams, Validation) {
  EXPECT_EQ(ho::validate(ho::NavGoalParams{}), "");
  ho::NavGoalParams p;
  p.tolerance = 0.04;  // below stop_distance
  EXPECT_NE(ho::validate(p), "");
  p = {};
  p.hand_speed = std::nan("");
  EXPECT_NE(ho::validate(p), "");
  auto view = std::make_shared<ho::OperatorView>();
  EXPECT_THROW(ho::NavGoalHand(view, {}), std::invalid_argument);
  EXPECT_THROW(ho::NavGoalHand(view, {{1.0, std::nan("")}}), std::invalid_argument);
  EXPECT_THROW(ho::NavGoalHand(nullptr, {{1.0, 0.0}}), std::invalid_argument);
  EXPECT_THROW(ho::NavGoalHand(view, {{1.0, 0.0}}, p), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("nav-to-goal", {{{INFINITY, 0.0}}, {}}), std::invalid_argument);
  // Targets from the command line: a probe line is two finite points that
  // the SIMULATED Omni reaches at the exploration scale (50: its 35 mm
  // depth is 1.75 m ahead, its 80 mm half width 4 m aside), for
  // probe-cylinder only; nav-to-wall takes one goal.
  EXPECT_TRUE(ho::make_demo_script("probe-cylinder", {{}, {{1.42, 0.15}, {1.42, 0.85}}}).hand);
  EXPECT_TRUE(ho::make_demo_script("probe-cylinder", {{}, {{1.74, 3.9}, {-1.74, -3.9}}}).hand);
  try {
    ho::make_demo_script("probe-cylinder", {{}, {{2.52, -0.1}, {2.52, -0.9}}});
    ADD_FAILURE() << "a line 2.52 m ahead is out of reach";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("(2.52, -0.10) is beyond what exploration reaches"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("1.75 m ahead or behind, 4.00 m to either side"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(ho::make_demo_script("probe-cylinder", {{}, {{1.0, 4.1}, {1.0, 0.0}}}), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("probe-cylinder", {{}, {{1.42, -0.1}}}), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("probe-cylinder", {{}, {{5.0, 0.0}, {1.0, 0.0}}}), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("probe-cylinder", {{}, {{NAN, 0.0}, {1.0, 0.0}}}), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("nav-to-goal", {{}, {{1.0, 0.0}, {1.0, 1.0}}}), std::invalid_argument);
  EXPECT_TRUE(ho::make_demo_script("nav-to-wall", {{{2.0, -1.6}}, {}}).hand);
  EXPECT_THROW(ho::make_demo_script("nav-to-wall", {{{2.0, -1.6}, {3.0, 0.0}}, {}}), std::invalid_argument);
  EXPECT_THROW(ho::make_demo_script("idle", {{{2.0, -1.6}}, {}}), std::invalid_argument);
}

// ---------------------------------------------------------------- the hand

// Issue 23: the closed-loop hand holds the stylus's dead-man pressed; when
// its display shows the robot waiting to be re-armed it lets go for
// rearm_release_s and presses again, at most once per rearm_retry_s.
TEST(NavGoalHand, PressesTheDeadManAndLetsGoBrieflyWhenTheRobotWaitsToBeReArmed) {
  auto view = std::make_shared<ho::OperatorView>();
  ho::NavGoalParams p;
  ho::NavGoalHand hand(view, {{1.0, 0.0}}, p);
  *view = view_at(0, 0, 0);
  EXPECT_TRUE(hand.at(0.5).deadman);
  view->robot_safety = hemm::wire::SAFETY_REARM;
  std::vector<double> released;
  for (int i = 0; i <= 2500; ++i) {
    const double t = 1.0 + i * 0.001;
    if (!hand.at(t).deadman) released.push_back(t);
  }
  // Let go at 1.0 s and 2.0 s (not in between), each time for 0.2 s.
  ASSERT_FALSE(released.empty());
  EXPECT_NEAR(released.front(), 1.0, 1e-9);
  const auto second = std::find_if(released.begin(), released.end(), [](double t) { return t > 1.5; });
  ASSERT_NE(second, released.end());
  EXPECT_NEAR(*second, 2.0, 0.0015);
  EXPECT_NEAR(static_cast<double>(released.size()) * 0.001, 3 * p.rearm_release_s, 0.004);  // 1.0, 2.0 and 3.0 s
  view->robot_safety = 0;  // re-armed: held pressed
  for (int i = 1; i <= 1500; ++i) EXPECT_TRUE(hand.at(3.5 + i * 0.001).deadman);
  p.rearm_retry_s = p.rearm_release_s;
  EXPECT_FALSE(ho::validate(p).empty());
}

TEST(NavGoalHand, MovesTheStylusAtBoundedSpeedAndFollowsTheRoute) {
  auto view = std::make_shared<ho::OperatorView>();
  ho::NavGoalParams p;
  ho::NavGoalHand hand(view, {{1.0, 0.0}, {1.0, -2.0}}, p);
  // No view yet: centre.
  EXPECT_EQ(hand.at(0.0).position_H, Eigen::Vector3d::Zero());
  *view = view_at(0, 0, 0);
  const double dt = 0.001;
  Eigen::Vector3d prev = Eigen::Vector3d::Zero();
  double max_step = 0.0;
  for (int i = 1; i <= 2000; ++i) {
    const Eigen::Vector3d x = hand.at(i * dt).position_H;
    max_step = std::max(max_step, (x - prev).norm());
    prev = x;
  }
  EXPECT_LE(max_step, p.hand_speed * dt * (1 + 1e-9));
  EXPECT_GT(max_step, 0.9 * p.hand_speed * dt);  // it did move at the limit
  // Settled on the controller's wish for the first goal (1 m ahead: cruise, no turn).
  const ho::NavHandTarget want = ho::hand_target_for_goal(*view, {1.0, 0.0}, p, false);
  EXPECT_TRUE(prev.isApprox(want.position_H, 1e-12));
  EXPECT_EQ(hand.goal_index(), 0u);
  // Inside the pass radius of the first goal: on to the second (to the right, behind the turn limit).
  *view = view_at(0.8, 0.0, 0.0);
  hand.at(2.001);
  EXPECT_EQ(hand.goal_index(), 1u);
  for (int i = 2; i <= 2000; ++i) prev = hand.at(2.0 + i * dt).position_H;
  EXPECT_LT(command_for(p, prev).omega, 0.0);
  EXPECT_FALSE(hand.arrived());
  // At the last goal: arrived, stylus back to the centre, first arrival time kept.
  *view = view_at(1.0, -1.97, -std::numbers::pi / 2);
  for (int i = 1; i <= 2000; ++i) prev = hand.at(4.0 + i * dt).position_H;
  EXPECT_TRUE(hand.arrived());
  EXPECT_EQ(prev, Eigen::Vector3d::Zero());
  EXPECT_NEAR(hand.first_arrival_s(), 4.001, 1e-9);
  EXPECT_EQ(hand.arrivals(), 1u);
  // Drifts away beyond the tolerance: drives again; back: a second arrival.
  *view = view_at(1.0, -1.6, -std::numbers::pi / 2);
  hand.at(6.001);
  EXPECT_FALSE(hand.arrived());
  *view = view_at(1.0, -2.0, -std::numbers::pi / 2);
  hand.at(6.002);
  EXPECT_TRUE(hand.arrived());
  EXPECT_EQ(hand.arrivals(), 2u);
  EXPECT_NEAR(hand.first_arrival_s(), 4.001, 1e-9);
}

// Issue 9 item 8: the hand's route progress follows the robot, not a model
// that went stale: it never advances while the view is invalid, and when the
// robot restarted (view.resyncs) the route starts again from where the new
// robot is.
TEST(NavGoalHand, RouteProgressIsResynchronisedFromTheRestartedRobot) {
  auto view = std::make_shared<ho::OperatorView>();
  ho::NavGoalParams p;
  ho::NavGoalHand hand(view, {{1.2, 0.0}, {1.0, -0.7}}, p);
  *view = view_at(0.6, 0.0, 0.0);
  hand.at(0.001);
  EXPECT_EQ(hand.goal_index(), 0u);
  // The model went stale: its extrapolated pose passes the first goal, but
  // the view is invalid: no progress, stylus to the centre.
  *view = view_at(1.2, 0.0, 0.0);
  view->valid = false;
  for (int i = 2; i <= 1000; ++i) hand.at(i * 0.001);
  EXPECT_EQ(hand.goal_index(), 0u);
  EXPECT_TRUE(hand.at(1.001).position_H.isZero(1e-12));
  // The old robot had passed it before it died...
  *view = view_at(1.1, 0.0, 0.0);
  hand.at(1.002);
  EXPECT_EQ(hand.goal_index(), 1u);
  // ... and the restarted robot stands at the start of the route: back to the first goal.
  *view = view_at(0.0, 0.0, 0.0);
  view->resyncs = 1;
  hand.at(1.003);
  EXPECT_EQ(hand.goal_index(), 0u);
  EXPECT_FALSE(hand.arrived());
}

// ---------------------------------------------------------------- closed loop

// home.xml's obstacles near the route, as the 2D footprints the base must not
// touch: the bin (circle), wall_mid_s (x >= 2.95, y <= -0.5), the sofa
// (x in [0, 2], y <= -2.1), the south wall (y <= -2.95).
// Distance from a point to the footprint (0 inside).
double footprint_distance(const hm::Pose2& T_W_R, const Eigen::Vector2d& q_W) {
  const Eigen::Vector2d q = hm::rotation2(T_W_R.theta).transpose() * (q_W - Eigen::Vector2d(T_W_R.x, T_W_R.y));
  return (q.cwiseAbs() - Eigen::Vector2d(0.245, 0.25)).cwiseMax(0.0).norm();
}
double footprint_max_x(const hm::Pose2& T_W_R) {
  return T_W_R.x + 0.245 * std::abs(std::cos(T_W_R.theta)) + 0.25 * std::abs(std::sin(T_W_R.theta));
}

bool footprint_collides(const hm::Pose2& T_W_R) {
  constexpr double hx = 0.245, hy = 0.25;  // 490 D x 500 W mm
  const double c = std::cos(T_W_R.theta), s = std::sin(T_W_R.theta);
  for (double a = -hx; a <= hx + 1e-9; a += 0.01) {
    for (double b : {-hy, hy}) {
      for (int swap = 0; swap < 2; ++swap) {
        const double xr = swap ? b * hx / hy : a, yr = swap ? a * hy / hx : b;
        const double x = T_W_R.x + c * xr - s * yr, y = T_W_R.y + s * xr + c * yr;
        if (std::hypot(x - 1.5, y + 1.2) < 0.15) return true;
        if (x >= 2.95 && y <= -0.5) return true;
        if (x >= 0.0 && x <= 2.0 && y <= -2.1) return true;
        if (y <= -2.95) return true;
      }
    }
  }
  return false;
}

struct LoopResult {
  double first_arrival_s = -1;
  bool arrived_at_end = false;
  hm::Pose2 truth;           // the robot at the end
  hm::Pose2 predicted;       // what the station showed at the end
  double final_distance = 0;  // truth to goal
  double moved_last_5s = 0;  // truth path length over the last 5 s
  double max_prediction_error = 0;  // after the first state arrived
  bool collided = false;
  double bin_clearance = 1e9;   // m, footprint to the bin's surface
  double wall_clearance = 1e9;  // m, footprint to wall_mid_s (x = 2.95) while beside it (y < -0.25)
  std::uint64_t arrivals = 0;
};

// The station's servo side with a unicycle robot. Commands (200 Hz, as the
// CommandSender) reach the robot after delay_ns; states (200 Hz) come back
// after delay_ns; the model (50 Hz) predicts with command delay = delay_ns.
LoopResult run_closed_loop(std::int64_t delay_ns, const std::vector<Eigen::Vector2d>& route, double duration_s) {
  hs::ModelChannel channel;
  ho::ModelThread model(channel, ho::ModelThreadParams{});
  model.set_command_delay(delay_ns);
  ho::DemoScript script = ho::make_demo_script("nav-to-goal", {route, {}});
  EXPECT_TRUE(script.hand && script.view && script.nav_goal);
  ho::OperatorTaskParams tp;
  tp.initial_mode = script.mode;
  ho::OperatorServoTask task(tp, nullptr, script.view.get());
  hd::SimulatedOmni omni(hd::SimulatedOmniModel{}, script.hand);

  hm::Pose2 truth;  // robot_start (0, 0, 0)
  double v = 0, omega = 0;
  struct Cmd { std::int64_t at; double v, omega; };
  struct State { std::int64_t at; hemm::wire::RobotState m; };
  std::deque<Cmd> to_robot;
  std::deque<State> to_operator;
  std::vector<hm::Pose2> path;

  LoopResult r;
  const std::int64_t t0 = 1'000'000'000, ms = 1'000'000;
  const int ticks = static_cast<int>(duration_s * 1000);
  for (int k = 0; k < ticks; ++k) {
    const std::int64_t t = t0 + k * ms;
    // Robot: apply the commands that arrived, move 1 ms, report every 5 ms.
    while (!to_robot.empty() && to_robot.front().at <= t) {
      v = to_robot.front().v;
      omega = to_robot.front().omega;
      to_robot.pop_front();
    }
    truth = ho::integrate_unicycle(truth, v, omega, 1e-3);
    path.push_back(truth);
    if (k % 5 == 0) {
      State s{t + delay_ns, {}};
      s.m.set_stamp_ns(t);
      s.m.mutable_t_w_r_odom()->set_x(truth.x);
      s.m.mutable_t_w_r_odom()->set_y(truth.y);
      s.m.mutable_t_w_r_odom()->set_theta(truth.theta);
      s.m.set_v(v);
      s.m.set_omega(omega);
      to_operator.push_back(std::move(s));
    }
    while (!to_operator.empty() && to_operator.front().at <= t) {
      model.submit_state(to_operator.front().m);
      to_operator.pop_front();
    }
    if (k % 20 == 0) model.step(t);
    // Servo tick: device -> task -> device (the hand looks at the view here).
    hd::DeviceSample in;
    omni.read(in);
    in.t_ns = t;
    const hs::ModelSnapshot* snap = channel.acquire();
    hs::ModelSnapshot empty;
    hs::TickOutput out;
    task.tick(in, snap != nullptr ? *snap : empty, out);
    omni.write(out.command);
    if (script.view->valid) {
      const hm::Pose2& p = script.view->T_W_R;
      r.max_prediction_error = std::max(r.max_prediction_error, std::hypot(p.x - truth.x, p.y - truth.y));
    }
    // Command sender: the newest setpoint, recorded for the prediction.
    if (k % 5 == 0) {
      const ho::StationSetpoint& sp = task.last_setpoint();
      const double cv = sp.moves_robot ? sp.v : 0.0, cw = sp.moves_robot ? sp.omega : 0.0;
      model.record_command({t, cv, cw});
      to_robot.push_back({t + delay_ns, cv, cw});
    }
    r.collided = r.collided || footprint_collides(truth);
    r.bin_clearance = std::min(r.bin_clearance, footprint_distance(truth, {1.5, -1.2}) - 0.15);
    if (truth.y < -0.25) r.wall_clearance = std::min(r.wall_clearance, 2.95 - footprint_max_x(truth));
  }
  const auto& hand = *script.nav_goal;
  r.first_arrival_s = hand.first_arrival_s();
  r.arrived_at_end = hand.arrived();
  r.arrivals = hand.arrivals();
  r.truth = truth;
  r.predicted = script.view->T_W_R;
  r.final_distance = (route.back() - Eigen::Vector2d(truth.x, truth.y)).norm();
  for (std::size_t i = path.size() - 5000; i + 1 < path.size(); ++i)
    r.moved_last_5s += std::hypot(path[i + 1].x - path[i].x, path[i + 1].y - path[i].y);
  return r;
}

class ClosedLoop : public ::testing::TestWithParam<int> {};

TEST_P(ClosedLoop, DefaultRouteReachesTheGoalStopsAndStaysClear) {
  const std::int64_t delay_ns = std::int64_t{GetParam()} * 1'000'000;
  const ho::NavGoalParams p;
  const auto route = ho::default_nav_goal_route();
  const LoopResult r = run_closed_loop(delay_ns, route, 25.0);
  std::printf("delay %d ms: first arrival %.2f s, arrivals %llu, final (%.3f, %.3f, %.3f), distance to goal %.3f m, "
              "predicted (%.3f, %.3f), max prediction error %.4f m, moved in the last 5 s %.4f m, clearance to "
              "bin %.3f m, to wall_mid_s %.3f m\n",
              GetParam(), r.first_arrival_s, static_cast<unsigned long long>(r.arrivals), r.truth.x, r.truth.y,
              r.truth.theta, r.final_distance, r.predicted.x, r.predicted.y, r.max_prediction_error,
              r.moved_last_5s, r.bin_clearance, r.wall_clearance);
  EXPECT_GT(r.first_arrival_s, 0.0);
  EXPECT_LT(r.first_arrival_s, 20.0);
  EXPECT_TRUE(r.arrived_at_end);
  EXPECT_LT(r.final_distance, p.tolerance);
  EXPECT_LT(r.moved_last_5s, 1e-9);  // stopped: the stylus is inside the dead band
  EXPECT_FALSE(r.collided);
  EXPECT_GT(r.bin_clearance, 0.1);
  EXPECT_GT(r.wall_clearance, 0.1);
  // Same delay on both sides and no noise: the station showed the true pose.
  EXPECT_LT(r.max_prediction_error, 0.02);
}

TEST_P(ClosedLoop, GoalsInEveryDirectionAreReached) {
  const std::int64_t delay_ns = std::int64_t{GetParam()} * 1'000'000;
  const ho::NavGoalParams p;
  for (const Eigen::Vector2d& g : {Eigen::Vector2d(1.5, 0.8), Eigen::Vector2d(-1.0, -0.5), Eigen::Vector2d(0.0, -1.2),
                                  Eigen::Vector2d(-0.3, 0.0)}) {
    const LoopResult r = run_closed_loop(delay_ns, {g}, 20.0);
    std::printf("delay %d ms, goal (%.2f, %.2f): first arrival %.2f s, final distance %.3f m\n", GetParam(), g.x(),
                g.y(), r.first_arrival_s, r.final_distance);
    EXPECT_TRUE(r.arrived_at_end) << g.transpose();
    EXPECT_LT(r.final_distance, p.tolerance) << g.transpose();
    EXPECT_LT(r.moved_last_5s, 1e-9) << g.transpose();
  }
}

INSTANTIATE_TEST_SUITE_P(OneWayDelayMs, ClosedLoop, ::testing::Values(0, 500));

// ---------------------------------------------------------------- JSON

// The summary is printed by protobuf's JSON support (report.proto): it
// parses back, with protobuf's own parser, into the same numbers.
TEST(StationJson, HasEveryKeyAndTheNumbersParseBack) {
  ho::OperatorStationSummary s;
  s.timing.ticks = 25001;
  s.timing.misses = 3;
  s.timing.overruns = 1;
  s.timing.late_wakes = 2;
  s.timing.skipped_periods = 4;
  s.timing.period = {25000, 1000.5, 1012.5, 2345.5, 1000.01};
  s.timing.wake_latency = {25000, 50.5, 120.5, 900.5, 55.25};
  s.timing.compute = {25001, 8.5, 20.5, 77.5, 9.125};
  s.model.scans_in = 11;
  s.model.states_in = 12;
  s.model.resyncs = 1;
  s.commands.commands_sent = 5000;
  s.commands.stale = 7;
  s.mode_switches = 2;
  s.robot_estop = 1;
  s.servo_log_written = 100;
  s.world_log_dropped = 9;
  s.robot_pose = {2.4, -1.55, -1.25};
  s.robot_pose_valid = true;
  s.has_goal = true;
  s.goal_W = {2.45, -1.6};
  s.arrived = true;
  s.first_arrival_s = 12.25;
  s.arrivals = 1;
  s.goal_index = 1;
  s.route_size = 2;
  s.goal_distance_m = std::hypot(0.05, 0.05);

  const std::string text = ho::to_json(s);
  for (const char* k : {"\"timing\"", "\"period_us\"", "\"wake_latency_us\"", "\"compute_us\"", "\"median\"",
                        "\"p99\"", "\"model\"", "\"scans_rejected\"", "\"commands\"", "\"mode_switches\"",
                        "\"estop\"", "\"logs\"", "\"robot_pose\"", "\"x_m\"", "\"nav_goal\"", "\"goal_distance_m\""})
    EXPECT_NE(text.find(k), std::string::npos) << k << " in " << text;
  hemm::report::OperatorStation r;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(text, &r).ok()) << text;
  EXPECT_EQ(r.timing().ticks(), 25001u);
  EXPECT_EQ(r.timing().misses(), 3u);
  EXPECT_EQ(r.timing().overruns(), 1u);
  EXPECT_EQ(r.timing().late_wakes(), 2u);
  EXPECT_EQ(r.timing().skipped_periods(), 4u);
  EXPECT_EQ(r.timing().period_us().count(), 25000u);
  EXPECT_EQ(r.timing().period_us().median(), 1000.5);
  EXPECT_EQ(r.timing().period_us().p99(), 1012.5);
  EXPECT_EQ(r.timing().period_us().max(), 2345.5);
  EXPECT_EQ(r.timing().period_us().mean(), 1000.01);
  EXPECT_EQ(r.timing().wake_latency_us().median(), 50.5);
  EXPECT_EQ(r.timing().wake_latency_us().p99(), 120.5);
  EXPECT_EQ(r.timing().compute_us().max(), 77.5);
  EXPECT_EQ(r.model().scans_in(), 11u);
  EXPECT_EQ(r.model().states_in(), 12u);
  EXPECT_EQ(r.model().resyncs(), 1u);
  EXPECT_EQ(r.model().scans_rejected(), 0u);
  EXPECT_EQ(r.commands().sent(), 5000u);
  EXPECT_EQ(r.commands().stale(), 7u);
  EXPECT_EQ(r.mode_switches(), 2u);
  ASSERT_TRUE(r.estop().has_robot_engaged());
  EXPECT_TRUE(r.estop().robot_engaged());
  EXPECT_EQ(r.logs().servo_written(), 100u);
  EXPECT_EQ(r.logs().world_dropped(), 9u);
  EXPECT_TRUE(r.robot_pose().valid());
  EXPECT_EQ(r.robot_pose().x_m(), 2.4);
  EXPECT_EQ(r.robot_pose().y_m(), -1.55);
  EXPECT_EQ(r.robot_pose().theta_rad(), -1.25);
  ASSERT_TRUE(r.has_nav_goal());
  EXPECT_EQ(r.nav_goal().goal_x_m(), 2.45);
  EXPECT_EQ(r.nav_goal().goal_y_m(), -1.6);
  EXPECT_TRUE(r.nav_goal().arrived());
  EXPECT_EQ(r.nav_goal().first_arrival_s(), 12.25);
  EXPECT_EQ(r.nav_goal().arrivals(), 1u);
  EXPECT_EQ(r.nav_goal().goal_index(), 1u);
  EXPECT_EQ(r.nav_goal().route_size(), 2u);
  EXPECT_EQ(r.nav_goal().goal_distance_m(), std::hypot(0.05, 0.05));

  // No goal, no pose, the robot's e-stop never reported, a non-finite
  // number: absent / NaN, still valid JSON that parses back.
  ho::OperatorStationSummary e;
  e.timing.period.mean_us = std::nan("");
  const std::string text2 = ho::to_json(e);
  hemm::report::OperatorStation r2;
  ASSERT_TRUE(google::protobuf::util::JsonStringToMessage(text2, &r2).ok()) << text2;
  EXPECT_FALSE(r2.has_nav_goal());
  EXPECT_EQ(text2.find("\"nav_goal\""), std::string::npos) << text2;
  EXPECT_FALSE(r2.robot_pose().valid());
  EXPECT_NE(text2.find("\"valid\": false"), std::string::npos) << text2;  // zeros are printed
  EXPECT_FALSE(r2.estop().has_robot_engaged());
  EXPECT_TRUE(std::isnan(r2.timing().period_us().mean()));
}

}  // namespace
