#pragma once
// Ground truth for the virtual proxy: exact 2D geometry (segments, closed
// polygons, solid circles; all extruded vertically without limit) and the same
// god-object run against it, so the force rendered from the scan-built local
// model can be compared with the force the true scene would give along the
// same device path. Also an exact ray cast, to synthesise range scans.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/haptics/proxy/virtual_proxy.h"

namespace hemm::haptics {

struct ExactSegment {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
};
struct ExactCircle {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  double radius = 0.0;  // solid disc
};

// Segments are two-sided thin walls; a polygon is added as its closed boundary.
struct ExactScene {
  std::vector<ExactSegment> segments;
  std::vector<ExactCircle> circles;
};

void add_polygon(ExactScene& scene, const std::vector<Eigen::Vector2d>& vertices);
// Axis-aligned box (as a polygon) and a thin wall of given thickness between two points.
void add_box(ExactScene& scene, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi);
void add_thick_wall(ExactScene& scene, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double thickness);

// Nearest hit along origin + t dir (dir need not be unit; t in units of |dir|
// scaled to metres), or nullopt. Returns the distance in metres.
std::optional<double> raycast(const ExactScene& scene, const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                              double max_range);

// Exact signed-free distance from p to the scene's surfaces (>= 0 outside; for
// circles negative inside).
double distance_to_scene(const ExactScene& scene, const Eigen::Vector2d& p);

// The god-object tick against the exact scene (same algorithm, same data).
void reference_tick(const ProxyModel& m, const ExactScene& scene, ProxyData& d, const Eigen::Vector3d& device_W,
                    double scale);

struct ForceError {
  double rms = 0.0;     // N
  double max = 0.0;     // N
  std::size_t count = 0;
  bool valid = true;    // false if the sequences differ in length
};
ForceError force_error(const std::vector<Eigen::Vector3d>& rendered, const std::vector<Eigen::Vector3d>& truth);

}  // namespace hemm::haptics
