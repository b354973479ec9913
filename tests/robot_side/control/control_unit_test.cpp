// Controllers and safety as pure functions, against closed forms.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/arm_control.h"
#include "robot_side/control/base_control.h"
#include "common/math/geometry3.h"
#include "robot_side/control/safety.h"

namespace hr = hemm::robot;

namespace {

// Reference for the turning guard, independent of its closed form: turn the
// grown footprint in small steps until the point is inside it.
double brute_force_turn(const hr::CollisionGuardParams& p, const Eigen::Vector2d& pt, double sign) {
  const double m = p.turn_margin;
  for (double a = 0.0; a < 2.0 * std::numbers::pi; a += 1e-5) {
    const double c = std::cos(sign * a), s = std::sin(sign * a);
    const Eigen::Vector2d q(c * pt.x() + s * pt.y(), -s * pt.x() + c * pt.y());  // the point in the turned footprint
    if (q.x() >= p.rear_x - m && q.x() <= p.front_x + m && std::abs(q.y()) <= p.half_width + m) return a;
  }
  return std::numeric_limits<double>::infinity();
}

// A SIMULATED laser at the R origin: 181 beams over 180 deg, every return at `range`.
struct Scan {
  std::vector<float> ranges;
  std::vector<uint8_t> valid;
  double angle(std::size_t i) const { return -std::numbers::pi / 2 + static_cast<double>(i) * std::numbers::pi / 180.0; }
  explicit Scan(float range) : ranges(181, range), valid(181, 1) {}
  // The guard's knowledge from it (laser: no cone; not a ring).
  hr::KnownFree known() const {
    std::vector<float> kr(ranges.size());
    hr::known_beam_ranges(ranges, valid, 2, false, kr);
    std::vector<Eigen::Vector2d> ends(ranges.size());
    std::vector<uint8_t> k(ranges.size());
    for (std::size_t i = 0; i < ranges.size(); ++i) {
      k[i] = kr[i] >= 0.0f;
      ends[i] = std::max(0.0f, kr[i]) * Eigen::Vector2d(std::cos(angle(i)), std::sin(angle(i)));
    }
    hr::KnownFree out{};
    hr::add_known_free(ends, k, 0.0, false, out);
    return out;
  }
};

}  // namespace

TEST(BaseSlew, RampsAtTheAccelerationLimitAndClampsSpeed) {
  const hr::BaseLimits l{0.7, 2.0, 1.0, 4.0};
  hr::BaseSetpoint s;
  int steps = 0;
  while (s.v < 0.7 && steps < 10000) {
    s = hr::slew_setpoint(l, s, 5.0, 0.0, 0.001);  // asks for more than the limit
    ++steps;
  }
  EXPECT_NEAR(steps, 700, 1);  // 0.7 m/s at 1 m/s^2
  EXPECT_DOUBLE_EQ(s.v, 0.7);
  s = hr::slew_setpoint(l, s, std::nan(""), 1e9, 0.001);  // NaN counts as 0
  EXPECT_NEAR(s.v, 0.699, 1e-12);
  EXPECT_NEAR(s.omega, 0.004, 1e-12);
}

TEST(SkidSteer, WheelSpeedsAndBodyMotionAreInverses) {
  const hr::SkidSteerGeometry g;
  const hr::BaseSetpoint b{0.3, -0.8};
  const hr::WheelSpeeds w = hr::wheel_speeds(g, b);
  EXPECT_NEAR(w.right - w.left, b.omega * g.track_width * g.slip_factor, 1e-12);
  const hr::BaseSetpoint b2 = hr::body_motion(g, w);
  EXPECT_NEAR(b2.v, b.v, 1e-12);
  EXPECT_NEAR(b2.omega, b.omega, 1e-12);
}

TEST(Odometry, ConstantWheelSpeedsTraceTheClosedFormArc) {
  const hr::SkidSteerGeometry g;
  const hr::BaseSetpoint b{0.4, 0.5};
  const hr::WheelSpeeds w = hr::wheel_speeds(g, b);
  hr::Odometry o;
  const double T = 2.0;
  for (int k = 0; k < 2000; ++k) hr::integrate_odometry(g, w, 0.001, o);
  // Arc of radius v/omega (the chord update is exact for constant speeds).
  const double R = b.v / b.omega, th = b.omega * T;
  EXPECT_NEAR(o.x, R * std::sin(th), 1e-9);
  EXPECT_NEAR(o.y, R * (1 - std::cos(th)), 1e-9);
  EXPECT_NEAR(o.theta, th, 1e-12);
  EXPECT_NEAR(hemm::math::wrap_angle(3 * std::numbers::pi), std::numbers::pi, 1e-12);
}

