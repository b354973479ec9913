#include "common/haptics/vps/contact.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace hemm::vps {

namespace {

constexpr std::uint32_t kNever = 0xFFFFFFFFu;
// Far faces told apart per pair and tick (PairState); one more group holds
// the rest, always kept. Two far faces are one when their normals agree
// within ~1 degree and their planes within a quarter voxel.
constexpr int kThroughGroups = 4;
constexpr double kSameFarFace = 0.9998;

// floor() as an int for the hot loop: truncation and a fix-up, with the
// total grid_floor for anything non-finite or out of range.
inline int fast_floor(double g) {
  if (!(std::abs(g) < static_cast<double>(kGridFar))) return grid_floor(g);
  const int i = static_cast<int>(g);
  return i - (g < static_cast<double>(i) ? 1 : 0);
}

inline int local_index(int x, int y, int z) {
  return ((z & (kBlockDim - 1)) << (2 * kBlockShift)) | ((y & (kBlockDim - 1)) << kBlockShift) | (x & (kBlockDim - 1));
}

// The voxel block lookup of the hot loop, with the last block remembered
// (the points of a leaf are neighbours, so most lookups hit it).
class BlockCache {
 public:
  explicit BlockCache(const Voxmap& vm) : vm_(vm), dims_(vm.dims()) {}
  // Block index of voxel (x, y, z) (or kBlockEmpty / kBlockUniformInside);
  // kBlockEmpty outside the grid. The remembered block is compared by its
  // block coordinates (C++20 shifts of negative ints are arithmetic).
  std::int32_t block_of(int x, int y, int z) {
    if ((x >> kBlockShift) == bx_ && (y >> kBlockShift) == by_ && (z >> kBlockShift) == bz_) return last_bi_;
    if (x < 0 || y < 0 || z < 0 || x >= dims_.x() || y >= dims_.y() || z >= dims_.z()) return kBlockEmpty;
    return lookup(x, y, z);
  }
  // clearance_voxels() for the hot loop (same value).
  int clearance(int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= dims_.x() || y >= dims_.y() || z >= dims_.z())
      return clearance_voxels(vm_, Eigen::Vector3i(x, y, z));
    const std::int32_t bi = block_of(x, y, z);
    return clearance_in_grid(vm_, last_bl_, bi, local_index(x, y, z));
  }

 private:
  std::int32_t lookup(int x, int y, int z) {
    bx_ = x >> kBlockShift;
    by_ = y >> kBlockShift;
    bz_ = z >> kBlockShift;
    last_bl_ = (static_cast<std::size_t>(bz_) * static_cast<std::size_t>(vm_.block_dims.y()) +
                static_cast<std::size_t>(by_)) *
                   static_cast<std::size_t>(vm_.block_dims.x()) +
               static_cast<std::size_t>(bx_);
    last_bi_ = vm_.top[last_bl_];
    return last_bi_;
  }

  const Voxmap& vm_;
  Eigen::Vector3i dims_;
  int bx_ = -kGridFar, by_ = -kGridFar, bz_ = -kGridFar;  // no block remembered yet
  std::size_t last_bl_ = 0;
  std::int32_t last_bi_ = kBlockEmpty;
};

