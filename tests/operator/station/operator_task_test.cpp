// The servo task: frames and force direction, the three modes and their
// switching without force jumps, navigation force rising toward a wall (and
// the command stopping the robot short of it), and no allocation on tick.
#include <gtest/gtest.h>
#include <numbers>

#include <cmath>
#include <limits>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"
#include "operator/station/operator_task.h"
#include "tests/operator/servo/alloc_counter.h"

namespace ho = hemm::op;
namespace hm = hemm::math;
namespace hd = hemm::device;
namespace hs = hemm::servo;
namespace hmap = hemm::mapping;

namespace {

constexpr double kK = 300.0;  // proxy stiffness (default)

// A snapshot with one wall segment from a to b (normal toward the free side).
std::unique_ptr<ho::OperatorModelSnapshot> wall_snapshot(Eigen::Vector2d a, Eigen::Vector2d b, Eigen::Vector2d n,
                                                         hm::Pose2 T_W_R, std::int64_t stamp = 0) {
  hmap::LocalMap lm;
  hmap::Segment2 s;
  s.a = a;
  s.b = b;
  s.normal = n.normalized();
  lm.segments.push_back(s);
  auto snap = std::make_unique<ho::OperatorModelSnapshot>();
  snap->map = hmap::build_snapshot(hmap::MapParams{}, lm);
  snap->T_W_R = T_W_R;
  snap->have_state = true;
  snap->stamp_ns = stamp;
  snap->version = 1;
  return snap;
}

// A snapshot with no 2D map and a live voxmap (1 cm voxels, `layers` each
// side) of a 0.6 x 0.6 x 0.2 m box centred at `centre_W`; null if the
// voxmap cannot be built.
std::unique_ptr<ho::OperatorModelSnapshot> box_voxmap_snapshot(const Eigen::Vector3d& centre_W, int layers) {
  hemm::mesh::TriangleMesh m = hemm::mesh::make_box({0.3, 0.3, 0.1}, 4);
  for (auto& v : m.vertices) v += centre_W;
  hemm::vps::VoxmapParams vp;
  vp.voxel_size = 0.01;
  vp.layers_in = vp.layers_out = layers;
  auto vm = std::make_shared<hemm::vps::Voxmap>();
  if (hemm::vps::build_voxmap(m, vp, vm.get(), nullptr)) return nullptr;
  auto snap = std::make_unique<ho::OperatorModelSnapshot>();
  snap->map = hmap::build_snapshot(hmap::MapParams{}, hmap::LocalMap{});
  snap->have_state = true;
  snap->version = 1;
  snap->voxmap = vm;
  return snap;
}

// H position for a B position (x forward, y left, z up).
Eigen::Vector3d H(double xb, double yb, double zb) { return ho::R_B_H().transpose() * Eigen::Vector3d(xb, yb, zb); }

struct Runner {
  ho::OperatorServoTask task;
  std::int64_t t = 0;
  explicit Runner(const ho::OperatorTaskParams& p, ho::StationLogger* log = nullptr) : task(p, log) {}
  hs::TickOutput tick(const hs::ModelSnapshot& m, const Eigen::Vector3d& p_H, std::uint32_t buttons = 0) {
    hd::DeviceSample s;
    t += 1'000'000;
    s.t_ns = t;
    s.ee[0].position_H = p_H;
    s.ee[0].handle.buttons = buttons;
    hs::TickOutput out;
    task.tick(s, m, out);
    return out;
  }
  // Moves the stylus linearly from a to b over n ticks, then holds for hold ticks.
  hs::TickOutput move(const hs::ModelSnapshot& m, const Eigen::Vector3d& a, const Eigen::Vector3d& b, int n,
                      int hold) {
    hs::TickOutput out;
    for (int i = 1; i <= n; ++i) out = tick(m, a + (b - a) * (double(i) / n));
    for (int i = 0; i < hold; ++i) out = tick(m, b);
    return out;
  }
};

TEST(Frames, RBHIsAProperRotationWithTheDocumentedAxes) {
  const Eigen::Matrix3d R = ho::R_B_H();
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE((R * R.transpose()).isIdentity(1e-12));
  EXPECT_TRUE((R * Eigen::Vector3d(0, 0, -1)).isApprox(Eigen::Vector3d(1, 0, 0)));  // forward = -z_H
  EXPECT_TRUE((R * Eigen::Vector3d(-1, 0, 0)).isApprox(Eigen::Vector3d(0, 1, 0)));  // left = -x_H
  EXPECT_TRUE((R * Eigen::Vector3d(0, 1, 0)).isApprox(Eigen::Vector3d(0, 0, 1)));   // up = y_H
}

TEST(Exploration, WallAheadOfATurnedRobotPushesTheStylusBack) {
  // Robot at (1, 1) heading +y; wall y = 2 in W (1 m ahead). Exploration scale 50.
  ho::OperatorTaskParams p;
  Runner r(p);
  const auto snap = wall_snapshot({-1, 2}, {3, 2}, {0, -1}, {1, 1, std::numbers::pi / 2});
  // Stylus forward 20.4 mm -> 1.02 m ahead: 0.02 + probe radius 0.03 = 0.05 m past the proxy's stop.
  const double xb = 1.02 / 50.0;
  const hs::TickOutput out = r.move(*snap, H(0, 0, 0), H(xb, 0, 0), 500, 300);
  const double pen_device = 0.05 / 50.0;
  // Force back toward the user: +z_H, magnitude k * penetration (device metres).
  EXPECT_NEAR(out.command.ee[0].force_H.z(), kK * pen_device, 0.01 * kK * pen_device);
  EXPECT_NEAR(out.command.ee[0].force_H.x(), 0.0, 1e-6);
  EXPECT_NEAR(out.command.ee[0].force_H.y(), 0.0, 1e-6);
  EXPECT_NEAR(r.task.proxy().proxy_W.y(), 2.0 - p.proxy.probe_radius, 1e-6);
  EXPECT_NEAR(r.task.proxy().proxy_W.x(), 1.0, 1e-6);
  EXPECT_FALSE(r.task.last_setpoint().moves_robot);
  EXPECT_EQ(out.mode, static_cast<std::uint32_t>(hemm::wire::MODE_EXPLORATION));
  // The logged proxy (H) sits short of the device by the penetration.
  EXPECT_NEAR((out.points[0].proxy_position_H - H(xb, 0, 0)).norm(), pen_device, 1e-6);
}

TEST(Navigation, ForceRisesAsTheRobotNearsAWallAndTheCommandStopsShort) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kNavigation;
  p.navigation_point_origin_R = Eigen::Vector3d::Zero();  // the point's origin at the robot's centre
  Runner r(p);
  // Wall x = 2 in W; stylus held 30 mm forward: navigation point 0.75 m ahead (scale 25).
  const double xb = 0.030, scale = 25.0;
  std::vector<double> forces, speeds;
  bool first = true;
  for (double x : {0.8, 1.0, 1.2, 1.23, 1.25, 1.27, 1.29}) {
    const auto snap = wall_snapshot({2, -3}, {2, 3}, {-1, 0}, {x, 0, 0});
    const hs::TickOutput out =
        first ? r.move(*snap, H(0, 0, 0), H(xb, 0, 0), 300, 300) : r.move(*snap, H(xb, 0, 0), H(xb, 0, 0), 1, 300);
    first = false;
    forces.push_back(out.command.ee[0].force_H.norm());
    speeds.push_back(r.task.last_setpoint().v);
    const double pen = std::max(0.0, x + xb * scale - (2.0 - p.proxy.probe_radius));
    EXPECT_NEAR(out.command.ee[0].force_H.norm(), kK * pen / scale, 0.01) << "robot at x = " << x;
    if (pen > 0) {
      EXPECT_GT(out.command.ee[0].force_H.z(), 0.0);  // pushes the stylus back
    }
  }
  EXPECT_EQ(forces.front(), 0.0);
  for (std::size_t i = 3; i < forces.size(); ++i) EXPECT_GT(forces[i], forces[i - 1] + 0.05);
  for (std::size_t i = 3; i < speeds.size(); ++i) EXPECT_LT(speeds[i], speeds[i - 1]);
  EXPECT_TRUE(r.task.last_setpoint().moves_robot);
  // Closer still: the proxy, held by the wall, falls into the dead band: v = 0.
  const auto near = wall_snapshot({2, -3}, {2, 3}, {-1, 0}, {1.8, 0, 0});
  const hs::TickOutput out = r.move(*near, H(xb, 0, 0), H(xb, 0, 0), 1, 300);
  EXPECT_EQ(r.task.last_setpoint().v, 0.0);
  EXPECT_GT(out.command.ee[0].force_H.norm(), forces.back() * 0.99);  // still pressed (clamped to the device's limits)
}

