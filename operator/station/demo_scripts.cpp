#include "operator/station/demo_scripts.h"

namespace hemm::op {
namespace {
// B (x forward, y left, z up) -> H (x right, y up, z towards the user).
Eigen::Vector3d h_from_b(double xb, double yb, double zb) { return {-yb, zb, -xb}; }
}  // namespace

std::vector<std::string> demo_script_names() { return {"idle", "nav-to-wall", "probe-cylinder"}; }

DemoScript make_demo_script(std::string_view name) {
  DemoScript d;
  if (name == "idle") {
    d.hand = std::make_shared<device::HoldScript>(Eigen::Vector3d::Zero());
    d.mode = math::Mode::kExploration;
  } else if (name == "nav-to-wall") {
    d.hand = std::make_shared<device::LineScript>(Eigen::Vector3d::Zero(), h_from_b(0.025, 0.0, 0.0), 0.02, 1.0);
    d.mode = math::Mode::kNavigation;
    d.duration_s = 12.0;
  } else if (name == "probe-cylinder") {
    constexpr double s = 50.0;  // exploration: 4 m over 0.08 m
    auto b = [](double xw, double yw) { return h_from_b(xw / s, yw / s, 0.0); };
    std::vector<device::Waypoint> w;
    w.push_back({0.0, Eigen::Vector3d::Zero(), 0});
    w.push_back({1.0, Eigen::Vector3d::Zero(), 0});
    // 8 cm west of the bin's centre line, so the proxy slides round its side.
    w.push_back({3.0, b(1.42, -0.8), 0});
    w.push_back({9.0, b(1.42, -1.6), 0});
    w.push_back({15.0, b(1.42, -0.8), 0});
    w.push_back({17.0, Eigen::Vector3d::Zero(), 0});
    d.hand = std::make_shared<device::WaypointScript>(std::move(w));
    d.mode = math::Mode::kExploration;
    d.duration_s = 17.0;
  }
  return d;
}

}  // namespace hemm::op
