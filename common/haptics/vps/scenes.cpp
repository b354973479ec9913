#include "common/haptics/vps/scenes.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "common/mesh/primitives.h"

namespace hemm::vps {

namespace {

constexpr double mm = 1e-3;

Eigen::Isometry3d pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

// Smooth 0 -> 1 over [t0, t1] (cosine), for hand paths without jerks.
double ramp(double t, double t0, double t1) {
  if (t <= t0) return 0.0;
  if (t >= t1) return 1.0;
  return 0.5 - 0.5 * std::cos(std::numbers::pi * (t - t0) / (t1 - t0));
}

}  // namespace

BimanualScene make_peg_in_hole_scene() {
  BimanualScene s;
  s.name = "peg-in-hole";
  // Table: 300 x 200 x 20 mm, its top 1 mm below the holes object.
  mesh::append_mesh(&s.scene, mesh::make_box({0.15, 0.1, 0.01}, 2), pose({0, 0, -0.016 - 0.01}));
  // Pins: plate z in [0, 10] mm, pins below down to -25 mm, at x = +-20 mm.
  s.right = mesh::make_rectilinear_solid({-40 * mm, -25 * mm, -15 * mm, 15 * mm, 25 * mm, 40 * mm},
                                         {-20 * mm, -5 * mm, 5 * mm, 20 * mm}, {-25 * mm, 0.0, 10 * mm},
                                         [](int i, int j, int k) { return k == 1 || ((i == 1 || i == 3) && j == 1); });
  // Holes: z in [-15, 15] mm, 12 x 12 mm through holes at x = +-20 mm.
  s.left = mesh::make_rectilinear_solid({-40 * mm, -26 * mm, -14 * mm, 14 * mm, 26 * mm, 40 * mm},
                                        {-20 * mm, -6 * mm, 6 * mm, 20 * mm}, {-15 * mm, 15 * mm},
                                        [](int i, int j, int) { return !((i == 1 || i == 3) && j == 1); });
  return s;
}

BimanualPoses peg_in_hole_hands(double t) {
  BimanualPoses p;
  p.left = pose(Eigen::Vector3d::Zero());
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(0.4 * std::numbers::pi / 180, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d start(0.4 * mm, -0.3 * mm, 50 * mm);  // pin tips 10 mm above the holes
  const double z_end = 13 * mm;  // 2 mm below plate-on-block contact: the hand presses the plate down
  const double speed = 0.03;
  const double frac = std::clamp(speed * std::max(t, 0.0) / (start.z() - z_end), 0.0, 1.0);
  p.right = pose({start.x() + 1.2 * mm * frac, start.y(), start.z() - frac * (start.z() - z_end)}, tilt);
  return p;
}

BimanualScene make_assembly_scene(int bosses, const AssemblyLayout& L) {
  BimanualScene s;
  s.name = "assembly";
  bosses = std::max(bosses, 1);
  const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(bosses))));
  const auto ball = mesh::make_icosphere(L.boss_radius, 6);
  double xmax = 0, ymax = 0;
  for (int i = 0; i < bosses; ++i) {
    const Eigen::Vector3d c((i % cols) * L.boss_spacing, (i / cols) * L.boss_spacing, 0.0);
    mesh::append_mesh(&s.scene, ball, pose(c));
    xmax = std::max(xmax, c.x());
    ymax = std::max(ymax, c.y());
  }
  // Floor slab under the bosses with the tank's pocket.
  const Eigen::Vector3d& pc = L.pocket_centre;
  const Eigen::Vector3d& ph = L.pocket_half;
  const double x0 = pc.x() - ph.x() - 0.15, x1 = xmax + L.boss_spacing;
  const double y0 = -L.boss_spacing, y1 = ymax + L.boss_spacing;
  mesh::append_mesh(&s.scene,
                    mesh::make_rectilinear_solid({x0, pc.x() - ph.x(), pc.x() + ph.x(), x1},
                                                 {y0, pc.y() - ph.y(), pc.y() + ph.y(), y1},
                                                 {L.slab_top - 2 * ph.z() - 0.03, L.slab_top - 2 * ph.z(), L.slab_top},
                                                 [](int i, int j, int k) { return !(i == 1 && j == 1 && k == 1); }));
  s.right = mesh::make_box(L.tank_half, 46);
  s.left = mesh::make_icosphere(L.drill_ball_radius, 5);
  mesh::append_mesh(&s.left, mesh::make_box(L.handle_half, 35),
                    pose({0, 0, L.drill_ball_radius + 0.001 + L.handle_half.z()}));
  return s;
}

BimanualPoses assembly_hands(double t, const AssemblyLayout& L) {
  BimanualPoses p;
  // Right: the tank from 50 mm above the slab into the pocket at 40 mm/s,
  // the 1 mm / 1 degree misalignment taken out during the descent, then 2 mm
  // of press onto the pocket floor.
  const double z_start = L.slab_top + 0.05 + L.tank_half.z();
  const double z_end = L.slab_top - 2 * L.pocket_half.z() + L.tank_half.z() - 0.002;
  const double descend = (z_start - z_end) / 0.04;
  const double a = ramp(t, 0.2, 0.2 + descend);
  const double yaw = (1.0 - ramp(t, 0.2, 0.2 + 0.8 * descend)) * std::numbers::pi / 180;
  const Eigen::Vector3d off = (1.0 - ramp(t, 0.2, 0.2 + 0.8 * descend)) * Eigen::Vector3d(0.001, 0.0005, 0.0);
  p.right = pose(Eigen::Vector3d(L.pocket_centre.x(), L.pocket_centre.y(), z_start + a * (z_end - z_start)) + off,
                 Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  // Left: the drill's ball onto the flank of boss 0 (45 degrees up, handle
  // pointing away), 1.5 mm of press, slid 40 degrees round the boss, off.
  const double Rsum = L.boss_radius + L.drill_ball_radius;
  const double az = (-20.0 + 40.0 * ramp(t, 2.5, 4.5)) * std::numbers::pi / 180;
  const double el = std::numbers::pi / 4;
  const Eigen::Vector3d u(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  const Eigen::Vector3d far(0.25, -0.15, 0.25);
  const double dist = Rsum + 0.01 - (0.01 + 0.0015) * ramp(t, 1.5, 2.5) + (0.05 + 0.0015) * ramp(t, 4.5, 5.5);
  const Eigen::Vector3d near = dist * u;
  const double b = ramp(t, 0.0, 1.5);
  // Handle along u (tool z to u).
  const Eigen::Matrix3d R = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), u).toRotationMatrix();
  p.left = pose(far + b * (near - far), R);
  return p;
}

}  // namespace hemm::vps
