#pragma once
// The virtual proxy of HEMM Sec. 3.2 as a 2D god-object (constraint-based
// proxy, Zilles & Salisbury 1995) against the local map's segments, extruded
// vertically without limit: the probe's z is free (walls are vertical), so
// all constraints and forces live in the horizontal plane of W.
//
// The proxy is a disc of radius probe_radius (so in configuration space each
// segment is a capsule). Every tick it moves from where it was toward the
// interaction (device) point, stopping at the first capsule on its way
// (swept test, so it never tunnels however far the device moves in one
// tick), then slides along the active constraints: the goal is projected onto
// the cone of feasible directions of all contacts at once (one contact:
// slide along it; a concave corner of two: stop), and after a slide it is
// retracted onto the curved surface it slid on (rounded segment ends). Up to
// max_iterations such steps per tick. It never crosses a surface.
//
// Map changes: when a new snapshot puts a surface through the proxy, the
// proxy is pushed out along that surface's normal (counted in
// depenetrations); this is the one motion not swept.
//
// Map segments are one-sided: each is a surface seen from the side its
// normal points to (the sensor's), and only holds a proxy whose centre is on
// that side. Behind a visible face is unseen space, not solid: a proxy that
// got there (past the end of an object's visible face, where the true object
// goes on but the scans do not) comes back out through the face instead of
// being trapped behind it with a force that stays after the hand has left.
// Within one_sided_depth behind the line (over the segment, not beside its
// ends) it counts as inside the surface and is pushed out to the front, the
// way it is going: at most k (probe_radius + one_sided_depth) / scale, once.
// That depth also keeps scan noise (a new scan's face drawn a few sigma
// nearer than the last) from ever putting a resting proxy "behind" a face. From the front a face blocks as before, thin walls included; at
// a wall's end the proxy rolls over the rounded end and is released once its
// centre passes behind the wall line. The exact reference (reference_scene.h)
// is two-sided: true geometry is solid.
//
// Force on the device (newtons, W axes):
//   e = (proxy - device) / scale           spring vector in device metres
//   F = k e + B (de/dt . e_hat) e_hat      spring + damping along the spring
// F is zero without contact and never pulls into a surface (unilateral).
// For a single contact e is the penetration along the surface normal.
//
// Passivity at the servo period T (Colgate & Schenkelberg): a virtual wall
// k, B is passive when the device's physical damping b satisfies
// b > k T / 2 + |B|. The Omni's own damping is small, so in practice the
// operator's hand supplies b; defaults k = 300 N/m, B = 0.3 N s/m need
// b > 0.45 N s/m, far below a grasping hand's (several N s/m), and keep k
// under device_max_stiffness (800 N/m here: an ASSUMED figure for the Omni,
// not a measured one; read HD_NOMINAL_MAX_STIFFNESS on the real device).
// The discrete spring with ZOH returns k/2 dx^2 per sample more than it took
// (power k T / 2 v^2); B > k T / 2 makes the virtual
// coupling itself dissipative for smooth motion, which the passivity observer
// in the tests confirms.
//
// Force clamp: |F| <= limit where limit = force_peak (Omni 3.3 N) while the
// low-passed |F| (time constant continuous_time_constant) stays below half of
// force_continuous (Omni 0.88 N), then falls linearly to force_continuous as
// the low-passed |F| reaches force_continuous: short taps may use the peak,
// sustained pushing is held at the continuous rating, and the limit itself
// never jumps. Clamping scales the vector, keeping its direction.
//
// The tick never allocates: all buffers live in ProxyData (make_proxy_data).
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/mapping/local_map.h"

namespace hemm::haptics {

struct ProxyModel {
  double probe_radius = 0.03;        // m in W
  double stiffness = 300.0;          // k, N/m of device travel
  double damping = 0.3;              // B, N s/m of device travel
  double period = 1e-3;              // T, s
  double force_peak = 3.3;           // N, Omni peak
  double force_continuous = 0.88;    // N, Omni continuous
  double continuous_time_constant = 2.0;  // s
  double device_max_stiffness = 800.0;    // N/m, assumed Omni usable stiffness
  double assumed_device_damping = 0.5;    // N s/m the hand+device is assumed to add (Colgate's b)
  // Hard caps that bound the tick (tests/common/haptics/proxy time the worst
  // case on a dense map): at most max_candidates segments are considered
  // (a more crowded neighbourhood shortens the step, the rest follows next
  // tick), at most max_iterations move/slide steps, and the proxy moves at
  // most max_step in one tick (bounds the query disc, so the grid cells
  // visited: 5 m per ms is far beyond any device motion at any scale; a
  // larger jump is followed over a few ticks). A query stops counting at
  // max_candidates + 1 (mapping::query_segments), so a crowded query costs
  // at most the items of the cells it visits.
  // Surface evaluations per tick (ProxyData::work)
  //   <= (5 + 3 max_iterations) max_candidates + max_iterations.
  std::size_t max_candidates = 512;  // segments considered per tick
  int max_iterations = 16;            // move/slide steps per tick
  double max_step = 5.0;              // m in W per tick
  // Map segments are one-sided (see above): a proxy centre more than this
  // far behind a segment's line is in unseen space and not held by it.
  double one_sided_depth = 0.05;     // m in W, >= 0
};

// Colgate & Schenkelberg: largest passive stiffness for physical damping b,
// virtual damping B and period T: K < 2 (b - |B|) / T.
inline double colgate_max_stiffness(double b, double B, double T) { return 2.0 * (b - std::abs(B)) / T; }

// Empty when usable; checks ranges, the device's stiffness, and the Colgate
// bound with assumed_device_damping.
std::string validate(const ProxyModel& m);

constexpr int kMaxContacts = 16;

struct ProxyData {
  bool initialized = false;
  Eigen::Vector2d proxy_W = Eigen::Vector2d::Zero();   // proxy centre
  Eigen::Vector3d device_W = Eigen::Vector3d::Zero();  // last goal (interaction point)
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();   // N, z = 0
  Eigen::Vector2d spring_prev = Eigen::Vector2d::Zero();  // e of the last tick
  double force_filtered = 0.0;                            // low-passed |F|
  double force_limit = 0.0;                               // limit applied this tick
  bool clamped = false;
  int contact_count = 0;                                  // active constraints after the tick
  std::array<Eigen::Vector2d, kMaxContacts> contact_normals{};
  std::vector<std::uint32_t> candidates;                  // preallocated, max_candidates
  std::uint64_t ticks = 0;
  std::uint64_t shrunk_queries = 0;   // ticks whose motion was shortened to fit max_candidates
  std::uint64_t depenetrations = 0;   // proxy pushed out of a surface (after a map change)
  std::uint64_t rejected_inputs = 0;  // non-finite device point or scale
  std::uint64_t work = 0;             // surface evaluations (closest / sweep) in the last tick
  std::uint64_t max_work = 0;         // the most in any tick
};

ProxyData make_proxy_data(const ProxyModel& m);

// Puts the proxy at a point (e.g. the device point at start-up).
void proxy_reset(ProxyData& d, const Eigen::Vector2d& at_W);

// One servo tick: moves the proxy toward device_W (interaction point in W)
// against the snapshot and computes force_W. scale: world metres per device
// metre of the active workspace map. A non-finite input keeps the last proxy
// and outputs zero force. Never allocates.
void proxy_tick(const ProxyModel& m, const mapping::MapSnapshot& map, ProxyData& d,
                const Eigen::Vector3d& device_W, double scale);

}  // namespace hemm::haptics