// One pair's evaluation, level by level.
class PairEval {
 public:
  PairEval(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V, const PointShell& ps,
           const Eigen::Isometry3d& T_W_P, const ContactParams& params, PairState* state, bool per_level)
      : vm_(vm), ps_(ps), params_(params), state_(state), per_level_(per_level), cache_(vm), ref_V_(ref_V) {
    T_W_V_ = T_W_V;
    T_V_P_ = T_W_V.inverse() * T_W_P;
    s_ = vm.voxel_size;
    inv_s_ = 1.0 / s_;
    const Eigen::Matrix3d R = T_V_P_.linear();
    const Eigen::Vector3d tg = (T_V_P_.translation() - vm.origin) * inv_s_;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        rg_[3 * i + j] = R(i, j) * inv_s_;
        r_[3 * i + j] = R(i, j);
      }
      tg_[i] = tg[i];
    }
    dims_ = vm.dims();
    for (int i = 0; i < 9; ++i) rgf_[i] = static_cast<float>(rg_[i]);
    grad_scale_ = static_cast<float>(s_ / kGradScale);
    leaf_radius_ = static_cast<float>(params.leaf_radius_voxels * s_);
    r_V_ = T_V_P_ * ps.reference_point;
    layered_ = params.model == PenetrationModel::kLayered;
    max_layer_ = layered_ ? 0 : 1;
    early_out_ = static_cast<float>(params.early_out_voxels * s_);
    // A state sized for another pointshell is not used (stateless sheets).
    if (!state_ok()) state_ = nullptr;
    valid_ = !ps.nodes.empty() && !vm.top.empty();
    if (state_ != nullptr && valid_) {
      ++state_->tick;
      if (state_->tick == kNever) state_->tick = 1;
      T_V_P_prev_ = state_->has_prev ? state_->T_V_P_prev : T_V_P_;
    }
    for (int l = 0; l < kMaxShellLevels; ++l) {
      F_[l].setZero();
      tau_[l].setZero();
      Finf_[l].setZero();
    }
    inferred_scale_ = params.inferred_stiffness_scale;
  }

  int levels() const { return valid_ ? ps_.levels : 0; }

  // The tree over all points (full resolution).
  bool run_full(std::int64_t* budget) {
    if (!valid_) return true;
    return run_tree(ps_.nodes, ps_.parent, nullptr, 0, state_ != nullptr ? &state_->node_mark : nullptr, budget);
  }

  // Level l's tree (its new points); false when the budget ran out first.
  bool run_level(int l, std::int64_t* budget) {
    if (!valid_ || l >= ps_.levels) return true;
    const ShellLevel& lev = ps_.level[static_cast<std::size_t>(l)];
    if (lev.root < 0) return true;
    return run_tree(ps_.level_nodes, ps_.level_parent, ps_.level_index.data(), lev.root,
                    state_ != nullptr ? &state_->level_node_mark : nullptr, budget);
  }

  // One tree whose node ranges index `index` (null: the point arrays).
  bool run_tree(const std::vector<SphereNode>& nodes, const std::vector<std::int32_t>& parent,
                const std::int32_t* index, std::int32_t root, std::vector<std::uint32_t>* marks,
                std::int64_t* budget) {
    parent_ = &parent;
    marks_ = marks;
    std::array<std::int32_t, 128> stack;
    int top = 0;
    stack[top++] = root;
    while (top > 0) {
      if (*budget < 1) return false;
      const std::int32_t ni = stack[--top];
      const SphereNode& node = nodes[static_cast<std::size_t>(ni)];
      --*budget;
      ++out_.nodes_visited;
      double c[3];
      to_grid(node.cx, node.cy, node.cz, c);
      const Eigen::Vector3i v(fast_floor(c[0]), fast_floor(c[1]), fast_floor(c[2]));
      // Points within `radius` of c lie at most floor(r/s)+1 voxels (Chebyshev)
      // from c's voxel; skip when even then they cannot reach a contact layer,
      // unless the node held a sheet contact on the previous tick.
      const int reach = fast_floor(node.radius * inv_s_) + 1;
      const bool marked = marks != nullptr && (*marks)[static_cast<std::size_t>(ni)] + 1 == state_->tick;
      if (!marked && cache_.clearance(v.x(), v.y(), v.z()) > reach + max_layer_) continue;
      // Descend unless the node is small enough that its children would
      // hardly be culled more than it is (radius <= leaf_radius_), or the
      // stack is full: then test all of its points.
      if (node.left >= 0 && node.radius > leaf_radius_ && top + 2 <= static_cast<int>(stack.size())) {
        stack[top++] = node.right;
        stack[top++] = node.left;
        continue;
      }
      if (*budget < node.count) {
        ++*budget;  // the node's points were not evaluated: its visit is not spent
        --out_.nodes_visited;
        return false;
      }
      *budget -= node.count;
      test_points(node, ni, index, c, v);
    }
    return true;
  }

  void finish(int level_used, PairResult* out) {
    keep_or_release_through_points();
    out_.levels_completed = level_used + 1;
    const int l = std::clamp(level_used, 0, kMaxShellLevels - 1);
    const Eigen::Matrix3d R_W_V = T_W_V_.linear();
    out_.on_shell.force = R_W_V * F_[l];
    out_.inferred_force = R_W_V * Finf_[l];
    out_.on_shell.torque = R_W_V * tau_[l];
    out_.on_voxmap.force = -out_.on_shell.force;
    out_.on_voxmap.torque = R_W_V * (-(tau_[l] + (r_V_ - ref_V_).cross(F_[l])));
    if (state_ != nullptr && valid_) {
      state_->T_V_P_prev = T_V_P_;
      state_->has_prev = true;
    }
    *out = out_;
  }

 private:
  void to_grid(double x, double y, double z, double g[3]) const {
    g[0] = rg_[0] * x + rg_[1] * y + rg_[2] * z + tg_[0];
    g[1] = rg_[3] * x + rg_[4] * y + rg_[5] * z + tg_[1];
    g[2] = rg_[6] * x + rg_[7] * y + rg_[8] * z + tg_[2];
  }

  bool state_ok() const {
    return state_ == nullptr || (state_->entry.size() == 3 * ps_.size() && state_->seen.size() == ps_.size() &&
                                 state_->sheet_visits.size() == ps_.size() && ps_.size() < (std::size_t{1} << 29) &&
                                 state_->node_mark.size() == ps_.nodes.size() &&
                                 state_->level_node_mark.size() == ps_.level_nodes.size());
  }

  void mark_node(std::int32_t ni) {
    // The leaf and its ancestors: none of them may be culled next tick.
    if (marks_ == nullptr) return;
    while (ni >= 0 && (*marks_)[static_cast<std::size_t>(ni)] != state_->tick) {
      (*marks_)[static_cast<std::size_t>(ni)] = state_->tick;
      ni = (*parent_)[static_cast<std::size_t>(ni)];
    }
  }

  // Points past the far face of the wall they came through, summed apart per
  // far face (u: unit normal towards the side they came from; the face is
  // u.y = f). A group counts if some sheet point of the pair visited this
  // tick lies on that side of the face (the object still reaches back into
  // the wall); otherwise the object has gone through: its force is dropped
  // and its points are released (not seen: next tick they come from where
  // they are now). The last group (overflow) is always kept.
  struct ThroughGroup {
    Eigen::Vector3d u = Eigen::Vector3d::Zero();
    double f = 0.0;
    Eigen::Vector3d F[kMaxShellLevels], tau[kMaxShellLevels], Finf[kMaxShellLevels];
    int contacts = 0, inferred_contacts = 0;
    double max_pen = 0.0;
    void reset(const Eigen::Vector3d& u_in, double f_in) {
      u = u_in;
      f = f_in;
      for (int l = 0; l < kMaxShellLevels; ++l) {
        F[l].setZero();
        tau[l].setZero();
        Finf[l].setZero();
      }
      contacts = inferred_contacts = 0;
      max_pen = 0.0;
    }
  };

  int through_group(const Eigen::Vector3d& u, double f) {
    for (int gi = 0; gi < n_thr_; ++gi) {
      if (thr_[gi].u.dot(u) > kSameFarFace && std::abs(thr_[gi].f - f) < 0.25 * s_) return gi;
    }
    if (n_thr_ == kThroughGroups) {
      if (!overflow_used_) thr_[kThroughGroups].reset(Eigen::Vector3d::Zero(), 0.0);
      overflow_used_ = true;
      return kThroughGroups;
    }
    thr_[n_thr_].reset(u, f);
    return n_thr_++;
  }

  void keep_or_release_through_points() {
    if (n_thr_ == 0 && !overflow_used_) return;
    // The farthest any visited sheet point reaches along each group's u.
    double reach[kThroughGroups];
    std::fill(reach, reach + kThroughGroups, -std::numeric_limits<double>::infinity());
    const std::uint32_t* visits = state_->sheet_visits.data();
    for (int i = 0; i < n_visits_; ++i) {
      const auto k = static_cast<std::size_t>(visits[i] >> 3);
      const Eigen::Vector3d x = T_V_P_ * Eigen::Vector3d(ps_.px[k], ps_.py[k], ps_.pz[k]);
      for (int gi = 0; gi < n_thr_; ++gi) reach[gi] = std::max(reach[gi], thr_[gi].u.dot(x));
    }
    for (int gi = 0; gi <= kThroughGroups; ++gi) {
      if (gi == kThroughGroups ? !overflow_used_ : gi >= n_thr_) continue;
      const ThroughGroup& t = thr_[gi];
      if (gi < kThroughGroups && !(reach[gi] > t.f)) {
        for (int i = 0; i < n_visits_; ++i) {
          if (static_cast<int>(visits[i] & 7u) == gi + 1) state_->seen[visits[i] >> 3] = kNever;
        }
        continue;
      }
      for (int l = 0; l < kMaxShellLevels; ++l) {
        F_[l] += t.F[l];
        tau_[l] += t.tau[l];
        Finf_[l] += t.Finf[l];
      }
      out_.contacts += t.contacts;
      out_.inferred_contacts += t.inferred_contacts;
      out_.max_penetration = std::max(out_.max_penetration, t.max_pen);
    }
  }

  // Depth of x (grid coordinates g, voxmap frame x) in the sheet of voxel
  // (vx, block bi, local index li). *through: the far-face group of a point
  // past the far face of the wall it came through (through_group), else -1.
  double sheet_depth(std::int32_t k, const Voxel& vx, std::int32_t bi, int li, const Eigen::Vector3d& g,
                     const Eigen::Vector3i& v, const Eigen::Vector3d& x, int* through) {
    const std::int32_t si = vm_.sheet_of_block[static_cast<std::size_t>(bi)];
    const SheetBlock& sb = vm_.sheets[static_cast<std::size_t>(si)];
    const double phi_c = sb.phi[static_cast<std::size_t>(li)];
    const double th = sb.thickness[static_cast<std::size_t>(li)];
    const Eigen::Vector3d n = Eigen::Vector3d(vx.grad[0], vx.grad[1], vx.grad[2]) * (1.0 / kGradScale);
    const Eigen::Vector3d c = vm_.origin + (v.cast<double>() + Eigen::Vector3d::Constant(0.5)) * s_;
    const double phi = phi_c + n.dot((g - v.cast<double>() - Eigen::Vector3d::Constant(0.5)) * s_);
    ++out_.sheet_points;
    *through = -1;
    if (state_ == nullptr) return phi >= -0.5 * th ? -phi : phi + th;  // nearer face
    const auto ku = static_cast<std::size_t>(k);
    float* e = &state_->entry[3 * ku];
    if (state_->seen[ku] + 1 != state_->tick) {
      // Not seen on the previous tick: it came from where it was then.
      const Eigen::Vector3d p_prev = T_V_P_prev_ * Eigen::Vector3d(ps_.px[ku], ps_.py[ku], ps_.pz[ku]);
      e[0] = static_cast<float>(p_prev.x());
      e[1] = static_cast<float>(p_prev.y());
      e[2] = static_cast<float>(p_prev.z());
    }
    state_->seen[ku] = state_->tick;
    const double phi_e = phi_c + n.dot(Eigen::Vector3d(e[0], e[1], e[2]) - c);
    const bool plus = phi_e >= -0.5 * th;  // came through the + face
    const double depth = plus ? -phi : phi + th;
    if (depth > th) {
      // Past the far face (the - face for a point come through the +
      // face, phi = -th there; else the + face, phi = 0).
      const double nx = n.dot(x) - phi;  // n.y on the + face
      *through = plus ? through_group(n, nx - th) : through_group(-n, -nx);
    }
    if (n_visits_ < static_cast<int>(state_->sheet_visits.size()))
      state_->sheet_visits[static_cast<std::size_t>(n_visits_++)] =
          static_cast<std::uint32_t>(k) << 3 | static_cast<std::uint32_t>(*through + 1);
    if (depth <= 0.0) {  // outside on its own side: this is where it now comes from
      e[0] = static_cast<float>(x.x());
      e[1] = static_cast<float>(x.y());
      e[2] = static_cast<float>(x.z());
    }
    return depth;
  }

  // The points of `node` in chunks of eight: their grid positions relative
  // to the node centre's voxel in float (small numbers: full precision),
  // written as fixed-width loops the compiler vectorizes; then each point's
  // voxel lookup and rejection tests.
  void test_points(const SphereNode& node, std::int32_t ni, const std::int32_t* index, const double c[3],
                   const Eigen::Vector3i& v) {
    const float fc[3] = {static_cast<float>(c[0] - v.x()), static_cast<float>(c[1] - v.y()),
                         static_cast<float>(c[2] - v.z())};
    for (std::int32_t k0 = node.first; k0 < node.first + node.count; k0 += 8) {
      const int m = std::min<std::int32_t>(8, node.first + node.count - k0);
      float ox[8] = {}, oy[8] = {}, oz[8] = {};
      std::int32_t id[8];
      for (int j = 0; j < m; ++j) {
        id[j] = index != nullptr ? index[k0 + j] : k0 + j;
        const auto pi = static_cast<std::size_t>(id[j]);
        ox[j] = ps_.px[pi] - node.cx;
        oy[j] = ps_.py[pi] - node.cy;
        oz[j] = ps_.pz[pi] - node.cz;
      }
      float lx[8], ly[8], lz[8];
      int ix[8], iy[8], iz[8];
      for (int j = 0; j < 8; ++j) {
        lx[j] = fc[0] + rgf_[0] * ox[j] + rgf_[1] * oy[j] + rgf_[2] * oz[j];
        ly[j] = fc[1] + rgf_[3] * ox[j] + rgf_[4] * oy[j] + rgf_[5] * oz[j];
        lz[j] = fc[2] + rgf_[6] * ox[j] + rgf_[7] * oy[j] + rgf_[8] * oz[j];
      }
      // |l| is bounded by the node's reach (a few voxels); clamped anyway (NaN
      // too) so the casts below are always defined.
      constexpr float kLim = 1e6f;
      for (int j = 0; j < 8; ++j) {
        lx[j] = lx[j] > -kLim ? (lx[j] < kLim ? lx[j] : kLim) : -kLim;
        ly[j] = ly[j] > -kLim ? (ly[j] < kLim ? ly[j] : kLim) : -kLim;
        lz[j] = lz[j] > -kLim ? (lz[j] < kLim ? lz[j] : kLim) : -kLim;
      }
      float fx[8], fy[8], fz[8];
      for (int j = 0; j < 8; ++j) {
        ix[j] = static_cast<int>(lx[j]) - (lx[j] < static_cast<float>(static_cast<int>(lx[j])) ? 1 : 0);
        iy[j] = static_cast<int>(ly[j]) - (ly[j] < static_cast<float>(static_cast<int>(ly[j])) ? 1 : 0);
        iz[j] = static_cast<int>(lz[j]) - (lz[j] < static_cast<float>(static_cast<int>(lz[j])) ? 1 : 0);
        fx[j] = lx[j] - static_cast<float>(ix[j]) - 0.5f;
        fy[j] = ly[j] - static_cast<float>(iy[j]) - 0.5f;
        fz[j] = lz[j] - static_cast<float>(iz[j]) - 0.5f;
      }
      for (int j = 0; j < m; ++j) {
        const float off[3] = {fx[j], fy[j], fz[j]};
        test_point(id[j], ni, v.x() + ix[j], v.y() + iy[j], v.z() + iz[j], off);
      }
    }
  }

  // Point k in voxel (vx_i, vy_i, vz_i) at `off` voxels from its centre.
  void test_point(std::int32_t k, std::int32_t leaf, int vx_i, int vy_i, int vz_i, const float off[3]) {
    const auto ku = static_cast<std::size_t>(k);
    ++out_.points_tested;
    const std::int32_t bi = cache_.block_of(vx_i, vy_i, vz_i);
    if (bi == kBlockEmpty) return;
    Voxel vx;
    int li = 0;
    if (bi == kBlockUniformInside) {
      vx = far_inside_voxel(vm_);
    } else {
      li = local_index(vx_i, vy_i, vz_i);
      vx = vm_.blocks[static_cast<std::size_t>(bi)].v[static_cast<std::size_t>(li)];
    }
    const bool sheet = !layered_ && (vx.flags & kFlagSheet) != 0;
    if (!sheet && vx.layer > max_layer_) return;
    if (!sheet && !layered_ && (vx.flags & (kFlagNoGradient | kFlagThin)) == 0) {
      const float taylor = vx.sdf + grad_scale_ * (vx.grad[0] * off[0] + vx.grad[1] * off[1] + vx.grad[2] * off[2]);
      if (taylor > early_out_) return;
    }
    const double ga[3] = {vx_i + 0.5 + off[0], vy_i + 0.5 + off[1], vz_i + 0.5 + off[2]};
    const Eigen::Vector3d g(ga[0], ga[1], ga[2]);
    const Eigen::Vector3i v(vx_i, vy_i, vz_i);
    const Eigen::Vector3d x = s_ * g + vm_.origin;
    const double pn[3] = {ps_.nx[ku], ps_.ny[ku], ps_.nz[ku]};
    const Eigen::Vector3d n(r_[0] * pn[0] + r_[1] * pn[1] + r_[2] * pn[2], r_[3] * pn[0] + r_[4] * pn[1] + r_[5] * pn[2],
                            r_[6] * pn[0] + r_[7] * pn[1] + r_[8] * pn[2]);
    double pen;
    int through = -1;
    if (sheet) {
      pen = sheet_depth(k, vx, bi, li, g, v, x, &through);
      if (pen > 0.0 && state_ != nullptr) mark_node(leaf);
    } else {
      double pen_layered = -1.0;
      if (vx.layer <= 0 && (layered_ || (vx.flags & kFlagThin) != 0)) {
        const double depth_c = vx.layer == kLayerFarInside ? (vm_.layers_in + 1) * s_ : -vx.layer * s_;
        pen_layered = depth_c + 0.5 * s_ - s_ * (off[0] * n.x() + off[1] * n.y() + off[2] * n.z());
      }
      pen = layered_ ? pen_layered : std::max(-field(ga), pen_layered);
    }
    if (pen <= 0.0) return;
    // Past the far face of the wall it came through: summed apart until the
    // pair's other points have said whether the object still reaches back
    // into the wall (keep_or_release_through_points).
    // A point in an inferred voxel (nobody saw that surface): its stiffness
    // scaled, its force also summed apart (PairResult::inferred_force).
    const bool inferred = (vx.flags & kFlagInferred) != 0;
    Eigen::Vector3d* F = F_;
    Eigen::Vector3d* tau = tau_;
    Eigen::Vector3d* Finf = Finf_;
    int* inferred_contacts = &out_.inferred_contacts;
    if (through >= 0) {
      ThroughGroup& tg = thr_[through];
      F = tg.F;
      tau = tg.tau;
      Finf = tg.Finf;
      inferred_contacts = &tg.inferred_contacts;
      ++tg.contacts;
      tg.max_pen = std::max(tg.max_pen, pen);
    } else {
      ++out_.contacts;
      out_.max_penetration = std::max(out_.max_penetration, pen);
    }
    const double stiff = inferred ? params_.stiffness * inferred_scale_ : params_.stiffness;
    const Eigen::Vector3d f = (stiff * pen) * n;  // per unit weight
    const Eigen::Vector3d t = (x - r_V_).cross(f);
    if (inferred) ++*inferred_contacts;
    if (per_level_) {
      const float* w = &ps_.level_weight[ku * kMaxShellLevels];
      for (int l = ps_.point_level[ku]; l < ps_.levels; ++l) {
        F[l] += w[l] * f;
        tau[l] += w[l] * t;
        if (inferred) Finf[l] += w[l] * f;
      }
    } else {
      const int l = ps_.levels - 1;
      F[l] += ps_.weight[ku] * f;
      tau[l] += ps_.weight[ku] * t;
      if (inferred) Finf[l] += ps_.weight[ku] * f;
    }
  }

  // The Hermite field at grid point g; the eight corners from one block when
  // they all lie in it.
  double field(const double g[3]) {
    const int x0 = fast_floor(g[0] - 0.5), y0 = fast_floor(g[1] - 0.5), z0 = fast_floor(g[2] - 0.5);
    const double t[3] = {g[0] - 0.5 - x0, g[1] - 0.5 - y0, g[2] - 0.5 - z0};
    const Voxel* corner[8];
    Voxel store[8];
    constexpr int kMask = kBlockDim - 1;
    const std::int32_t bi = (x0 & kMask) != kMask && (y0 & kMask) != kMask && (z0 & kMask) != kMask
                                ? cache_.block_of(x0, y0, z0)
                                : kBlockEmpty;
    if (bi >= 0) {
      const Voxel* base = &vm_.blocks[static_cast<std::size_t>(bi)].v[static_cast<std::size_t>(local_index(x0, y0, z0))];
      constexpr int kOff[8] = {0, 1, kBlockDim, kBlockDim + 1, kBlockDim * kBlockDim, kBlockDim * kBlockDim + 1,
                               kBlockDim * kBlockDim + kBlockDim, kBlockDim * kBlockDim + kBlockDim + 1};
      for (int c = 0; c < 8; ++c) corner[c] = base + kOff[c];
    } else {
      for (int c = 0; c < 8; ++c) {
        store[c] = sample_voxel(vm_, Eigen::Vector3i(x0 + (c & 1), y0 + ((c >> 1) & 1), z0 + ((c >> 2) & 1)));
        corner[c] = &store[c];
      }
    }
    return cell_hermite(corner, t, s_);
  }

  const Voxmap& vm_;
  const PointShell& ps_;
  const ContactParams& params_;
  PairState* state_;
  bool per_level_;
  BlockCache cache_;
  Eigen::Vector3d ref_V_;
  Eigen::Isometry3d T_W_V_, T_V_P_, T_V_P_prev_ = Eigen::Isometry3d::Identity();
  double rg_[9], r_[9], tg_[3];  // grid coordinates g = rg p + tg; rotation r
  float rgf_[9];
  float grad_scale_ = 0, leaf_radius_ = 0;
  Eigen::Vector3i dims_;
  Eigen::Vector3d r_V_;
  double s_ = 0, inv_s_ = 0;
  float early_out_ = 0;
  bool layered_ = false, valid_ = false;
  int max_layer_ = 1;
  Eigen::Vector3d F_[kMaxShellLevels], tau_[kMaxShellLevels], Finf_[kMaxShellLevels];
  double inferred_scale_ = 1.0;
  ThroughGroup thr_[kThroughGroups + 1];  // the last: overflow, always kept
  int n_thr_ = 0;
  bool overflow_used_ = false;
  int n_visits_ = 0;  // this tick's entries in state_->sheet_visits
  PairResult out_;
  const std::vector<std::int32_t>* parent_ = nullptr;
  std::vector<std::uint32_t>* marks_ = nullptr;
};