TEST(Navigation, PointStartsAheadOfTheChassis) {
  ho::OperatorTaskParams p;  // default origin (0.35, 0, 0)
  p.initial_mode = hm::Mode::kNavigation;
  Runner r(p);
  // Wall 0.5 m ahead of a robot at the origin; stylus 10 mm forward: point at 0.35 + 0.25 = 0.6.
  const auto snap = wall_snapshot({0.5, -3}, {0.5, 3}, {-1, 0}, {0, 0, 0});
  const hs::TickOutput out = r.move(*snap, H(0, 0, 0), H(0.010, 0, 0), 200, 300);
  EXPECT_NEAR(out.command.ee[0].force_H.norm(), kK * (0.6 - 0.47) / 25.0, 0.01);
  EXPECT_EQ(r.task.last_setpoint().v, 0.0);  // proxy held 0.12 m past the origin: inside the dead band
}

TEST(Modes, ButtonsCycleAndSwitchingKeepsTheForce) {
  ho::OperatorTaskParams p;
  Runner r(p);
  const auto snap = wall_snapshot({-3, 1}, {3, 1}, {0, -1}, {0, 0, std::numbers::pi / 2});  // wall 1 m ahead
  const double xb = 1.03 / 50.0;  // 0.06 past the proxy's stop in exploration
  hs::TickOutput out = r.move(*snap, H(0, 0, 0), H(xb, 0, 0), 500, 300);
  const double f0 = out.command.ee[0].force_H.norm();
  ASSERT_GT(f0, 0.2);
  // Without re-anchoring, navigation (scale 25) would put the point
  // 0.35 + 0.515 m ahead (no contact: force 0): a jump of f0.
  EXPECT_LT(p.navigation_point_origin_R.x() + xb * 25.0, 1.0 - p.proxy.probe_radius);

  const hm::Mode order[] = {hm::Mode::kNavigation, hm::Mode::kManipulation, hm::Mode::kExploration};
  double max_step = 0.0;
  Eigen::Vector3d prev = out.command.ee[0].force_H;
  for (hm::Mode expected : order) {
    out = r.tick(*snap, H(xb, 0, 0), hd::kButton1);  // press
    EXPECT_EQ(r.task.mode(), expected);
    max_step = std::max(max_step, (out.command.ee[0].force_H - prev).norm());
    prev = out.command.ee[0].force_H;
    for (int i = 0; i < 50; ++i) {  // hold the button: no further switch
      out = r.tick(*snap, H(xb, 0, 0), hd::kButton1);
      max_step = std::max(max_step, (out.command.ee[0].force_H - prev).norm());
      prev = out.command.ee[0].force_H;
    }
    EXPECT_EQ(r.task.mode(), expected);
    out = r.tick(*snap, H(xb, 0, 0), 0);  // release
    max_step = std::max(max_step, (out.command.ee[0].force_H - prev).norm());
    prev = out.command.ee[0].force_H;
  }
  EXPECT_EQ(r.task.mode_switches(), 3u);
  // The force is continuous across switches: per-tick changes are far below f0.
  EXPECT_LT(max_step, 0.02) << "f0 " << f0;
  // Button 2 toggles exploration <-> navigation.
  r.tick(*snap, H(xb, 0, 0), hd::kButton2);
  EXPECT_EQ(r.task.mode(), hm::Mode::kNavigation);
  r.tick(*snap, H(xb, 0, 0), 0);
  r.tick(*snap, H(xb, 0, 0), hd::kButton2);
  EXPECT_EQ(r.task.mode(), hm::Mode::kExploration);
}

