// Collision detection and force computation of the Voxmap-PointShell
// algorithm: every pointshell point that lands in contact with the voxmap
// gives F_k = K w_k p_k n_k (p_k penetration, n_k the point's inward normal,
// w_k its area weight), summed into a force and a torque about the moving
// object's reference point. Allocation-free and bounded per call: the work
// (sphere nodes visited + points tested) of a call is at most the
// pointshell's nodes plus points, and a budgeted call stops at its budget.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <vector>

#include "common/haptics/vps/pointshell.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::vps {

enum class PenetrationModel {
  // The paper's: for a point in a surface or interior voxel, the distance from
  // the point to the plane through the voxel centre with the point's normal,
  // offset by the voxel's layer depth (k voxels for inside layer -k) and by
  // half a voxel, so contact starts as the point enters a surface voxel.
  // Discontinuous across voxel boundaries; errors of order one voxel.
  kLayered,
  // p = -sdf_hermite(x): the Hermite-like interpolant of the stored distances
  // and gradients (voxmap.h), continuous and second-order accurate. Points in
  // sheet voxels (thin walls, open surfaces) take their depth from the sheet's
  // face on the side they came from (PairState), so a wall thinner than a
  // voxel is neither tunnelled nor pushes the wrong way. A point past the
  // wall's far face counts only while the object still reaches back across
  // that face: once it has gone through, its force is exactly zero and its
  // points are felt from the side they are now on. Point-cloud surface
  // voxels (no normals) use the layered value when larger.
  kContinuous,
};

struct ContactParams {
  // Pressure stiffness (N/m per m^2, i.e. N/m^3) when pointshell weights are
  // areas: the force approaches K * integral(p n dA). With unit weights it is
  // the per-point stiffness (N/m) of the paper's F_k = p n.
  double stiffness = 1e7;
  PenetrationModel model = PenetrationModel::kContinuous;
  // A point is skipped without interpolating when the first-order estimate
  // of the field from its own voxel (value + gradient) exceeds this many
  // voxels. Outside convex geometry the distance is convex, so the estimate
  // is below it and the skip is exact; elsewhere the two differ by at most
  // 3/8 kappa s^2 (kappa the surface curvature), under a quarter voxel for
  // curvature radii above 1.5 voxels; kinks (medial axes, sharp concave
  // edges) are flagged and never skipped.
  double early_out_voxels = 0.25;
  // Sphere nodes no larger than this (voxmap voxels) are not descended: all
  // their points are tested, since their children would hardly be culled.
  double leaf_radius_voxels = 1.0;
  // Stiffness factor for points whose voxel is kFlagInferred (a surface
  // nobody saw: a fitted primitive's unseen side, unknown space), in (0, 1]:
  // 1 renders it like a seen one; below, softer, so the operator can tell.
  double inferred_stiffness_scale = 1.0;
};

struct Wrench {
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
};

struct PairResult {
  Wrench on_shell;    // world frame; torque about the pointshell object's reference point
  Wrench on_voxmap;   // the reaction, torque about the voxmap object's reference point
  int contacts = 0;
  double max_penetration = 0.0;
  int points_tested = 0;
  int nodes_visited = 0;
  int sheet_points = 0;       // points judged by a sheet plane
  int levels_completed = 0;   // pointshell levels whose force is complete; the wrench is the deepest
  // The part of on_shell.force from points whose voxel is kFlagInferred
  // (after inferred_stiffness_scale), and how many such points touched.
  Eigen::Vector3d inferred_force = Eigen::Vector3d::Zero();
  int inferred_contacts = 0;
};

// The share of a contact force that came from inferred voxels:
// |F_inferred| / (|F_inferred| + |F - F_inferred|), in [0, 1]; 0 without force.
inline double inferred_share(const PairResult& r) {
  const double a = r.inferred_force.norm(), b = (r.on_shell.force - r.inferred_force).norm();
  return a + b > 0.0 ? a / (a + b) : 0.0;
}

