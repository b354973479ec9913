// The live view's command-line options, shared by hemm-operator and
// hemm-robot (--view, --view-png DIR, --view-interval S, --view-fps HZ,
// --view-size WxH, --view-top X,Y,DIST). CLI11 stays in the .cpp.
#pragma once

#include <optional>
#include <string>

#include "common/view/mujoco_window.h"

namespace CLI {
class App;
}

namespace hemm::view {

struct ViewOptions {
  bool window = false;          // --view: a window on the display
  std::string png_dir;          // --view-png: write PNGs here
  double png_interval_s = 1.0;  // --view-interval
  double fps = 30.0;            // --view-fps: window frame rate
  int width = 640, height = 480;
  // --view-top: a fixed top-down camera over (X, Y) at DIST metres (tests,
  // reproducible pictures); the mouse still moves it.
  std::optional<CameraSpec> top;
  bool enabled() const { return window || !png_dir.empty(); }
};

// Adds the options; the returned callback-free strings are parsed by
// finish_view_options after app.parse().
struct ViewOptionStrings {
  std::string size = "640x480";
  std::string top;
};
void add_view_options(CLI::App& app, ViewOptions* o, ViewOptionStrings* s);
// Parses the strings into o; returns a one-line error for a bad value.
std::optional<std::string> finish_view_options(const ViewOptionStrings& s, ViewOptions* o);

// A top-down camera over (x, y) at `distance` (elevation -90, +y up in the picture).
CameraSpec top_down_camera(double x, double y, double distance);
// A camera looking at the origin (until it follows something) from
// `distance`, at azimuth and elevation in degrees.
CameraSpec orbit_camera(double distance, double azimuth, double elevation);

}  // namespace hemm::view
