#include "common/view/view_options.h"

#include <CLI/CLI.hpp>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace hemm::view {
namespace {

// Splits on `sep` and parses each part as a finite number (nothing else on it).
std::optional<std::vector<double>> numbers(const std::string& s, char sep) {
  std::vector<double> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = s.find(sep, start);
    const std::string t = s.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (t.empty() || t.front() == ' ') return std::nullopt;
    char* stop = nullptr;
    errno = 0;
    const double v = std::strtod(t.c_str(), &stop);
    if (errno != 0 || stop != t.c_str() + t.size() || !std::isfinite(v)) return std::nullopt;
    out.push_back(v);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

}  // namespace

void add_view_options(CLI::App& app, ViewOptions* o, ViewOptionStrings* s) {
  app.add_flag("--view", o->window, "open the live view: a 3D window (MuJoCo renderer, GLFW) on the display");
  app.add_option("--view-png", o->png_dir,
                 "write the live view as PNG files into this directory (view_NNNNN.png every --view-interval "
                 "seconds, view_last.png at exit); without --view the view renders offscreen (needs an X display, "
                 "e.g. Xvfb)");
  app.add_option("--view-interval", o->png_interval_s, "seconds between PNGs of the live view (default 1)")
      ->check(CLI::Range(0.05, 3600.0));
  app.add_option("--view-fps", o->fps, "frame rate of the live view's window, 1..60 (default 30)")
      ->check(CLI::Range(1.0, 60.0));
  app.add_option("--view-size", s->size, "size of the live view's window and PNGs, WxH pixels (default 640x480)");
  app.add_option("--view-top", s->top,
                 "X,Y,DIST: start the live view's camera straight down over (X, Y) of W from DIST metres "
                 "(+x right, +y up in the picture)");
}

std::optional<std::string> finish_view_options(const ViewOptionStrings& s, ViewOptions* o) {
  const auto wh = numbers(s.size, 'x');
  if (!wh || wh->size() != 2 || (*wh)[0] != std::floor((*wh)[0]) || (*wh)[1] != std::floor((*wh)[1]) ||
      (*wh)[0] < 64 || (*wh)[1] < 64 || (*wh)[0] > 4096 || (*wh)[1] > 4096)
    return "--view-size '" + s.size + "': expected WxH, whole pixels in 64..4096";
  o->width = static_cast<int>((*wh)[0]);
  o->height = static_cast<int>((*wh)[1]);
  if (!s.top.empty()) {
    const auto t = numbers(s.top, ',');
    if (!t || t->size() != 3 || !((*t)[2] > 0.1 && (*t)[2] <= 1000.0))
      return "--view-top '" + s.top + "': expected X,Y,DIST (metres; DIST in (0.1, 1000])";
    o->top = top_down_camera((*t)[0], (*t)[1], (*t)[2]);
  }
  return std::nullopt;
}

CameraSpec top_down_camera(double x, double y, double distance) {
  CameraSpec c;
  c.lookat = Eigen::Vector3d(x, y, 0.0);
  c.distance = distance;
  c.azimuth = 90.0;
  c.elevation = -90.0;
  return c;
}

CameraSpec orbit_camera(double distance, double azimuth, double elevation) {
  CameraSpec c;
  c.distance = distance;
  c.azimuth = azimuth;
  c.elevation = elevation;
  return c;
}

}  // namespace hemm::view