TEST(Modes, AnchorRelaxesAtBoundedForceRate) {
  ho::OperatorTaskParams p;
  Runner r(p);
  const auto snap = wall_snapshot({-3, 1}, {3, 1}, {0, -1}, {0, 0, std::numbers::pi / 2});
  const double xb = 1.03 / 50.0;
  hs::TickOutput out = r.move(*snap, H(0, 0, 0), H(xb, 0, 0), 500, 300);
  out = r.tick(*snap, H(xb, 0, 0), hd::kButton1);  // -> navigation
  ASSERT_EQ(r.task.mode(), hm::Mode::kNavigation);
  const double offset0 = r.task.anchor().offset_B.norm();
  ASSERT_GT(offset0, 1e-3);
  Eigen::Vector3d prev = out.command.ee[0].force_H;
  double max_step = 0.0;
  const int n = static_cast<int>(offset0 / p.relax_speed * 1000.0) + 200;
  for (int i = 0; i < n; ++i) {
    out = r.tick(*snap, H(xb, 0, 0), 0);
    max_step = std::max(max_step, (out.command.ee[0].force_H - prev).norm());
    prev = out.command.ee[0].force_H;
  }
  EXPECT_LT(r.task.anchor().offset_B.norm(), 1e-9);  // back on the natural map
  // Bounded by k * relax_speed * T (plus the damping term's share).
  EXPECT_LT(max_step, 2.0 * kK * p.relax_speed * 1e-3);
  // Natural navigation map: 0.865 m ahead, no contact.
  EXPECT_NEAR(out.command.ee[0].force_H.norm(), 0.0, 1e-9);
}

// Issue 9 item 10: a switch re-anchors the map for the force, and the
// command used to follow the re-anchored proxy: switching exploration ->
// navigation commanded -0.16 m/s with the stylus centred and 0.7 m/s with
// the exploration proxy far ahead. No motion may follow a switch until the
// hand moves (and, in navigation, the command has passed through neutral).
struct SwitchRun {
  double max_abs_v = 0.0, max_abs_omega = 0.0;
  bool any_moves = false;
  void note(const ho::StationSetpoint& sp) {
    max_abs_v = std::max(max_abs_v, std::abs(sp.v));
    max_abs_omega = std::max(max_abs_omega, std::abs(sp.omega));
    any_moves = any_moves || sp.moves_robot;
  }
};

TEST(ModeSwitch, NoMotionAfterSwitchingToNavigationWithTheStylusCentredUntilTheHandMoves) {
  ho::OperatorTaskParams p;
  Runner r(p);
  const auto free_space = wall_snapshot({20, -1}, {20, 1}, {-1, 0}, {0, 0, 0});  // nothing near
  r.move(*free_space, H(0, 0, 0), H(0, 0, 0), 1, 500);
  r.tick(*free_space, H(0, 0, 0), hd::kButton2);  // -> navigation, stylus centred
  ASSERT_EQ(r.task.mode(), hm::Mode::kNavigation);
  SwitchRun after;
  for (int i = 0; i < 1500; ++i) {
    r.tick(*free_space, H(0, 0, 0), 0);
    after.note(r.task.last_setpoint());
  }
  EXPECT_EQ(after.max_abs_v, 0.0);
  EXPECT_EQ(after.max_abs_omega, 0.0);
  EXPECT_FALSE(after.any_moves);
  // The hand pushes forward 20 mm: the robot is driven.
  r.move(*free_space, H(0, 0, 0), H(0.020, 0, 0), 200, 100);
  EXPECT_TRUE(r.task.last_setpoint().moves_robot);
  EXPECT_GT(r.task.last_setpoint().v, 0.2);
}