TEST(Watchdog, ExpiresAfterTheTimeout) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  EXPECT_TRUE(hr::watchdog_expired(w, 0));  // nothing received yet
  hr::watchdog_feed(w, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'250'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'250'000'001));
}

TEST(Watchdog, CountsFromTheCommandsSendTimeAndNeverFromTheFuture) {
  hr::Watchdog w;
  w.timeout_ns = 250'000'000;
  // Arrived at t = 1 s but sent (as the fastest command would have been) 150 ms earlier: 100 ms left.
  hr::watchdog_feed(w, 850'000'000, 1'000'000'000);
  EXPECT_FALSE(hr::watchdog_expired(w, 1'100'000'000));
  EXPECT_TRUE(hr::watchdog_expired(w, 1'100'000'001));
  // Held longer than the timeout: expired on arrival.
  hr::watchdog_feed(w, 600'000'000, 1'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 1'000'000'000));
  // A send time after now (a clock estimate off) counts as now, not later.
  hr::watchdog_feed(w, 5'000'000'000, 2'000'000'000);
  EXPECT_TRUE(hr::watchdog_expired(w, 2'250'000'001));
}

TEST(CollisionGuard, StoppingDistanceFitsTheFreeRange) {
  const double a = 1.0, tr = 0.05;
  for (double d : {0.01, 0.1, 0.5, 2.0}) {
    const double v = hr::stoppable_speed(d, a, tr);
    EXPECT_NEAR(v * tr + v * v / (2 * a), d, 1e-12);
  }
  EXPECT_EQ(hr::stoppable_speed(-0.1, a, tr), 0.0);
  hr::CollisionGuardParams p;
  p.margin = 0.15;
  const std::vector<Eigen::Vector2d> pts = {
      {1.0, 0.1},   // ahead in the corridor
      {0.6, 0.4},   // ahead but outside the corridor: ignored
      {0.0, 0.3},   // beside the robot: not in the corridor (it limits turning)
      {-0.9, -0.2}  // behind
  };
  const hr::GuardLimit g = hr::collision_guard(p, pts);
  EXPECT_NEAR(g.free_ahead, 1.0 - p.front_x, 1e-12);
  EXPECT_NEAR(g.free_behind, 0.9 + p.rear_x, 1e-12);
  EXPECT_NEAR(g.max_forward, hr::stoppable_speed(1.0 - p.front_x - p.margin, p.max_decel, p.reaction_time), 1e-12);
  const hr::GuardLimit none = hr::collision_guard(p, {});
  EXPECT_TRUE(std::isinf(none.max_forward));
  // An obstacle inside the margin: no forward motion at all.
  const std::vector<Eigen::Vector2d> close = {{p.front_x + 0.1, 0.0}};
  EXPECT_EQ(hr::collision_guard(p, close).max_forward, 0.0);
}

TEST(CollisionGuard, TurningInPlaceIsLimitedByTheSweptFootprintIncludingTheArm) {
  hr::CollisionGuardParams p;
  // A return 0.15 m beside the body: turning either way swings a corner into it.
  const Eigen::Vector2d beside(0.0, 0.40);
  const std::vector<Eigen::Vector2d> pts = {beside};
  const hr::GuardLimit g = hr::collision_guard(p, pts);
  const double ccw = brute_force_turn(p, beside, 1.0), cw = brute_force_turn(p, beside, -1.0);
  ASSERT_TRUE(std::isfinite(ccw) && std::isfinite(cw));
  EXPECT_NEAR(g.free_turn_ccw, ccw, 1e-4);
  EXPECT_NEAR(g.free_turn_cw, cw, 1e-4);
  EXPECT_NEAR(g.max_yaw_ccw, hr::stoppable_speed(ccw, p.max_yaw_decel, p.reaction_time), 1e-3);
  EXPECT_NEAR(g.max_yaw_cw, hr::stoppable_speed(cw, p.max_yaw_decel, p.reaction_time), 1e-3);
  EXPECT_TRUE(std::isfinite(g.max_yaw_ccw));
  // The corridor ahead and behind is not in the way.
  EXPECT_TRUE(std::isinf(g.max_forward));
  // 0.6 m to the side is out of the body's reach, not of an arm reaching 0.7 m forward.
  const std::vector<Eigen::Vector2d> far = {{0.0, 0.6}};
  EXPECT_TRUE(std::isinf(hr::collision_guard(p, far).max_yaw_ccw));
  hr::CollisionGuardParams arm = p;
  arm.front_x = 0.70;
  arm.half_width = 0.25;
  const hr::GuardLimit ga = hr::collision_guard(arm, far);
  EXPECT_NEAR(ga.free_turn_ccw, brute_force_turn(arm, far[0], 1.0), 1e-4);
  EXPECT_NEAR(ga.free_turn_cw, brute_force_turn(arm, far[0], -1.0), 1e-4);
  EXPECT_LT(ga.free_turn_ccw, ga.free_turn_cw);  // turning left swings the arm at it first
  // Inside the swept footprint (beside the arm, not the body): no turning at all.
  const std::vector<Eigen::Vector2d> by_arm = {{0.5, 0.2}};
  const hr::GuardLimit gb = hr::collision_guard(arm, by_arm);
  EXPECT_EQ(gb.max_yaw_ccw, 0.0);
  EXPECT_EQ(gb.max_yaw_cw, 0.0);
  EXPECT_FALSE(gb.inside);
}

TEST(CollisionGuard, ReverseWithNoDataBehindIsACrawl) {
  hr::CollisionGuardParams p;
  // Everything ahead seen free to 5 m, nothing known behind.
  hr::KnownFree known{};
  for (int k = 0; k < hr::kGuardSectors; ++k) {
    const double a = -std::numbers::pi + (k + 0.5) * 2.0 * std::numbers::pi / hr::kGuardSectors;
    if (std::cos(a) > 0.0) known[static_cast<std::size_t>(k)] = 5.0;
  }
  const hr::GuardLimit g = hr::collision_guard(p, {}, &known);
  EXPECT_EQ(g.known_behind, 0.0);
  EXPECT_EQ(g.max_backward, p.unknown_speed);
  EXPECT_GT(g.max_forward, 2.0);
  // Seen free to 2 m all round: the rear corridor is known as far as the
  // circle of 2 m meets its sides, x = -sqrt(4 - h^2).
  known.fill(2.0);
  const hr::GuardLimit g2 = hr::collision_guard(p, {}, &known);
  const double expect = std::sqrt(4.0 - p.half_width * p.half_width) + p.rear_x;
  EXPECT_NEAR(g2.known_behind, expect, 0.005);
  EXPECT_NEAR(g2.max_backward, hr::stoppable_speed(g2.known_behind - p.margin, p.max_decel, p.reaction_time), 1e-9);
  EXPECT_GT(g2.max_backward, 1.0);
}

TEST(CollisionGuard, LaserDropoutsAreNotFreeSpace) {
  hr::CollisionGuardParams p;
  // A wall 2 m all round the laser's half; one lone dropout ahead is bounded
  // by its neighbours: the corridor is known free to the wall.
  Scan one(2.0f);
  one.valid[90] = 0;
  const hr::KnownFree k1 = one.known();
  const hr::GuardLimit g1 = hr::collision_guard(p, {}, &k1);
  EXPECT_NEAR(g1.known_ahead, std::sqrt(4.0 - p.half_width * p.half_width) - p.front_x, 0.005);
  // Five dropouts straight ahead (something black, or glass): not free.
  Scan five(2.0f);
  for (std::size_t i = 88; i <= 92; ++i) five.valid[i] = 0;
  std::vector<float> kr(181);
  hr::known_beam_ranges(five.ranges, five.valid, 2, false, kr);
  EXPECT_EQ(kr[90], -1.0f);
  const hr::KnownFree k5 = five.known();
  const hr::GuardLimit g5 = hr::collision_guard(p, {}, &k5);
  EXPECT_EQ(g5.known_ahead, 0.0);
  EXPECT_EQ(g5.max_forward, p.unknown_speed);
  EXPECT_GT(g5.max_backward, 0.0);
  // Two dropouts are bridged by the nearer neighbour.
  Scan two(2.0f);
  two.ranges[88] = 1.5f;
  two.valid[89] = two.valid[90] = 0;
  hr::known_beam_ranges(two.ranges, two.valid, 2, false, kr);
  EXPECT_EQ(kr[89], 1.5f);
  EXPECT_EQ(kr[90], 1.5f);
  // A ring wraps: beam 0's neighbours are the last and the second.
  const std::vector<float> ring_r = {1.0f, 3.0f, 3.0f, 2.0f};
  const std::vector<uint8_t> ring_v = {0, 1, 1, 1};
  std::vector<float> rk(4);
  hr::known_beam_ranges(ring_r, ring_v, 1, true, rk);
  EXPECT_EQ(rk[0], 2.0f);
  hr::known_beam_ranges(ring_r, ring_v, 1, false, rk);
  EXPECT_EQ(rk[0], -1.0f);
}

TEST(CollisionGuard, AReturnInsideTheBodyStopsEverything) {
  hr::CollisionGuardParams p;
  const std::vector<Eigen::Vector2d> inside = {{0.10, 0.05}, {3.0, 0.0}};
  const hr::GuardLimit g = hr::collision_guard(p, inside);
  EXPECT_TRUE(g.inside);
  EXPECT_EQ(g.max_forward, 0.0);
  EXPECT_EQ(g.max_backward, 0.0);
  EXPECT_EQ(g.max_yaw_ccw, 0.0);
  EXPECT_EQ(g.max_yaw_cw, 0.0);
  // On the body's edge within the range noise: touching, not inside.
  const std::vector<Eigen::Vector2d> edge = {{0.0, p.body_half_width - 0.5 * p.inside_tolerance}};
  EXPECT_FALSE(hr::collision_guard(p, edge).inside);
}

TEST(ArmKeepOut, RefusesPosesIntoTheFloorTheBaseAndSeenGeometry) {
  const hr::ArmKeepOut k;
  const Eigen::Vector3d shoulder(0.02, 0.0, 0.36);
  // Reaching forward and level, over free floor: allowed.
  const std::vector<Eigen::Vector3d> level = {shoulder, {0.08, 0, 0.36}, {0.24, 0, 0.36}, {0.38, 0, 0.36},
                                              {0.52, 0, 0.36}};
  EXPECT_EQ(hr::check_arm_chain(k, level, {}), hr::ArmRefusal::kNone);
  // Down into the floor in front of the robot.
  const std::vector<Eigen::Vector3d> floor = {shoulder, {0.08, 0, 0.36}, {0.24, 0, 0.20}, {0.38, 0, 0.06},
                                              {0.45, 0, 0.01}};
  EXPECT_EQ(hr::check_arm_chain(k, floor, {}), hr::ArmRefusal::kFloor);
  // Folded back down onto the chassis top (z 0.26).
  const std::vector<Eigen::Vector3d> base = {shoulder, {-0.04, 0, 0.36}, {-0.15, 0, 0.30}, {-0.20, 0, 0.27}};
  EXPECT_EQ(hr::check_arm_chain(k, base, {}), hr::ArmRefusal::kBase);
  // Onto the laser head (x 0.14..0.22, z up to 0.32).
  const std::vector<Eigen::Vector3d> head = {shoulder, {0.08, 0, 0.36}, {0.18, 0, 0.33}};
  EXPECT_EQ(hr::check_arm_chain(k, head, {}), hr::ArmRefusal::kBase);
  // A wall the laser saw 0.45 m ahead: the level reach to 0.52 m goes through it.
  const std::vector<Eigen::Vector2d> wall = {{0.45, -0.1}, {0.45, 0.0}, {0.45, 0.1}};
  hr::SeenScene seen;
  seen.columns_R = wall;
  EXPECT_EQ(hr::check_arm_chain(k, level, seen), hr::ArmRefusal::kScene);
  // ... a wall 0.6 m ahead leaves it free (tip 0.08 m short).
  const std::vector<Eigen::Vector2d> far_wall = {{0.60, -0.1}, {0.60, 0.0}, {0.60, 0.1}};
  seen.columns_R = far_wall;
  EXPECT_EQ(hr::check_arm_chain(k, level, seen), hr::ArmRefusal::kNone);
  EXPECT_STRNE(hr::to_string(hr::ArmRefusal::kScene), hr::to_string(hr::ArmRefusal::kFloor));
}

TEST(ArmControl, ReferenceIsRateLimitedAndTorqueClamped) {
  const hemm::kinematics::Arm5Model m;
  hr::ArmControlParams p;
  hr::ArmControlState s;
  hr::reset_arm(s, hr::Arm5Vector::Zero());
  EXPECT_TRUE(hr::set_arm_goal(m, s, hr::Arm5Vector::Constant(5.0)));  // beyond the limits: clamped
  EXPECT_TRUE(hemm::kinematics::within_limits(m, s.q_goal));
  bool sat = false;
  const hr::Arm5Vector tau =
      hr::arm_control_step(p, s, hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), 0.001, &sat);
  EXPECT_NEAR(s.q_ref(0), p.max_joint_speed * 0.001, 1e-15);
  EXPECT_LE(tau.cwiseAbs().maxCoeff(), p.max_joint_torque);
  // Gravity bias alone passes through (no error, no motion).
  hr::reset_arm(s, hr::Arm5Vector::Zero());
  const hr::Arm5Vector bias = (hr::Arm5Vector() << 0, 1.0, -0.5, 0, 0.1).finished();
  const hr::Arm5Vector t2 = hr::arm_control_step(p, s, hr::Arm5Vector::Zero(), hr::Arm5Vector::Zero(), bias, 0.001, &sat);
  EXPECT_LT((t2 - bias).norm(), 1e-12);
  EXPECT_FALSE(sat);
}

// ---------------------------------------------------------------- 3D keep-out (issue 13)

TEST(ArmKeepOut3d, SegmentSegmentDistanceMatchesClosedForms) {
  const Eigen::Vector3d o(0, 0, 0), x1(1, 0, 0);
  // Skew, perpendicular, crossing over the middle at height h.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {0.5, -1, 0.3}, {0.5, 1, 0.3}).distance, 0.3, 1e-12);
  // Parallel, offset sideways by 0.2 and overlapping.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {0.5, 0.2, 0}, {1.5, 0.2, 0}).distance, 0.2, 1e-12);
  // Collinear, apart by a gap of 0.25 past the end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {1.25, 0, 0}, {2, 0, 0}).distance, 0.25, 1e-12);
  // A point (degenerate segment) beyond an end: distance to the end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {2, 0, 0}, {2, 0, 0}).distance, 1.0, 1e-12);
  EXPECT_NEAR(hemm::math::segment_segment({3, 4, 0}, {3, 4, 0}, o, o).distance, 5.0, 1e-12);
  // Skew lines whose closest points lie past both ends: end to end.
  EXPECT_NEAR(hemm::math::segment_segment(o, x1, {2, 1, 0}, {3, 1, 0}).distance, std::sqrt(2.0), 1e-12);
}

namespace {
// A plane z = z0 of seen points in P on a 1 cm grid (x 0..0.8, y -0.3..0.3),
// so that the point straight below any point of a chain along x at y = 0 is
// in the set: the chain's distance to the set is its height above z0.
std::vector<Eigen::Vector3f> plane_points(double z0, const Eigen::Isometry3d& T_P_R) {
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i <= 80; ++i)
    for (int j = -30; j <= 30; ++j) pts.push_back((T_P_R * Eigen::Vector3d(0.01 * i, 0.01 * j, z0)).cast<float>());
  return pts;
}
}  // namespace

TEST(ArmKeepOut3d, AChainAboveSeenPointsIsRefusedExactlyInsideTheReach) {
  const hr::ArmKeepOut k;
  const double reach = k.link_radius + k.clearance + k.seen_pad;  // 0.04 m
  // The robot stands anywhere in P (the points are in P, the chain in R).
  Eigen::Isometry3d T_P_R = Eigen::Isometry3d::Identity();
  T_P_R.translation() << 2.0, -1.0, 0.0;
  T_P_R.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double z0 = 0.46;  // a seat
  const std::vector<Eigen::Vector3f> pts = plane_points(z0, T_P_R);
  // The shoulder high above, the forearm and tool level over the plane at h.
  auto chain_at = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, 0.80}, {0.08, 0, 0.80}, {0.20, 0, 0.80}, {0.30, 0, h}, {0.44, 0, h}};
  };
  hr::SeenScene seen;
  seen.points_P = pts;
  seen.T_P_R = T_P_R;
  // float points: within 1e-5 m of the threshold either way.
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach + 1e-5), seen), hr::ArmRefusal::kNone);
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach - 1e-5), seen), hr::ArmRefusal::kScene);
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + 0.2), seen), hr::ArmRefusal::kNone);
  // The same chain with the robot elsewhere in P: the plane is not under it.
  hr::SeenScene moved = seen;
  moved.T_P_R.translation().x() += 3.0;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(z0 + reach - 1e-3), moved), hr::ArmRefusal::kNone);
  // Floor and base come first, as before.
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.01), seen), hr::ArmRefusal::kFloor);
}

