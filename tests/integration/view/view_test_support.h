// What the live view tests share: a pinhole camera built from a PNG's
// camera text (to project W points into the picture), a pixel search, Xvfb
// on a display of its own, and the numbered pictures of a PNG directory.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/view/png_io.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {

// A pinhole camera as MuJoCo's free camera is documented: forward from
// azimuth/elevation, the camera at lookat - distance * forward, up
// perpendicular to forward in the vertical plane, vertical field of view fovy.
struct Camera {
  Eigen::Vector3d pos, forward, up, right;
  double f_px = 0;  // focal length in pixels
  int width = 0, height = 0;

  static std::optional<Camera> from_text(const std::string& text, int width, int height) {
    std::istringstream in(text);
    double lx, ly, lz, dist, az, el, fovy;
    if (!(in >> lx >> ly >> lz >> dist >> az >> el >> fovy)) return std::nullopt;
    const double a = az * std::numbers::pi / 180, e = el * std::numbers::pi / 180;
    Camera c;
    c.forward = Eigen::Vector3d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
    c.up = Eigen::Vector3d(-std::sin(e) * std::cos(a), -std::sin(e) * std::sin(a), std::cos(e));
    c.right = c.forward.cross(c.up);
    c.pos = Eigen::Vector3d(lx, ly, lz) - dist * c.forward;
    c.f_px = 0.5 * height / std::tan(0.5 * fovy * std::numbers::pi / 180);
    c.width = width;
    c.height = height;
    return c;
  }
  // Pixel (column, row from the top) of a W point.
  Eigen::Vector2d project(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d v = p - pos;
    const double z = v.dot(forward);
    return Eigen::Vector2d(0.5 * width + f_px * v.dot(right) / z, 0.5 * height - f_px * v.dot(up) / z);
  }
};

// Any pixel within `radius` of (u, v) of the class.
template <class Pred>
inline bool near(const view::Image& img, const Eigen::Vector2d& uv, int radius, Pred pred) {
  for (int dy = -radius; dy <= radius; ++dy)
    for (int dx = -radius; dx <= radius; ++dx) {
      const int x = static_cast<int>(std::lround(uv.x())) + dx, y = static_cast<int>(std::lround(uv.y())) + dy;
      if (x >= 0 && y >= 0 && x < img.width && y < img.height && pred(img.at(x, y))) return true;
    }
  return false;
}

// Xvfb on a display it picks itself (-displayfd), for this test only.
class Xvfb {
 public:
  explicit Xvfb(const std::string& dir)
      : out_(dir + "/xvfb.out"),
        proc_({"/usr/bin/Xvfb", "-displayfd", "1", "-screen", "0", "1024x768x24", "-nolisten", "tcp"}, out_,
              dir + "/xvfb.err") {
    for (int i = 0; i < 100 && display_.empty(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      const std::string s = read_file(out_);
      if (!s.empty() && s.back() == '\n') display_ = ":" + s.substr(0, s.size() - 1);
    }
  }
  ~Xvfb() { proc_.signal(SIGTERM); proc_.wait(std::chrono::seconds(5)); }
  const std::string& display() const { return display_; }

 private:
  std::string out_;
  ChildProcess proc_;
  std::string display_;
};

// This process's children draw on xvfb's display with software OpenGL and
// one rasterizer thread: the view must not starve the 1 kHz threads on two
// cores.
inline void use_software_display(const Xvfb& xvfb) {
  ::setenv("DISPLAY", xvfb.display().c_str(), 1);
  ::setenv("LIBGL_ALWAYS_SOFTWARE", "1", 1);
  ::setenv("LP_NUM_THREADS", "1", 1);
}

// Xvfb for a test in `dir`, its display used by this process's children;
// an error message if it is not installed or does not start.
inline std::optional<std::string> start_test_display(const std::string& dir, std::unique_ptr<Xvfb>* out) {
  if (!std::filesystem::exists("/usr/bin/Xvfb")) return "Xvfb is needed (Debian package xvfb; deploy/run.sh installs it)";
  *out = std::make_unique<Xvfb>(dir);
  if ((*out)->display().empty()) return "Xvfb did not start: " + read_file(dir + "/xvfb.err");
  use_software_display(**out);
  return std::nullopt;
}

inline std::vector<std::string> pngs_in(const std::string& dir) {
  std::vector<std::string> out;
  if (!std::filesystem::is_directory(dir)) return out;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().filename().string().rfind("view_0", 0) == 0) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace hemm::test