TEST(ModeSwitch, NoMotionAfterSwitchingToNavigationWithTheProxyFarAheadUntilTheHandReturnsThroughNeutral) {
  ho::OperatorTaskParams p;
  Runner r(p);
  const auto free_space = wall_snapshot({20, -1}, {20, 1}, {-1, 0}, {0, 0, 0});
  // Exploration: stylus 20 mm forward = the proxy 1 m ahead of the robot.
  r.move(*free_space, H(0, 0, 0), H(0.020, 0, 0), 300, 300);
  ASSERT_NEAR(r.task.proxy().proxy_W.x(), 1.0, 1e-6);
  r.tick(*free_space, H(0.020, 0, 0), hd::kButton2);  // -> navigation
  ASSERT_EQ(r.task.mode(), hm::Mode::kNavigation);
  SwitchRun held;
  for (int i = 0; i < 1500; ++i) {  // the hand stays
    r.tick(*free_space, H(0.020, 0, 0), 0);
    held.note(r.task.last_setpoint());
  }
  EXPECT_EQ(held.max_abs_v, 0.0);
  EXPECT_FALSE(held.any_moves);
  // The hand moves further forward: still no motion (it never passed neutral).
  SwitchRun further;
  for (int i = 1; i <= 200; ++i) {
    r.tick(*free_space, H(0.020 + 0.005 * i / 200.0, 0, 0), 0);
    further.note(r.task.last_setpoint());
  }
  EXPECT_EQ(further.max_abs_v, 0.0);
  EXPECT_FALSE(further.any_moves);
  // Back to the centre (through neutral), then forward: the robot is driven.
  r.move(*free_space, H(0.025, 0, 0), H(0, 0, 0), 500, 100);
  r.move(*free_space, H(0, 0, 0), H(0.020, 0, 0), 200, 100);
  EXPECT_TRUE(r.task.last_setpoint().moves_robot);
  EXPECT_GT(r.task.last_setpoint().v, 0.2);
}

TEST(ModeSwitch, NoArmMotionAfterSwitchingToManipulationUntilTheHandMoves) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kNavigation;
  Runner r(p);
  const auto free_space = wall_snapshot({20, -1}, {20, 1}, {-1, 0}, {0, 0, 0});
  r.move(*free_space, H(0, 0, 0), H(0.004, 0.003, 0), 100, 100);
  r.tick(*free_space, H(0.004, 0.003, 0), hd::kButton1);  // navigation -> manipulation
  ASSERT_EQ(r.task.mode(), hm::Mode::kManipulation);
  for (int i = 0; i < 1000; ++i) {
    r.tick(*free_space, H(0.004, 0.003, 0), 0);
    ASSERT_FALSE(r.task.last_setpoint().arm_valid) << "tick " << i;
    ASSERT_FALSE(r.task.last_setpoint().moves_robot) << "tick " << i;
  }
  r.move(*free_space, H(0.004, 0.003, 0), H(0.004, 0.003, 0.010), 100, 10);
  EXPECT_TRUE(r.task.last_setpoint().arm_valid);
  EXPECT_TRUE(r.task.last_setpoint().moves_robot);
}

// Issue 9 item 9: both device buttons together are the e-stop: counted once
// per press, no mode switch, the robot held until the hand moves again.
TEST(EStop, BothButtonsTogetherAreAnEStopAndSwitchNoMode) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kNavigation;
  Runner r(p);
  const auto free_space = wall_snapshot({20, -1}, {20, 1}, {-1, 0}, {0, 0, 0});
  r.move(*free_space, H(0, 0, 0), H(0.020, 0, 0), 200, 100);
  ASSERT_TRUE(r.task.last_setpoint().moves_robot);
  const std::uint32_t both = hd::kButton1 | hd::kButton2;
  for (int i = 0; i < 50; ++i) r.tick(*free_space, H(0.020, 0, 0), both);  // pressed and held
  EXPECT_EQ(r.task.estop_presses(), 1u);
  EXPECT_EQ(r.task.last_setpoint().estop_presses, 1u);
  EXPECT_EQ(r.task.mode(), hm::Mode::kNavigation);
  EXPECT_EQ(r.task.mode_switches(), 0u);
  EXPECT_FALSE(r.task.last_setpoint().moves_robot);
  EXPECT_EQ(r.task.last_setpoint().v, 0.0);
  for (int i = 0; i < 50; ++i) r.tick(*free_space, H(0.020, 0, 0), 0);  // released: still held
  EXPECT_FALSE(r.task.last_setpoint().moves_robot);
  r.tick(*free_space, H(0.020, 0, 0), both);  // a second press
  EXPECT_EQ(r.task.estop_presses(), 2u);
  r.tick(*free_space, H(0.020, 0, 0), 0);
  // One button alone is a mode switch, not an e-stop.
  r.tick(*free_space, H(0.020, 0, 0), hd::kButton2);
  EXPECT_EQ(r.task.estop_presses(), 2u);
  EXPECT_EQ(r.task.mode(), hm::Mode::kExploration);
}