// What one pair remembers from tick to tick: for each pointshell point the
// position (voxmap frame) where it was last outside a sheet, so its depth is
// measured from the face it came through; which sphere nodes held a sheet
// contact (they are not culled on the next tick, so a point pushed through a
// thin wall keeps being seen while it is within the sheet's layers); the
// previous relative pose (a point not seen on the previous tick takes its
// position there as where it came from: leaving the sheet's layers, on
// either side, releases what it remembered).
//
// A point past the far face of the wall it came through counts only while
// some sheet point of the pair lies on the entry side of that far face (the
// object still reaches into the wall; the face taken as a plane, from the
// point's sheet). On a tick with none, the object has gone through: those
// points' force is dropped and they are released (from the next tick on
// they come from where they were). Exact for flat walls; where the points
// past the far faces of one pair lie on more than four distinct planes
// (curved thin walls, several walls at once), the others are kept as before
// until they leave the layers. Sized by init_pair_state (allocates: do it
// when the model is loaded, not on the servo thread).
struct PairState {
  std::vector<float> entry;             // 3 per point
  std::vector<std::uint32_t> seen;      // tick of the point's last sheet visit
  std::vector<std::uint32_t> node_mark; // tick of the node's last sheet contact (full tree)
  std::vector<std::uint32_t> level_node_mark;  // the same for the levels' trees
  // This tick's sheet visits: point index << 3 | its far-face group + 1 (0:
  // not past a far face); one per point at most.
  std::vector<std::uint32_t> sheet_visits;
  std::uint32_t tick = 0;
  Eigen::Isometry3d T_V_P_prev = Eigen::Isometry3d::Identity();
  bool has_prev = false;
};

void init_pair_state(const PointShell& ps, PairState* state);
// Forgets the history (e.g. after the object was placed somewhere else);
// allocation-free.
void reset_pair_state(PairState* state);

// One pair: pointshell object P (pose T_W_P) against voxmap object V (pose
// T_W_V, reference point ref_V in V's frame, for the reaction torque). With
// a null state every sheet point is judged from its nearer face (stateless:
// thin walls can then be pushed through beyond their middle); so is a state
// initialised for another pointshell.
void evaluate_pair(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                   const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                   PairState* state, PairResult* out);

// One pair in the time-critical mode (Barbic & James): the pointshell's
// levels coarse to fine until `budget` work units (sphere nodes visited +
// points tested) are spent; the wrench is that of the deepest complete level
// (levels_completed). The coarsest level always completes (a partial sum can
// be worse than no force), so the call's work is at most the larger of its
// budget and the coarsest level's. With an unlimited budget it equals
// evaluate_pair.
// The most work the coarsest level can take (each of its sphere nodes visited
// and each of its points tested once): what a budgeted call always affords.
inline std::int64_t coarsest_level_work(const PointShell& ps) {
  return ps.levels > 0 ? static_cast<std::int64_t>(ps.level[0].count) + ps.level[0].node_count : 0;
}
void evaluate_pair_budgeted(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                            const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                            std::int64_t budget, PairState* state, PairResult* out);

// A moving object with both structures: its pointshell collides with the
// scene; its voxmap is hit by the other tool's pointshell.
struct VpsObject {
  const Voxmap* voxmap = nullptr;
  const PointShell* pointshell = nullptr;
};

// The bimanual set-up of the paper: static scene, right and left objects.
struct BimanualModel {
  const Voxmap* scene = nullptr;
  Eigen::Vector3d scene_reference = Eigen::Vector3d::Zero();
  VpsObject right;  // needs a pointshell
  VpsObject left;   // needs a pointshell and a voxmap
  ContactParams params;
};

struct BimanualState {
  PairState right_scene, left_scene, right_left;
};
void init_bimanual_state(const BimanualModel& model, BimanualState* state);

struct BimanualData {
  PairResult right_scene, left_scene, right_left;
  Wrench right_total;  // on the right object, about its reference point
  Wrench left_total;
  std::int64_t work = 0;      // sphere nodes visited + points tested
  int levels_completed = 0;   // time-critical: rounds (levels) completed by all three pairs
};

inline constexpr std::int64_t kUnlimitedWork = std::numeric_limits<std::int64_t>::max();

// The three pairs of each haptic cycle: (i) right-scene, (ii) left-scene,
// (iii) right against left (right's pointshell in left's voxmap). Full
// resolution. `state` may be null (stateless sheets).
void evaluate_bimanual(const BimanualModel& model, const Eigen::Isometry3d& T_W_S, const Eigen::Isometry3d& T_W_R,
                       const Eigen::Isometry3d& T_W_L, BimanualState* state, BimanualData* data);

// Time-critical cycle (Barbic & James): the pointshells' levels coarse to
// fine, each level for all three pairs in turn, until `budget` work units
// (sphere nodes visited + points tested) are spent; each pair's wrench is that
// of its deepest complete level, and the force degrades gracefully as the
// budget shrinks. Level 0 of every pair always completes, its work taken from
// the budget (a partial level-0 sum can be worse than no force): the work is
// at most the larger of the budget and the coarsest round's. With an
// unlimited budget it equals the full cycle.
void evaluate_bimanual_budgeted(const BimanualModel& model, const Eigen::Isometry3d& T_W_S,
                                const Eigen::Isometry3d& T_W_R, const Eigen::Isometry3d& T_W_L, std::int64_t budget,
                                BimanualState* state, BimanualData* data);

}  // namespace hemm::vps