// The coarsest level, whatever the budget (its work is then taken from the
// budget, down to none): below it the force is a partial sum over whichever
// nodes came first, which can be worse than no force at all (more than 100 %
// off on the SIMULATED Omni's probe, docs/realtime.md), and alternating with
// complete forces it shakes an object at rest. Its work is small and fixed
// per pointshell, so the tick stays bounded.
bool run_coarsest(PairEval& e, std::int64_t* budget) {
  std::int64_t unlimited = kUnlimitedWork;
  e.run_level(0, &unlimited);
  *budget = std::max<std::int64_t>(0, *budget - (kUnlimitedWork - unlimited));
  return true;
}

void sum_bimanual(const BimanualModel& model, BimanualData* data) {
  (void)model;
  data->right_total.force = data->right_scene.on_shell.force + data->right_left.on_shell.force;
  data->right_total.torque = data->right_scene.on_shell.torque + data->right_left.on_shell.torque;
  data->left_total.force = data->left_scene.on_shell.force + data->right_left.on_voxmap.force;
  data->left_total.torque = data->left_scene.on_shell.torque + data->right_left.on_voxmap.torque;
  data->work = data->right_scene.nodes_visited + data->right_scene.points_tested + data->left_scene.nodes_visited +
               data->left_scene.points_tested + data->right_left.nodes_visited + data->right_left.points_tested;
}

}  // namespace