// Issue 23 item 2: a stylus pose that is not finite (a sensor fault, a
// broken replay) holds all motion; it does not become the device origin
// (which in manipulation would send the arm to the workspace centre, and in
// navigation through the dead band would count as neutral). When the pose is
// finite again the robot stays held until the hand moves.
TEST(NonFinitePose, HoldsAllMotionAndDoesNotBecomeTheDeviceOrigin) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kManipulation;
  Runner r(p);
  const auto free_space = wall_snapshot({20, -1}, {20, 1}, {-1, 0}, {0, 0, 0});
  const Eigen::Vector3d there = H(0.010, 0.004, 0.008);
  r.move(*free_space, H(0, 0, 0), there, 200, 50);
  ASSERT_TRUE(r.task.last_setpoint().moves_robot);
  ASSERT_TRUE(r.task.last_setpoint().arm_valid);
  const Eigen::Vector3d target = r.task.last_setpoint().arm_target_R;
  for (const double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
    for (int i = 0; i < 20; ++i) {
      r.tick(*free_space, Eigen::Vector3d(bad, 0.0, 0.0));
      EXPECT_FALSE(r.task.last_setpoint().moves_robot) << "tick " << i;
      EXPECT_FALSE(r.task.last_setpoint().arm_valid) << "tick " << i;
      EXPECT_TRUE(r.task.last_setpoint().arm_target_R.allFinite());
    }
  }
  // Counted (the command sender logs and reports the count off the servo thread).
  EXPECT_EQ(r.task.nonfinite_poses(), 40u);
  EXPECT_EQ(r.task.last_setpoint().nonfinite_poses, 40u);
  // Finite again, where it was: still held (the hand has not moved).
  for (int i = 0; i < 100; ++i) r.tick(*free_space, there);
  EXPECT_FALSE(r.task.last_setpoint().moves_robot);
  // The hand moves on: the target continues from where it was, not from the origin.
  r.move(*free_space, there, there + H(0, 0, 0.004), 50, 10);
  EXPECT_TRUE(r.task.last_setpoint().moves_robot);
  EXPECT_LT((r.task.last_setpoint().arm_target_R - target).norm(), 0.05);
}

// Issue 9 item 8: a model going stale (no robot data: the robot died, the
// link went) fades its force to zero over fade_s, never in one tick, and the
// robot is held; fresh data brings the force back at the same bounded rate.
TEST(StaleModel, ForceFadesWithoutAStepAndTheRobotIsHeld) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kNavigation;
  p.navigation_point_origin_R = Eigen::Vector3d::Zero();
  Runner r(p);
  // Wall x = 0.76 ahead of the robot; data stamped at t = 0, fresh for 1 s, fade 1 s.
  auto stale = wall_snapshot({0.76, -3}, {0.76, 3}, {-1, 0}, {0, 0, 0});
  stale->have_data = true;
  stale->data_stamp_ns = 0;
  stale->stale_after_ns = 1'000'000'000;
  stale->fade_ns = 1'000'000'000;
  // Stylus 30 mm forward: the navigation point 0.75 m ahead, 0.02 m past the
  // proxy's stop at the wall (0.24 N, under the continuous rating's ramp).
  std::vector<double> f;
  std::vector<bool> moves;
  for (int i = 1; i <= 3000; ++i) {
    const hs::TickOutput out = r.tick(*stale, H(std::min(1.0, i / 300.0) * 0.030, 0, 0));
    f.push_back(out.command.ee[0].force_H.norm());
    moves.push_back(r.task.last_setpoint().moves_robot);
  }
  const double f0 = f[899];  // t = 0.9 s: still fresh
  EXPECT_NEAR(f0, 300.0 * 0.02 / 25.0, 0.01);
  EXPECT_TRUE(moves[899]);
  EXPECT_NEAR(f[1499], 0.5 * f0, 0.03 * f0);  // halfway through the fade
  EXPECT_LT(f[2000], 1e-9);                   // gone by stale_after + fade
  double max_step = 0.0;
  for (std::size_t i = 600; i < f.size(); ++i) max_step = std::max(max_step, std::abs(f[i] - f[i - 1]));
  EXPECT_LT(max_step, 1.2 * f0 * 1e-3) << "a step in the force";  // <= f0 per ms of fade
  for (std::size_t i = 1001; i < moves.size(); ++i) ASSERT_FALSE(moves[i]) << "moves at tick " << i;
  EXPECT_EQ(r.task.force_gain(), 0.0);
  // Fresh data again: the force comes back over the fade time, no step; the
  // robot stays held until the hand moves.
  auto fresh = wall_snapshot({0.76, -3}, {0.76, 3}, {-1, 0}, {0, 0, 0});
  fresh->have_data = true;
  fresh->data_stamp_ns = r.t;
  fresh->stale_after_ns = 10'000'000'000;
  fresh->fade_ns = 1'000'000'000;
  std::vector<double> g;
  for (int i = 0; i < 1200; ++i) {
    g.push_back(r.tick(*fresh, H(0.030, 0, 0)).command.ee[0].force_H.norm());
    ASSERT_FALSE(r.task.last_setpoint().moves_robot);
  }
  max_step = 0.0;
  for (std::size_t i = 1; i < g.size(); ++i) max_step = std::max(max_step, std::abs(g[i] - g[i - 1]));
  EXPECT_LT(max_step, 1.2 * f0 * 1e-3);
  EXPECT_NEAR(g[499], 0.5 * f0, 0.05 * f0);
  EXPECT_NEAR(g.back(), f0, 0.02 * f0);
}

