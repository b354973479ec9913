// Scan registration against the local map: a SIMULATED skid-steer robot whose
// odometry slips (heading scale and speed scale off, as on the real base)
// drives a route with four 90 deg turns round a ring corridor with columns,
// steering by its best pose estimate. Laser scans are cast against the exact
// scene from the TRUE pose and stamped with the odometry pose. Registration
// must keep the estimate within 0.1 m of the truth and bring the robot
// within 0.1 m of the true goal, where odometry alone does not.
#include "operator/model/scan_registration.h"

#include <cmath>
#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include "common/haptics/proxy/reference_scene.h"
#include "common/math/geometry2.h"
#include "tests/common/mapping/scan_synth.h"

namespace hemm::op {
namespace {

using Eigen::Vector2d;
using math::Pose2;

haptics::ExactScene ring_corridor() {
  haptics::ExactScene w;
  haptics::add_box(w, {-1.2, -1.2}, {7.2, 5.2});   // outer walls
  haptics::add_box(w, {1.0, 1.0}, {5.0, 3.0});     // the block the corridor goes round
  w.circles.push_back({{2.5, -0.7}, 0.12});         // columns of several radii along the way
  w.circles.push_back({{6.6, 2.0}, 0.2});
  w.circles.push_back({{3.4, 4.6}, 0.08});
  haptics::add_thick_wall(w, {-1.2, 2.0}, {-0.6, 2.0}, 0.02);  // a thin board sticking out
  return w;
}

struct RouteResult {
  double est_error = 0.0;    // |estimate - truth| at the end, m
  double goal_true = 0.0;    // |truth - final goal|, m
  double goal_est = 0.0;     // |estimate - final goal|, m
  double heading_error = 0.0;
  LocalizerStats stats;
  bool finished = false;
};

RouteResult drive_route(bool register_scans, std::uint32_t seed) {
  const haptics::ExactScene world = ring_corridor();
  auto ray = [&world](const Vector2d& o, const Vector2d& u, double r) { return haptics::raycast(world, o, u, r); };
  const std::vector<Vector2d> goals = {{6.0, 0.0}, {6.0, 4.1}, {0.0, 4.1}, {0.0, 1.2}};
  RegistrationParams rp;
  rp.enabled = register_scans;
  Localizer loc(rp);
  mapping::MapParams mp;
  mapping::LocalMap map;
  Pose2 truth{0.0, 0.0, 0.0}, odom = truth;
  test::SynthScanSpec spec;
  spec.sigma = 0.01;
  spec.dropout_probability = 0.01;
  spec.no_return_valid = true;
  spec.range_max = 10.0;
  const Pose2 T_R_S{0.18, 0.0, 0.0};
  const double dt = 0.01;
  std::size_t g = 0;
  RouteResult out;
  for (int k = 0; k < 20000 && g < goals.size(); ++k) {
    const auto stamp = static_cast<std::int64_t>(k) * 10'000'000 + 1;
    if (k % 9 == 0) {  // an 11 Hz laser keeps the test short (the station registers every scan at 30 Hz)
      spec.seed = seed * 100000u + static_cast<std::uint32_t>(k);
      mapping::RangeScan2D s = test::synth_scan(ray, truth, T_R_S, stamp, spec);
      s.T_W_R = odom;  // stamped with odometry, as the robot sends it
      const bool limited = loc.place(s, map).limited;
      loc.begin_step();
      if (!limited) {
        EXPECT_EQ(mapping::add_scan(mp, map, s), "");
      }
      const Pose2 est = loc.correct(odom);
      mapping::slide_window(mp, map, stamp, {est.x, est.y});
    }
    // Steer by the best estimate: turn toward the goal, then drive.
    const Pose2 est = loc.correct(odom);
    const Vector2d to = goals[g] - Vector2d(est.x, est.y);
    if (to.norm() < 0.05) {
      ++g;
      continue;
    }
    const double bearing = math::wrap_angle(std::atan2(to.y(), to.x()) - est.theta);
    double v = 0.0, w = std::clamp(2.0 * bearing, -0.8, 0.8);
    if (std::abs(bearing) < 0.15) v = std::min(0.4, 1.5 * to.norm());
    // Odometry integrates the command; the slipping base turns 1/1.1 of it
    // and rolls 3 % short.
    auto step = [dt](Pose2& p, double vv, double ww) {
      p.x += vv * std::cos(p.theta + 0.5 * ww * dt) * dt;
      p.y += vv * std::sin(p.theta + 0.5 * ww * dt) * dt;
      p.theta = math::wrap_angle(p.theta + ww * dt);
    };
    step(odom, v, w);
    step(truth, 0.97 * v, w / 1.1);
  }
  out.finished = g == goals.size();
  const Pose2 est = loc.correct(odom);
  out.est_error = std::hypot(est.x - truth.x, est.y - truth.y);
  out.heading_error = std::abs(math::wrap_angle(est.theta - truth.theta));
  out.goal_true = (goals.back() - Vector2d(truth.x, truth.y)).norm();
  out.goal_est = (goals.back() - Vector2d(est.x, est.y)).norm();
  out.stats = loc.stats();
  return out;
}

TEST(ScanRegistration, RouteWithFourTurnsArrivesWithinTenCentimetresOfTheTrueGoal) {
  for (std::uint32_t seed : {1u}) {
    const RouteResult with = drive_route(true, seed);
    const RouteResult without = drive_route(false, seed);
    std::printf("seed %u: pose error after the route: odometry %.3f m / %.1f deg, registered %.3f m / %.1f deg; "
                "true distance to the goal at arrival: odometry %.3f m, registered %.3f m; registrations "
                "accepted %llu, rejected %llu, degenerate %llu, last rms %.4f m\n",
                seed, without.est_error, without.heading_error * 180 / std::numbers::pi, with.est_error,
                with.heading_error * 180 / std::numbers::pi, without.goal_true, with.goal_true,
                static_cast<unsigned long long>(with.stats.accepted),
                static_cast<unsigned long long>(with.stats.rejected),
                static_cast<unsigned long long>(with.stats.degenerate), with.stats.last_rms);
    ASSERT_TRUE(with.finished && without.finished);
    EXPECT_LT(with.goal_est, 0.05);   // arrival is judged on the estimate ...
    EXPECT_LT(with.goal_true, 0.1);   // ... and the robot is truly there
    // What is left of the drift: a local map of the last 3 s has no loop
    // closure, so registration errors add up slowly (~0.1 m over the 19 m).
    EXPECT_LT(with.est_error, 0.15);
    EXPECT_LT(with.est_error, 0.2 * without.est_error);
    EXPECT_GT(without.goal_true, 0.3);  // odometry alone is not (the test can fail)
    EXPECT_GT(with.stats.accepted, with.stats.rejected);
  }
}

TEST(ScanRegistration, WrongMatchesAndDegenerateCorridorsAreNotAccepted) {
  // A scan of a room placed 0.6 m off (beyond the plausible step) is refused;
  // one 4 cm off is corrected; in a long straight corridor without features
  // the correction along the corridor is left out.
  haptics::ExactScene room;
  haptics::add_box(room, {-2, -1.5}, {3, 2});
  room.circles.push_back({{1.5, 0.8}, 0.15});
  auto ray = [&room](const Vector2d& o, const Vector2d& u, double r) { return haptics::raycast(room, o, u, r); };
  test::SynthScanSpec spec;
  spec.sigma = 0.005;
  mapping::MapParams mp;
  mapping::LocalMap map;
  ASSERT_EQ(mapping::add_scan(mp, map, test::synth_scan(ray, Pose2{}, Pose2{}, 1, spec)), "");
  RegistrationTarget target;
  target.build(map, 1000);
  ASSERT_GT(target.size(), 100u);
  RegistrationParams rp;
  rp.enabled = true;
  mapping::RangeScan2D s = test::synth_scan(ray, Pose2{}, Pose2{}, 2, spec);
  s.T_W_R = Pose2{0.03, -0.025, 0.02};  // odometry off by 4 cm and 1.1 deg
  RegistrationResult r = register_scan(rp, s, target);
  ASSERT_TRUE(r.accepted) << r.reason;
  const Pose2 fixed = math::compose(r.delta, s.T_W_R);
  EXPECT_LT(std::hypot(fixed.x, fixed.y), 0.01);
  EXPECT_LT(std::abs(fixed.theta), 0.005);
  s.T_W_R = Pose2{0.6, 0.0, 0.0};
  r = register_scan(rp, s, target);
  EXPECT_FALSE(r.accepted);

  haptics::ExactScene corridor;
  corridor.segments.push_back({{-20, -1}, {20, -1}});
  corridor.segments.push_back({{-20, 1}, {20, 1}});
  auto cray = [&corridor](const Vector2d& o, const Vector2d& u, double rr) {
    return haptics::raycast(corridor, o, u, rr);
  };
  mapping::LocalMap cmap;
  ASSERT_EQ(mapping::add_scan(mp, cmap, test::synth_scan(cray, Pose2{}, Pose2{}, 1, spec)), "");
  target.build(cmap, 1000);
  s = test::synth_scan(cray, Pose2{}, Pose2{}, 2, spec);
  s.T_W_R = Pose2{0.1, 0.03, 0.0};
  r = register_scan(rp, s, target);
  ASSERT_TRUE(r.accepted) << r.reason;
  EXPECT_TRUE(r.degenerate);
  const Pose2 c = math::compose(r.delta, s.T_W_R);
  EXPECT_LT(std::abs(c.y), 0.01);        // across the corridor: corrected
  EXPECT_NEAR(c.x, 0.1, 0.02);           // along it: left alone, not slid
  RegistrationParams bad;
  bad.max_correspondence = -1;
  EXPECT_FALSE(validate(bad).empty());
}

}  // namespace
}  // namespace hemm::op
