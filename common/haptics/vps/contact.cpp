#include "common/haptics/vps/contact.h"

#include <array>

namespace hemm::vps {

void evaluate_pair(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                   const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                   PairResult* out) {
  *out = PairResult{};
  if (ps.nodes.empty() || vm.top.empty()) return;
  const Eigen::Isometry3d T_V_P = T_W_V.inverse() * T_W_P;
  const Eigen::Matrix3d R = T_V_P.linear();
  const Eigen::Vector3d t = T_V_P.translation();
  const double s = vm.voxel_size;
  const double inv_s = 1.0 / s;
  const bool layered = params.model == PenetrationModel::kLayered;
  // A point can be in contact only if its voxel's layer is <= max_layer.
  const int max_layer = layered ? 0 : 1;
  const Eigen::Vector3d r_V = R * ps.reference_point + t;
  Eigen::Vector3d F = Eigen::Vector3d::Zero(), tau = Eigen::Vector3d::Zero();
  std::array<std::int32_t, 256> stack;
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const SphereNode& node = ps.nodes[static_cast<std::size_t>(stack[--top])];
    ++out->nodes_visited;
    const Eigen::Vector3d c = R * node.centre + t;
    // Points within `radius` of c lie at most floor(r/s)+1 voxels (Chebyshev)
    // from c's voxel; skip when even then they cannot reach a contact layer.
    const int reach = grid_floor(node.radius * inv_s) + 1;  // radius may come from a file: no raw cast
    if (clearance_voxels(vm, voxel_of(vm, c)) > reach + max_layer) continue;
    if (node.left >= 0 && top + 2 <= static_cast<int>(stack.size())) {
      stack[top++] = node.right;
      stack[top++] = node.left;
      continue;
    }
    // Leaf (or a full stack: then test all points of the node directly).
    for (int k = node.first; k < node.first + node.count; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      const Eigen::Vector3d x = R * ps.points[ku] + t;
      ++out->points_tested;
      const Eigen::Vector3i v = voxel_of(vm, x);
      const VoxelSample vs = sample_voxel(vm, v);
      if (vs.layer > max_layer) continue;
      const Eigen::Vector3d n = R * ps.normals[ku];
      double pen = 0.0;
      double pen_layered = -1.0;
      if (vs.layer <= 0 && (layered || (vs.flags & kFlagThin) != 0)) {
        const double depth_c = vs.layer == kLayerFarInside ? (vm.layers_in + 1) * s : -vs.layer * s;
        pen_layered = depth_c + 0.5 * s + (voxel_centre(vm, v) - x).dot(n);
      }
      if (layered) {
        pen = pen_layered;
      } else {
        pen = std::max(-sdf_trilinear(vm, x), pen_layered);
      }
      if (pen <= 0.0) continue;
      const Eigen::Vector3d f = (params.stiffness * ps.weights[ku] * pen) * n;
      F += f;
      tau += (x - r_V).cross(f);
      ++out->contacts;
      out->max_penetration = std::max(out->max_penetration, pen);
    }
  }
  const Eigen::Matrix3d R_W_V = T_W_V.linear();
  out->on_shell.force = R_W_V * F;
  out->on_shell.torque = R_W_V * tau;
  out->on_voxmap.force = -out->on_shell.force;
  out->on_voxmap.torque = R_W_V * (-(tau + (r_V - ref_V).cross(F)));
}

void evaluate_bimanual(const BimanualModel& model, const Eigen::Isometry3d& T_W_S, const Eigen::Isometry3d& T_W_R,
                       const Eigen::Isometry3d& T_W_L, BimanualData* data) {
  const Eigen::Vector3d ref_L = model.left.pointshell->reference_point;
  evaluate_pair(*model.scene, T_W_S, model.scene_reference, *model.right.pointshell, T_W_R, model.params,
                &data->right_scene);
  evaluate_pair(*model.scene, T_W_S, model.scene_reference, *model.left.pointshell, T_W_L, model.params,
                &data->left_scene);
  evaluate_pair(*model.left.voxmap, T_W_L, ref_L, *model.right.pointshell, T_W_R, model.params, &data->right_left);
  data->right_total.force = data->right_scene.on_shell.force + data->right_left.on_shell.force;
  data->right_total.torque = data->right_scene.on_shell.torque + data->right_left.on_shell.torque;
  data->left_total.force = data->left_scene.on_shell.force + data->right_left.on_voxmap.force;
  data->left_total.torque = data->left_scene.on_shell.torque + data->right_left.on_voxmap.torque;
}

}  // namespace hemm::vps