// Issue 9 item 8: while a restarted robot is taken in (resyncing) the force
// is faded out and the robot held; when its map takes over, the view counts
// the resync (the closed-loop hand restarts its route from it).
TEST(StaleModel, ARobotRestartFadesHoldsAndIsCountedInTheView) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kNavigation;
  ho::OperatorView view;
  ho::OperatorServoTask task(p, nullptr, &view);
  auto tick = [&](const hs::ModelSnapshot& m, std::int64_t t, const Eigen::Vector3d& p_H) {
    hd::DeviceSample s;
    s.t_ns = t;
    s.ee[0].position_H = p_H;
    hs::TickOutput out;
    task.tick(s, m, out);
    return out;
  };
  auto snap = wall_snapshot({20, -3}, {20, 3}, {-1, 0}, {0, 0, 0});
  snap->have_data = true;
  snap->data_stamp_ns = 0;
  snap->stale_after_ns = 10'000'000'000;
  snap->resyncing = true;
  for (int i = 1; i <= 1500; ++i) tick(*snap, i * 1'000'000LL, H(0.01 * std::min(1.0, i / 100.0), 0, 0));
  EXPECT_EQ(task.force_gain(), 0.0);
  EXPECT_FALSE(task.last_setpoint().moves_robot);
  EXPECT_FALSE(view.valid);
  EXPECT_EQ(view.resyncs, 0u);
  auto taken = wall_snapshot({20, -3}, {20, 3}, {-1, 0}, {0, 0, 0});
  taken->have_data = true;
  taken->data_stamp_ns = 1'500'000'000;
  taken->stale_after_ns = 10'000'000'000;
  taken->resyncs = 1;
  tick(*taken, 1'501'000'000, H(0.01, 0, 0));
  EXPECT_TRUE(view.valid);
  EXPECT_EQ(view.resyncs, 1u);
  EXPECT_FALSE(task.last_setpoint().moves_robot);  // held until the hand moves again
}

TEST(Manipulation, ArmTargetFollowsTheProxyInR) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kManipulation;
  Runner r(p);
  hs::ModelSnapshot empty;
  r.move(empty, H(0, 0, 0), H(0.01, 0.005, 0.0), 100, 10);
  const ho::StationSetpoint& sp = r.task.last_setpoint();
  EXPECT_TRUE(sp.arm_valid);
  EXPECT_TRUE(sp.moves_robot);
  const hm::ManipulationMap mm =
      hm::make_manipulation_map(p.workspace, p.arm_base_R, p.arm_workspace_centre_R, p.arm_reach);
  const hm::ManipulationTarget want = hm::manipulation_target(mm, Eigen::Vector3d(0.01, 0.005, 0.0));
  EXPECT_TRUE(sp.arm_target_R.isApprox(want.p_R, 1e-9)) << sp.arm_target_R.transpose() << " vs "
                                                         << want.p_R.transpose();
}