TEST(ArmKeepOut3d, CappedColumnsLetTheArmReachOverWhatTheLaserSaw) {
  const hr::ArmKeepOut k;
  const double r = k.link_radius + k.clearance;
  // The front of a seat the laser saw 0.32 m ahead; the tool reaches level
  // over it at height h to 0.50 m.
  const std::vector<Eigen::Vector2d> front = {{0.32, -0.1}, {0.32, 0.0}, {0.32, 0.1}};
  auto chain_at = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, 0.36}, {0.08, 0, 0.50}, {0.22, 0, 0.70}, {0.36, 0, h}, {0.50, 0, h}};
  };
  const double top = 0.40;
  hr::SeenScene infinite;
  infinite.columns_R = front;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), infinite), hr::ArmRefusal::kScene);
  const std::vector<std::uint8_t> capped = {1, 1, 1};
  hr::SeenScene with_caps = infinite;
  with_caps.column_capped = capped;
  with_caps.column_top_z = top;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), with_caps), hr::ArmRefusal::kNone);
  // Exactly at the threshold: a level chain at top + r over the capped
  // columns is allowed, just below it refused.
  auto level = [](double h) {
    return std::vector<Eigen::Vector3d>{{0.02, 0, h}, {0.10, 0, h}, {0.30, 0, h}, {0.50, 0, h}};
  };
  EXPECT_EQ(hr::check_arm_chain(k, level(top + r + 1e-9), with_caps), hr::ArmRefusal::kNone);
  EXPECT_EQ(hr::check_arm_chain(k, level(top + r - 1e-9), with_caps), hr::ArmRefusal::kScene);
  // Only the flagged columns are capped.
  const std::vector<std::uint8_t> one = {1, 0, 1};  // the one under the chain (y = 0) not capped
  hr::SeenScene partly = with_caps;
  partly.column_capped = one;
  EXPECT_EQ(hr::check_arm_chain(k, chain_at(0.55), partly), hr::ArmRefusal::kScene);
}

