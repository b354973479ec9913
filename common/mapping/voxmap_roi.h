// Where the live voxmap's region of interest goes (design principle 4, "model
// only what a scene needs"): a cube around the operator's probe, so the
// voxmap holds the surfaces the probe can reach and nothing else. Pure
// functions; the operator's model thread applies them (model_thread.h).
//
// Hysteresis: moving the ROI drops every cell that falls outside it (and a
// rebuild follows), so it is not moved every tick: it stays while the probe
// is at least `margin` inside each of its faces, and is re-centred on the
// probe when the probe comes nearer to a face. A probe moving at hand speed
// (a few mm per step of the model) is then still almost `margin` inside the
// old cube: the surfaces around it, up to that distance, were in the old
// cube and are in the new one, so the probe does not lose the surface it
// touches when the ROI moves (margin >> probe radius + penetration).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>
#include <string>

namespace hemm::mapping {

struct ProbeRoiParams {
  double size = 0.6;    // m, edge of the cube around the probe (W)
  double margin = 0.15; // m: re-centred when the probe comes nearer than this to a face
};

// A reason if unusable: size in [0.05, 10] m, margin in (0, size / 2).
std::optional<std::string> check(const ProbeRoiParams& p);

// The cube of edge p.size centred on probe_W.
Eigen::AlignedBox3d roi_around(const ProbeRoiParams& p, const Eigen::Vector3d& probe_W);

// The region of interest for a probe at probe_W: `current` while the probe
// is at least p.margin inside each of its faces, else (or with none yet) the
// cube re-centred on the probe. A non-finite probe position keeps `current`
// (or, with none, gives nullopt).
std::optional<Eigen::AlignedBox3d> follow_probe(const ProbeRoiParams& p, const std::optional<Eigen::AlignedBox3d>& current,
                                                const Eigen::Vector3d& probe_W);

}  // namespace hemm::mapping
