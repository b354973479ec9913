// The collision guard (robot_side/control/collision_guard.h) against closed
// forms and a brute-force reference.
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "robot_side/control/collision_guard.h"

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
