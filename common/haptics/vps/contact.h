// Collision detection and force computation of the Voxmap-PointShell
// algorithm: every pointshell point that lands in a surface or interior voxel
// gives F_k = K w_k p_k n_k (p_k penetration, n_k the point's inward normal,
// w_k its area weight), summed into a force and a torque about the moving
// object's reference point. Pure and allocation-free per call.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

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
  // Trilinear interpolation of the signed distance at voxel centres: p = -sdf(x).
  // Continuous across voxel boundaries. For surface voxels flagged thin (walls
  // thinner than ~2 voxels, open meshes) the layered value is used when larger,
  // so thin walls keep pushing back instead of being tunnelled.
  kContinuous,
};

struct ContactParams {
  // Pressure stiffness (N/m per m^2, i.e. N/m^3) when pointshell weights are
  // areas: the force approaches K * integral(p n dA). With unit weights it is
  // the per-point stiffness (N/m) of the paper's F_k = p n.
  double stiffness = 1e7;
  PenetrationModel model = PenetrationModel::kContinuous;
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
};

// One pair: pointshell object P (pose T_W_P) against voxmap object V (pose
// T_W_V, reference point ref_V in V's frame, for the reaction torque).
void evaluate_pair(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                   const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                   PairResult* out);

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

struct BimanualData {
  PairResult right_scene, left_scene, right_left;
  Wrench right_total;  // on the right object, about its reference point
  Wrench left_total;
};

// The three pairs of each haptic cycle: (i) right-scene, (ii) left-scene,
// (iii) right against left (right's pointshell in left's voxmap).
void evaluate_bimanual(const BimanualModel& model, const Eigen::Isometry3d& T_W_S, const Eigen::Isometry3d& T_W_R,
                       const Eigen::Isometry3d& T_W_L, BimanualData* data);

}  // namespace hemm::vps