TEST(ArmKeepOut3d, ACameraLookingStraightDownSeesItsConeOnly) {
  // Camera 1.1 m above R's origin looking straight down (optical z = -z_R).
  const hemm::mapping::DepthIntrinsics K =
      hemm::mapping::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  Eigen::Isometry3d T_R_S = Eigen::Isometry3d::Identity();
  T_R_S.linear().col(0) = Eigen::Vector3d(0, -1, 0);  // x_S right (image)
  T_R_S.linear().col(2) = Eigen::Vector3d(0, 0, -1);  // z_S down
  T_R_S.linear().col(1) = T_R_S.linear().col(2).cross(T_R_S.linear().col(0));
  T_R_S.translation() << 0, 0, 1.1;
  const Eigen::Isometry3d T_S_R = T_R_S.inverse();
  // Half the horizontal field (across y_R) at depth d is d tan(30 deg).
  const double d = 0.6, half = d * std::tan(30.0 * std::numbers::pi / 180.0);
  EXPECT_TRUE(hr::in_camera_view(K, T_S_R, {0.0, half - 1e-6, 1.1 - d}));
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, half + 1e-6, 1.1 - d}));
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, 0.0, 1.1 - 0.15}));  // nearer than range_min
  EXPECT_FALSE(hr::in_camera_view(K, T_S_R, {0.0, 0.0, 1.2}));         // behind
  // A column 0.1 m to the side seen from 0.4 to 0.8 m: both ends in the cone.
  EXPECT_TRUE(hr::column_seen_from_above(K, T_S_R, {0.0, 0.1}, 0.4, 0.8));
  // 0.4 m to the side: the top end (0.3 m below the camera) is outside.
  EXPECT_FALSE(hr::column_seen_from_above(K, T_S_R, {0.0, 0.4}, 0.4, 0.8));
}

