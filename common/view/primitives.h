// What a live view draws beyond its MuJoCo model: a list of simple shapes in
// W (boxes, spheres, cylinders, arrows, lines), overlay text and the camera,
// built by plain code that needs no OpenGL (so it is unit-tested without a
// display) and handed to MujocoWindow, which turns each shape into an mjvGeom.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

namespace hemm::view {

struct Rgba {
  float r = 1, g = 1, b = 1, a = 1;
};

enum class Shape { kBox, kSphere, kCylinder, kArrow, kLine, kCapsule };

struct Primitive {
  Shape shape = Shape::kBox;
  // Box, sphere, cylinder: centre, orientation, MuJoCo's size (box: half
  // extents; sphere: radius; cylinder: radius, half height).
  Eigen::Vector3d pos = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  // Arrow, line and capsule: from pos to `to`; width in m (arrow), pixels
  // (line) or the radius in m (capsule).
  Eigen::Vector3d to = Eigen::Vector3d::Zero();
  double width = 0.0;
  Rgba rgba;
};

// MuJoCo's free camera: looks at `lookat` from `distance`, azimuth and
// elevation in degrees (elevation -90: straight down, with +y up in the picture
// when azimuth is 90).
struct CameraSpec {
  Eigen::Vector3d lookat = Eigen::Vector3d::Zero();
  double distance = 5.0;
  double azimuth = 90.0;
  double elevation = -45.0;
};

struct Banner {
  std::string text;
  Rgba colour;
};

// A small plot in the bottom right corner (MuJoCo's mjr_figure): lines of
// points, a title and an x label; the axes fit the data.
struct PlotLine {
  std::string name;
  Rgba colour;
  std::vector<float> x, y;  // equal lengths; at most 1000 points are drawn
};
struct OverlayPlot {
  std::string title, xlabel;
  std::vector<PlotLine> lines;  // at most 8 are drawn
  float x_min = 0, x_max = 0;   // x_min >= x_max: fit the data
};

struct Overlay {
  std::string left, right;      // two columns, top left
  std::string bottom;           // one line, bottom left (key help)
  std::vector<Banner> banners;  // top right, one under the other
  OverlayPlot plot;             // drawn when it has a line with points
};

class PrimitiveList {
 public:
  void clear() { items_.clear(); }
  // A box with half extents `half`, turned by yaw (rad) about z.
  void box(const Eigen::Vector3d& centre, double yaw, const Eigen::Vector3d& half, Rgba c);
  // A box with half extents `half` along the columns of R.
  void box(const Eigen::Vector3d& centre, const Eigen::Matrix3d& R, const Eigen::Vector3d& half, Rgba c);
  void sphere(const Eigen::Vector3d& centre, double radius, Rgba c);
  // A vertical cylinder standing on z = centre.z() - half_height.
  void cylinder(const Eigen::Vector3d& centre, double radius, double half_height, Rgba c);
  // Nothing for a zero-length arrow.
  void arrow(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width, Rgba c);
  void line(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width_px, Rgba c);
  // A capsule of `radius` between two points (a sphere if they coincide).
  void capsule(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double radius, Rgba c);
  const std::vector<Primitive>& items() const { return items_; }
  std::size_t size() const { return items_.size(); }

 private:
  void connector(Shape shape, const Eigen::Vector3d& from, const Eigen::Vector3d& to, double width, Rgba c);
  std::vector<Primitive> items_;
};

}  // namespace hemm::view