// Manipulation through the model (issue 13): with the live voxmap the point
// probe runs at the tool tip and the arm target is its proxy, so pressing
// the stylus into a seat leaves the target on the seat's top + the tool
// radius (not at the stylus's point below it), the operator feels the
// push back, and the tick stays allocation-free.
TEST(Manipulation, WithTheVoxmapTheArmTargetIsTheToolProbesProxyOnTheSurface) {
  ho::OperatorTaskParams p;
  p.initial_mode = hm::Mode::kManipulation;
  p.probe_3d = true;
  p.probe3d.force = p.proxy;
  p.probe3d.force.probe_radius = 0.01;
  p.arm_base_R = {0.08, 0.0, 0.36};
  p.arm_workspace_centre_R = {0.42, 0.0, 0.56};
  p.arm_reach = 0.44;
  Runner r(p);
  // A seat 0.6 x 0.6 m, top at z 0.46 under the tool (robot at the origin of W).
  const auto snap = box_voxmap_snapshot(Eigen::Vector3d(0.5, 0.0, 0.36), 7);
  ASSERT_TRUE(snap);
  const double scale = r.task.map_of(hm::Mode::kManipulation).scale;
  const double z_goal = 0.46 + p.tool_probe_radius - 0.02;  // 2 cm (W) into the tool's cushion
  const Eigen::Vector3d press_B(0, 0, (z_goal - 0.56) / scale);
  const auto out = r.move(*snap, H(0, 0, 0.003), H(press_B.x(), press_B.y(), press_B.z()), 1500, 300);
  const ho::StationSetpoint& sp = r.task.last_setpoint();
  ASSERT_TRUE(sp.arm_valid);
  EXPECT_TRUE(r.task.tool_probe().contact);
  EXPECT_NEAR(sp.arm_target_R.z(), 0.46 + p.tool_probe_radius, 0.002) << sp.arm_target_R.transpose();
  EXPECT_NEAR(sp.arm_target_R.x(), 0.42, 0.002);
  const Eigen::Vector3d F_B = ho::R_B_H() * out.command.ee[0].force_H;
  EXPECT_GT(F_B.z(), 0.5 * kK * 0.02 / scale);  // the spring on 2 cm of W, device side
  // Sliding on it allocates nothing.
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  r.move(*snap, H(press_B.x(), press_B.y(), press_B.z()), H(press_B.x(), press_B.y() - 0.02, press_B.z()), 1000, 0);
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  EXPECT_NEAR(r.task.last_setpoint().arm_target_R.z(), 0.46 + p.tool_probe_radius, 0.002);
  const hs::TickOutput last = r.tick(*snap, H(press_B.x(), press_B.y() - 0.02, press_B.z()));
  EXPECT_STREQ(last.renderer, "point_probe");
  EXPECT_EQ(last.work, static_cast<std::int64_t>(r.task.tool_probe().work));
  EXPECT_GT(last.work, 0);
}

