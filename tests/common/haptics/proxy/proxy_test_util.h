#pragma once
// Test helpers for the proxy: maps from exact segments, and a SIMULATED
// device + hand (mass-spring-damper) driven at 1 kHz.
#include <vector>

#include <Eigen/Core>

#include "common/haptics/proxy/reference_scene.h"
#include "common/haptics/proxy/virtual_proxy.h"
#include "common/mapping/local_map.h"

namespace hemm::test {

// A snapshot straight from exact segments (normals toward `view`).
inline mapping::MapSnapshot snapshot_of(const haptics::ExactScene& scene, const Eigen::Vector2d& view,
                                        double cell = 0.25) {
  mapping::LocalMap map;
  for (const haptics::ExactSegment& e : scene.segments) {
    mapping::Segment2 s;
    s.a = e.a;
    s.b = e.b;
    Eigen::Vector2d n(-(e.b - e.a).y(), (e.b - e.a).x());
    n.normalize();
    if (n.dot(view - 0.5 * (e.a + e.b)) < 0) n = -n;
    s.normal = n;
    map.segments.push_back(s);
  }
  mapping::MapParams p;
  p.cell_size = cell;
  return mapping::build_snapshot(p, map);
}

// SIMULATED device + hand: the stylus (mass m) is held by the hand through a
// spring-damper toward a target; the rendered force acts on it (held constant
// over the 1 ms servo period, integrated in 10 sub-steps).
struct SimHand {
  double mass = 0.08;    // kg
  double k_hand = 150;   // N/m
  double b_hand = 1.5;   // N s/m
  Eigen::Vector2d x = Eigen::Vector2d::Zero();  // device metres
  Eigen::Vector2d v = Eigen::Vector2d::Zero();
  void step(const Eigen::Vector2d& target, const Eigen::Vector2d& force, double T) {
    const int sub = 10;
    const double h = T / sub;
    for (int i = 0; i < sub; ++i) {
      const Eigen::Vector2d a = (k_hand * (target - x) - b_hand * v + force) / mass;
      v += h * a;
      x += h * v;
    }
  }
};

}  // namespace hemm::test