void init_pair_state(const PointShell& ps, PairState* state) {
  state->entry.assign(3 * ps.size(), 0.0f);
  state->seen.assign(ps.size(), kNever);
  state->node_mark.assign(ps.nodes.size(), kNever);
  state->level_node_mark.assign(ps.level_nodes.size(), kNever);
  state->sheet_visits.assign(ps.size(), 0u);
  state->tick = 0;
  state->has_prev = false;
}

void reset_pair_state(PairState* state) {
  std::fill(state->seen.begin(), state->seen.end(), kNever);
  std::fill(state->node_mark.begin(), state->node_mark.end(), kNever);
  std::fill(state->level_node_mark.begin(), state->level_node_mark.end(), kNever);
  state->tick = 0;
  state->has_prev = false;
}

void evaluate_pair(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                   const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                   PairState* state, PairResult* out) {
  PairEval e(vm, T_W_V, ref_V, ps, T_W_P, params, state, false);
  std::int64_t budget = kUnlimitedWork;
  e.run_full(&budget);
  e.finish(e.levels() - 1, out);
}

void evaluate_pair_budgeted(const Voxmap& vm, const Eigen::Isometry3d& T_W_V, const Eigen::Vector3d& ref_V,
                            const PointShell& ps, const Eigen::Isometry3d& T_W_P, const ContactParams& params,
                            std::int64_t budget, PairState* state, PairResult* out) {
  if (budget == kUnlimitedWork) {
    evaluate_pair(vm, T_W_V, ref_V, ps, T_W_P, params, state, out);
    return;
  }
  PairEval e(vm, T_W_V, ref_V, ps, T_W_P, params, state, true);
  int done = -1;
  for (int l = 0; l < e.levels(); ++l) {
    if (!(l == 0 ? run_coarsest(e, &budget) : e.run_level(l, &budget))) break;
    done = l;
  }
  e.finish(std::max(done, 0), out);
  out->levels_completed = done + 1;
}