// The 6-DoF tool on a voxmap: its VPS work in the tick is bounded by the
// time budget (the cost per unit measured at start), reported as the tick's
// renderer and work; with the deadline already gone it does an eighth of
// the budget's work, not none; no allocation.
TEST(Tool6, TheTimeBudgetBoundsTheToolsWorkAndTheTickNamesIt) {
  ho::OperatorTaskParams p;
  p.tool6.enabled = true;
  p.tool6.tick_budget_ns = 100'000;
  ho::OperatorServoTask task(p);
  const ho::Tool6Explorer& tool = *task.tool6();
  ASSERT_GT(tool.calibration().samples, 0);
  ASSERT_GT(tool.budget().stats().calibrated_ns_per_unit, 0.0);
  // A block whose top is at z 0.85 under H's origin (R x 0.85, z 0.95).
  const auto snap = box_voxmap_snapshot(Eigen::Vector3d(0.85, 0.0, 0.75), 4);
  ASSERT_TRUE(snap);
  hd::DeviceSample s;
  s.end_effectors = 1;
  s.ee[0].enabled = true;
  s.ee[0].position_H = Eigen::Vector3d(0, 0, 0.87 - 0.95);  // the tip (radius 20 mm) 2 cm above the top
  hs::TickOutput out;
  for (int i = 0; i < 50; ++i) {  // warm up, the tool lowered 25 mm: 5 mm into the top
    s.t_ns += 1'000'000;
    s.ee[0].position_H.z() -= 0.0005;
    out = hs::TickOutput{};
    task.tick(s, *snap, out);
  }
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int i = 0; i < 200; ++i) {
    s.t_ns += 1'000'000;
    out = hs::TickOutput{};
    task.tick(s, *snap, out);
  }
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  EXPECT_STREQ(out.renderer, "tool6");
  EXPECT_EQ(out.work, tool.work());
  EXPECT_GT(tool.state().contact.contacts, 0);
  EXPECT_GT(out.work, 0);
  const double c = tool.budget().stats().ns_per_unit;
  // No tick had more than its time at the lowest cost per unit the run saw.
  EXPECT_LE(out.work, std::min<std::int64_t>(p.tool6.budget,
                                             static_cast<std::int64_t>(100'000 / tool.budget().stats().min_ns_per_unit) + 1));
  EXPECT_EQ(tool.budget().stats().ticks, 250u);
  out = hs::TickOutput{};
  out.deadline_ns = 1;  // long gone
  task.tick(s, *snap, out);
  EXPECT_GT(out.work, 0);
  EXPECT_LE(out.work, std::max(static_cast<std::int64_t>(12'500 / c) + 1, hemm::vps::coarsest_level_work(tool.tool().shell)));
}

// Issue 23 item 7: the 6-DoF tool's contact state belongs to one voxmap
// build. A new build published at the address of the old one (freed, and
// its memory reused) is a new voxmap: the pair state starts again.
TEST(Tool6, ContactStateIsKeyedOnTheVoxmapBuildNotOnItsAddress) {
  ho::OperatorTaskParams p;
  p.tool6.enabled = true;
  Runner r(p);
  ASSERT_NE(r.task.tool6(), nullptr);
  hemm::vps::VoxmapParams vp;
  vp.voxel_size = 0.01;
  auto build = [&](double top) {
    hemm::mesh::TriangleMesh m = hemm::mesh::make_box({0.1, 0.1, 0.05}, 2);
    for (auto& v : m.vertices) v += Eigen::Vector3d(0.85, 0.0, top - 0.05);
    auto vm = std::make_shared<hemm::vps::Voxmap>();
    EXPECT_FALSE(hemm::vps::build_voxmap(m, vp, vm.get(), nullptr));
    return vm;
  };
  auto vm = build(0.93);  // the tool's tip (radius 2 cm at z 0.95) rests on its top
  auto snap = std::make_unique<ho::OperatorModelSnapshot>();
  snap->map = hmap::build_snapshot(hmap::MapParams{}, hmap::LocalMap{});
  snap->have_state = true;
  snap->version = 1;
  snap->voxmap = vm;
  snap->voxmap_builds = 1;
  for (int i = 0; i < 50; ++i) r.tick(*snap, Eigen::Vector3d::Zero());
  const std::uint64_t changes = r.task.tool6()->state().voxmap_changes;
  // Build 2 (the box 5 mm higher) lands where build 1 was.
  *vm = *build(0.935);
  snap->version = 2;
  snap->voxmap_builds = 2;
  r.tick(*snap, Eigen::Vector3d::Zero());
  EXPECT_EQ(r.task.tool6()->state().voxmap_changes, changes + 1) << "the old build's contact state was kept";
  // Later ticks of the same build keep it.
  for (int i = 0; i < 10; ++i) r.tick(*snap, Eigen::Vector3d::Zero());
  EXPECT_EQ(r.task.tool6()->state().voxmap_changes, changes + 1);
}

TEST(Tick, NeverAllocatesOrFrees) {
  ho::OperatorTaskParams p;
  auto log = ho::make_station_logger(256);  // not started: pushes fill the ring, then count drops
  Runner r(p, &log);
  const auto snap = wall_snapshot({-3, 1}, {3, 1}, {0, -1}, {0, 0, std::numbers::pi / 2});
  r.move(*snap, H(0, 0, 0), H(0.001, 0, 0), 10, 0);  // warm up
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  const std::uint64_t frees_before = hemm::test::counted_frees();
  for (int i = 0; i < 3000; ++i) {
    const double s = std::sin(i * 0.005);
    const std::uint32_t buttons = (i / 500) % 2 == 1 ? hd::kButton1 : (i % 700 < 20 ? hd::kButton1 | hd::kButton2 : 0u);
    r.tick(*snap, H(0.022 * s, 0.01 * s, 0), buttons);
  }
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  const std::uint64_t frees = hemm::test::counted_frees() - frees_before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(frees, 0u);
  // What rendered the tick, and its work (the proxy's surface evaluations).
  const hs::TickOutput out = r.tick(*snap, H(0, 0, 0));
  EXPECT_STREQ(out.renderer, "proxy2d");
  EXPECT_EQ(out.work, static_cast<std::int64_t>(r.task.proxy().work));
  EXPECT_GT(out.work, 0);
  EXPECT_GE(r.task.mode_switches(), 2u);
  EXPECT_GE(r.task.estop_presses(), 2u);
}

// The 3D probe's position for the live voxmap's ROI (ModelThread::
// probe_positions): every tick, the proxy in W and whether the probe is in
// use (exploration with probe_3d); a copy and an atomic exchange, no allocation.
TEST(Probe3d, PublishesWhereTheProbeIsWithoutAllocating) {
  ho::OperatorTaskParams p;
  p.probe_3d = true;
  p.probe3d.force.probe_radius = 0.01;
  Runner r(p);
  hemm::NewestMailbox<ho::ProbePosition> box;
  r.task.set_probe_output(&box);
  const auto snap = wall_snapshot({-3, 1}, {3, 1}, {0, -1}, {1.5, 1.0, std::numbers::pi / 2});
  r.tick(*snap, H(0, 0, 0));
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  r.move(*snap, H(0, 0, 0), H(0.01, -0.01, 0.005), 200, 0);
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  const ho::ProbePosition* pos = box.take();
  ASSERT_NE(pos, nullptr);
  EXPECT_TRUE(pos->active);
  EXPECT_STREQ(r.tick(*snap, H(0.01, -0.01, 0.005)).renderer, "point_probe");
  EXPECT_TRUE(pos->p_W.isApprox(r.task.probe3d().proxy_W, 1e-12));
  // No voxmap: the proxy is at the goal, the stylus mapped around the robot
  // at W (1.5, 1.0) facing +y (centred: 0.9 m ahead, 0.85 m high).
  EXPECT_NEAR(pos->p_W.z(), 0.85 + 0.005 * r.task.probe3d_map().scale, 1e-9);
  // Navigation: no probe, the voxmap's ROI goes back ahead of the robot.
  r.tick(*snap, H(0.01, -0.01, 0.005), hd::kButton1);
  EXPECT_EQ(r.task.mode(), hm::Mode::kNavigation);
  pos = box.take();
  ASSERT_NE(pos, nullptr);
  EXPECT_FALSE(pos->active);
}

TEST(Task, RejectsBadParams) {
  ho::OperatorTaskParams p;
  p.exploration_range = -1;
  EXPECT_THROW(ho::OperatorServoTask t(p), std::invalid_argument);
  p = {};
  p.proxy.stiffness = 1e6;
  EXPECT_THROW(ho::OperatorServoTask t(p), std::invalid_argument);
}

}  // namespace