TEST(SeenVoxels, AFlatImageMarksOneVoxelPerCellOfThePlaneAndForgetsOldFrames) {
  // A camera 1 m above a floor-parallel plane at z = 0.5 (P), looking down:
  // every pixel's depth is 0.5 m.
  hemm::mapping::DepthImage img;
  img.K = hemm::mapping::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  img.depth.assign(80 * 60, 0.5f);
  img.status.assign(80 * 60, hemm::mapping::DepthStatus::kValid);
  img.status[0] = hemm::mapping::DepthStatus::kDropout;
  img.stamp_ns = 1'000'000'000;
  Eigen::Isometry3d T_P_S = Eigen::Isometry3d::Identity();
  T_P_S.linear().col(0) = Eigen::Vector3d(0, -1, 0);
  T_P_S.linear().col(2) = Eigen::Vector3d(0, 0, -1);
  T_P_S.linear().col(1) = T_P_S.linear().col(2).cross(T_P_S.linear().col(0));
  T_P_S.translation() << 0, 0, 1.0;
  hr::SeenVoxelParams p;
  p.voxel_size = 0.02;
  p.keep_ns = 500'000'000;
  hr::SeenVoxels sv(p);
  EXPECT_EQ(sv.add_frame(img, T_P_S), 80u * 60u - 1u);
  std::vector<Eigen::Vector3f> pts;
  sv.points(&pts);
  ASSERT_EQ(pts.size(), sv.size());
  // Every point is a pixel's point on the plane, and each 2 cm cell of the
  // imaged rectangle (0.577 x 0.433 m at 0.5 m) holds one.
  for (const Eigen::Vector3f& q : pts) EXPECT_NEAR(q.z(), 0.5f, 1e-5f);
  const double w = 2 * 0.5 * std::tan(30.0 * std::numbers::pi / 180.0), h = w * 60.0 / 80.0;
  EXPECT_NEAR(static_cast<double>(pts.size()), (w / 0.02 + 1) * (h / 0.02 + 1), 0.1 * (w / 0.02) * (h / 0.02));
  EXPECT_GT(sv.memory_bytes(), pts.size() * sizeof(Eigen::Vector3f));
  // A frame of nothing valid 0.4 s later keeps them; 0.6 s later forgets them.
  hemm::mapping::DepthImage none = img;
  none.status.assign(80 * 60, hemm::mapping::DepthStatus::kNoReturn);
  none.stamp_ns = img.stamp_ns + 400'000'000;
  EXPECT_EQ(sv.add_frame(none, T_P_S), 0u);
  EXPECT_EQ(sv.size(), pts.size());
  none.stamp_ns = img.stamp_ns + 600'000'000;
  sv.add_frame(none, T_P_S);
  EXPECT_EQ(sv.size(), 0u);
  // The floor band is left to the floor keep-out; the bound holds.
  Eigen::Isometry3d low = T_P_S;
  low.translation().z() = 0.52;  // plane at z = 0.02 < min_z
  EXPECT_EQ(sv.add_frame(img, low), 0u);
  hr::SeenVoxelParams small = p;
  small.max_voxels = 100;
  hr::SeenVoxels bounded(small);
  bounded.add_frame(img, T_P_S);
  EXPECT_EQ(bounded.size(), 100u);
  // A malformed image (sizes disagree) adds nothing.
  hemm::mapping::DepthImage bad = img;
  bad.depth.pop_back();
  hr::SeenVoxels fresh(p);
  EXPECT_EQ(fresh.add_frame(bad, T_P_S), 0u);
  EXPECT_EQ(fresh.size(), 0u);
  hr::SeenVoxelParams zero = p;
  zero.voxel_size = 0.0;
  EXPECT_THROW(hr::SeenVoxels{zero}, std::invalid_argument);
}