void init_bimanual_state(const BimanualModel& model, BimanualState* state) {
  init_pair_state(*model.right.pointshell, &state->right_scene);
  init_pair_state(*model.left.pointshell, &state->left_scene);
  init_pair_state(*model.right.pointshell, &state->right_left);
}

void evaluate_bimanual(const BimanualModel& model, const Eigen::Isometry3d& T_W_S, const Eigen::Isometry3d& T_W_R,
                       const Eigen::Isometry3d& T_W_L, BimanualState* state, BimanualData* data) {
  const Eigen::Vector3d ref_L = model.left.pointshell->reference_point;
  evaluate_pair(*model.scene, T_W_S, model.scene_reference, *model.right.pointshell, T_W_R, model.params,
                state != nullptr ? &state->right_scene : nullptr, &data->right_scene);
  evaluate_pair(*model.scene, T_W_S, model.scene_reference, *model.left.pointshell, T_W_L, model.params,
                state != nullptr ? &state->left_scene : nullptr, &data->left_scene);
  evaluate_pair(*model.left.voxmap, T_W_L, ref_L, *model.right.pointshell, T_W_R, model.params,
                state != nullptr ? &state->right_left : nullptr, &data->right_left);
  sum_bimanual(model, data);
  data->levels_completed = std::min({data->right_scene.levels_completed, data->left_scene.levels_completed,
                                     data->right_left.levels_completed});
}

void evaluate_bimanual_budgeted(const BimanualModel& model, const Eigen::Isometry3d& T_W_S,
                                const Eigen::Isometry3d& T_W_R, const Eigen::Isometry3d& T_W_L, std::int64_t budget,
                                BimanualState* state, BimanualData* data) {
  const Eigen::Vector3d ref_L = model.left.pointshell->reference_point;
  PairEval pairs[3] = {
      {*model.scene, T_W_S, model.scene_reference, *model.right.pointshell, T_W_R, model.params,
       state != nullptr ? &state->right_scene : nullptr, true},
      {*model.scene, T_W_S, model.scene_reference, *model.left.pointshell, T_W_L, model.params,
       state != nullptr ? &state->left_scene : nullptr, true},
      {*model.left.voxmap, T_W_L, ref_L, *model.right.pointshell, T_W_R, model.params,
       state != nullptr ? &state->right_left : nullptr, true},
  };
  int done[3] = {-1, -1, -1};  // deepest complete level per pair
  const int rounds = std::max({pairs[0].levels(), pairs[1].levels(), pairs[2].levels()});
  bool out_of_budget = false;
  int round = 0;
  for (; round < rounds && !out_of_budget; ++round) {
    for (int p = 0; p < 3 && !out_of_budget; ++p) {
      if (round >= pairs[p].levels()) continue;
      if (round == 0 ? run_coarsest(pairs[p], &budget) : pairs[p].run_level(round, &budget)) {
        done[p] = round;
      } else {
        out_of_budget = true;
      }
    }
  }
  pairs[0].finish(std::max(done[0], 0), &data->right_scene);
  pairs[1].finish(std::max(done[1], 0), &data->left_scene);
  pairs[2].finish(std::max(done[2], 0), &data->right_left);
  PairResult* res[3] = {&data->right_scene, &data->left_scene, &data->right_left};
  for (int p = 0; p < 3; ++p) res[p]->levels_completed = done[p] + 1;
  sum_bimanual(model, data);
  int completed = rounds;
  for (int p = 0; p < 3; ++p)
    if (pairs[p].levels() > 0) completed = std::min(completed, done[p] + 1);
  data->levels_completed = completed;
}

}  // namespace hemm::vps
