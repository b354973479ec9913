#include "common/mapping/depth_registration.h"

#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

#include "common/haptics/vps/voxmap.h"
#include "common/haptics/vps/voxmap_surface.h"

namespace hemm::mapping {
namespace {

using Cloud = pcl::PointCloud<pcl::PointNormal>;

struct Fit {
  double rmse = 0.0;
  double overlap = 0.0;
};

// Point-to-plane RMS over the points whose nearest surface point is within max_d.
Fit evaluate(const Cloud& src, const pcl::KdTreeFLANN<pcl::PointNormal>& tree, const Cloud& tgt, double max_d) {
  pcl::Indices idx(1);
  std::vector<float> d2(1);
  double sum = 0.0;
  std::size_t n = 0;
  for (const pcl::PointNormal& p : src.points) {
    if (tree.nearestKSearch(p, 1, idx, d2) < 1 || d2[0] > max_d * max_d) continue;
    const pcl::PointNormal& q = tgt.points[static_cast<std::size_t>(idx[0])];
    const double r = q.normal_x * (p.x - q.x) + q.normal_y * (p.y - q.y) + q.normal_z * (p.z - q.z);
    sum += r * r;
    ++n;
  }
  Fit f;
  f.overlap = src.empty() ? 0.0 : static_cast<double>(n) / static_cast<double>(src.size());
  f.rmse = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  return f;
}

// How well the correspondences of src (within max_d of the surface) fix
// each direction of a correction: the eigenvalues of the point-to-plane
// information matrix H = sum J^T J, J = [((x - c) x n) / L, n] about the
// frame's centroid c (rotations scaled by the frame's radius L so both
// halves are metres), smallest first, relative to the largest (0: none).
Eigen::Matrix<double, 6, 1> constraint_spectrum(const Cloud& src, const pcl::KdTreeFLANN<pcl::PointNormal>& tree,
                                                const Cloud& tgt, double max_d) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const pcl::PointNormal& q : src.points) c += Eigen::Vector3d(q.x, q.y, q.z);
  c /= static_cast<double>(std::max<std::size_t>(src.size(), 1));
  double L2 = 0.0;
  for (const pcl::PointNormal& q : src.points) L2 += (Eigen::Vector3d(q.x, q.y, q.z) - c).squaredNorm();
  const double L = std::sqrt(L2 / static_cast<double>(std::max<std::size_t>(src.size(), 1))) + 1e-6;
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  pcl::Indices idx(1);
  std::vector<float> d2(1);
  for (const pcl::PointNormal& q : src.points) {
    if (tree.nearestKSearch(q, 1, idx, d2) < 1 || d2[0] > max_d * max_d) continue;
    const pcl::PointNormal& t = tgt.points[static_cast<std::size_t>(idx[0])];
    const Eigen::Vector3d x(q.x, q.y, q.z), n(t.normal_x, t.normal_y, t.normal_z);
    Eigen::Matrix<double, 6, 1> J;
    J.head<3>() = (x - c).cross(n) / L;
    J.tail<3>() = n;
    H += J * J.transpose();
  }
  const Eigen::Matrix<double, 6, 1> ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(H).eigenvalues();
  const double lmax = ev.maxCoeff();
  return lmax > 0.0 ? Eigen::Matrix<double, 6, 1>(ev / lmax) : Eigen::Matrix<double, 6, 1>::Zero();
}

}  // namespace

std::optional<std::string> check(const DepthRegistrationParams& p) {
  if (!(p.leaf_m >= 0.001 && p.leaf_m <= 0.1)) return "depth registration: leaf_m not in [0.001, 0.1]";
  if (!(p.max_correspondence_m > 0.0 && p.max_correspondence_m <= 0.5))
    return "depth registration: max_correspondence_m not in (0, 0.5]";
  if (p.max_iterations < 1 || p.max_iterations > 200) return "depth registration: max_iterations not in 1..200";
  if (!(p.max_rmse_m > 0.0 && p.max_rmse_m <= 0.1)) return "depth registration: max_rmse_m not in (0, 0.1]";
  if (!(p.min_overlap > 0.0 && p.min_overlap <= 1.0)) return "depth registration: min_overlap not in (0, 1]";
  if (!(p.min_constraint >= 0.0 && p.min_constraint < 1.0)) return "depth registration: min_constraint not in [0, 1)";
  if (!(p.refine_correspondence_m > 0.0 && p.refine_correspondence_m <= p.max_correspondence_m))
    return "depth registration: refine_correspondence_m not in (0, max_correspondence_m]";
  if (!(p.min_improvement_m >= 0.0 && p.min_improvement_m <= 0.1))
    return "depth registration: min_improvement_m not in [0, 0.1]";
  if (p.min_points < 3 || p.min_target_points < 3) return "depth registration: need at least 3 points";
  if (!(p.max_translation_m > 0.0 && p.max_translation_m <= 1.0))
    return "depth registration: max_translation_m not in (0, 1]";
  if (!(p.max_rotation_rad > 0.0 && p.max_rotation_rad <= 0.5))
    return "depth registration: max_rotation_rad not in (0, 0.5]";
  return std::nullopt;
}

const char* to_string(RegistrationVerdict v) {
  switch (v) {
    case RegistrationVerdict::kAccepted: return "accepted";
    case RegistrationVerdict::kTooFewPoints: return "too few points";
    case RegistrationVerdict::kNoSurface: return "no surface";
    case RegistrationVerdict::kPoorFit: return "poor fit";
    case RegistrationVerdict::kNoGain: return "no gain";
    case RegistrationVerdict::kDegenerate: return "degenerate";
    case RegistrationVerdict::kStepTooLarge: return "step too large";
  }
  return "?";
}

void surface_from_voxmap(const vps::Voxmap& vm, RegistrationSurface* out) {
  out->points.clear();
  out->normals.clear();
  vps::for_each_surface_voxel(vm, [&](const Eigen::Vector3i& v, const vps::Voxel& vx) {
    if ((vx.flags & vps::kFlagNoGradient) != 0) return;
    const Eigen::Vector3d g = vps::voxel_gradient(vx);
    if (!(g.norm() > 0.5)) return;
    const Eigen::Vector3d n = g.normalized();
    out->points.push_back((vps::voxel_centre(vm, v) - static_cast<double>(vx.sdf) * n).cast<float>());
    out->normals.push_back(n.cast<float>());
  });
}

RegistrationResult register_points(const std::vector<Eigen::Vector3f>& points_W, const Eigen::Vector3d& sensor_W,
                                   const RegistrationSurface& surface, const DepthRegistrationParams& p) {
  RegistrationResult r;
  if (surface.points.size() < p.min_target_points || surface.normals.size() != surface.points.size()) {
    r.verdict = RegistrationVerdict::kNoSurface;
    return r;
  }
  // Only the frame's points where the surface is (the voxmap keeps a region
  // of interest; a frame sees far beyond it): the overlap is judged there.
  Eigen::AlignedBox3f box;
  for (const Eigen::Vector3f& x : surface.points) box.extend(x);
  box.min().array() -= static_cast<float>(p.max_correspondence_m);
  box.max().array() += static_cast<float>(p.max_correspondence_m);
  pcl::PointCloud<pcl::PointXYZ>::Ptr raw(new pcl::PointCloud<pcl::PointXYZ>);
  raw->reserve(points_W.size());
  for (const Eigen::Vector3f& x : points_W)
    if (box.contains(x)) raw->push_back(pcl::PointXYZ(x.x(), x.y(), x.z()));
  pcl::PointCloud<pcl::PointXYZ> down;
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(raw);
  const auto leaf = static_cast<float>(p.leaf_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(down);
  r.points = down.size();
  if (down.size() < p.min_points) {
    r.verdict = RegistrationVerdict::kTooFewPoints;
    return r;
  }
  Cloud::Ptr src(new Cloud), tgt(new Cloud);
  for (const pcl::PointXYZ& q : down.points) {
    pcl::PointNormal pn;
    pn.x = q.x;
    pn.y = q.y;
    pn.z = q.z;
    pn.normal_x = pn.normal_y = pn.normal_z = 0.0f;  // point-to-plane uses the target's normals
    src->push_back(pn);
  }
  for (std::size_t i = 0; i < surface.points.size(); ++i) {
    pcl::PointNormal pn;
    pn.x = surface.points[i].x();
    pn.y = surface.points[i].y();
    pn.z = surface.points[i].z();
    pn.normal_x = surface.normals[i].x();
    pn.normal_y = surface.normals[i].y();
    pn.normal_z = surface.normals[i].z();
    tgt->push_back(pn);
  }
  pcl::KdTreeFLANN<pcl::PointNormal> tree;
  tree.setInputCloud(tgt);
  const Fit before = evaluate(*src, tree, *tgt, p.max_correspondence_m);
  r.rmse_before = before.rmse;
  r.overlap_before = before.overlap;

  // A frame that does not fix every direction (a single plane: sliding and
  // turning about its normal are free) is refused before ICP, whose least
  // squares would be singular there.
  r.weakest_constraint = constraint_spectrum(*src, tree, *tgt, p.max_correspondence_m).minCoeff();
  if (r.weakest_constraint < p.min_constraint) {
    r.verdict = RegistrationVerdict::kDegenerate;
    return r;
  }
  pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal> icp;
  icp.setInputSource(src);
  icp.setInputTarget(tgt);
  icp.setMaxCorrespondenceDistance(p.max_correspondence_m);
  icp.setMaximumIterations(p.max_iterations);
  icp.setTransformationEpsilon(1e-10);
  icp.setEuclideanFitnessEpsilon(1e-12);
  Cloud aligned;
  icp.align(aligned);
  // A second pass from there with a tight correspondence distance: near the
  // objects' edges the wide first pass pairs points with the neighbouring
  // face's plane, which biases the fit by millimetres.
  // A scene the least squares cannot solve (a single plane: a singular
  // system) gives a non-finite transform: no fit.
  const Eigen::Matrix4f guess = icp.getFinalTransformation();
  if (!icp.hasConverged() || !guess.allFinite()) {
    r.verdict = RegistrationVerdict::kPoorFit;
    return r;
  }
  icp.setMaxCorrespondenceDistance(p.refine_correspondence_m);
  icp.align(aligned, guess);
  if (!icp.hasConverged() || !icp.getFinalTransformation().allFinite()) {
    r.verdict = RegistrationVerdict::kPoorFit;
    return r;
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = icp.getFinalTransformation().cast<double>();
  // Re-orthonormalise: the float 4x4 is not exactly a rotation.
  T.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  r.candidate = T;
  Cloud moved;
  for (const pcl::PointNormal& q : src->points) {
    const Eigen::Vector3d x = T * Eigen::Vector3d(q.x, q.y, q.z);
    pcl::PointNormal pn = q;
    pn.x = static_cast<float>(x.x());
    pn.y = static_cast<float>(x.y());
    pn.z = static_cast<float>(x.z());
    moved.push_back(pn);
  }
  const Fit after = evaluate(moved, tree, *tgt, p.max_correspondence_m);
  r.rmse_after = after.rmse;
  r.overlap_after = after.overlap;
  // The step: how far the correction moves the sensor, and turns it.
  const double step = (T * sensor_W - sensor_W).norm();
  const double angle = Eigen::AngleAxisd(T.linear()).angle();
  if (after.overlap < p.min_overlap || after.rmse > p.max_rmse_m) {
    r.verdict = RegistrationVerdict::kPoorFit;
  } else if (after.rmse > before.rmse - p.min_improvement_m) {
    r.verdict = RegistrationVerdict::kNoGain;
  } else if (step > p.max_translation_m || angle > p.max_rotation_rad) {
    r.verdict = RegistrationVerdict::kStepTooLarge;
  } else {
    r.verdict = RegistrationVerdict::kAccepted;
    r.correction = T;
  }
  return r;
}

void chunk_points_W(const DepthChunkData& c, const Eigen::Isometry3d& T_W_S, std::vector<Eigen::Vector3f>* out) {
  const int w = c.K.width;
  for (int r = 0; r < c.row_count; ++r)
    for (int u = 0; u < w; ++u) {
      const auto i = static_cast<std::size_t>(r) * static_cast<std::size_t>(w) + static_cast<std::size_t>(u);
      if (i >= c.status.size() || c.status[i] != DepthStatus::kValid) continue;
      const Eigen::Vector3d x_S = pixel_ray_z1(c.K, u, c.first_row + r) * static_cast<double>(c.depth[i]);
      out->push_back((T_W_S * x_S).cast<float>());
    }
}

Eigen::Vector2d pose_error(const Eigen::Isometry3d& T, const Eigen::Isometry3d& truth) {
  const Eigen::Isometry3d E = truth.inverse() * T;
  return {E.translation().norm(), Eigen::AngleAxisd(E.linear()).angle()};
}

void DepthFrameRegistration::add(const DepthChunkData& c, const RegistrationSurface* surface,
                                 std::vector<DepthChunkData>* ready) {
  if (!held_.empty() && held_.front().cloud_id != c.cloud_id) release(surface, ready);
  held_.push_back(c);
  rows_held_ += c.row_count;
  if (rows_held_ >= c.K.height) release(surface, ready);
}

void DepthFrameRegistration::flush(const RegistrationSurface* surface, std::vector<DepthChunkData>* ready) {
  if (!held_.empty()) release(surface, ready);
}

void DepthFrameRegistration::release(const RegistrationSurface* surface, std::vector<DepthChunkData>* ready) {
  points_S_.clear();
  for (const DepthChunkData& c : held_) chunk_points_W(c, Eigen::Isometry3d::Identity(), &points_S_);
  const Eigen::Isometry3d T_W_S = held_.front().T_W_S;  // one cloud, one pose
  points_.resize(points_S_.size());
  for (std::size_t i = 0; i < points_S_.size(); ++i) points_[i] = (T_W_S * points_S_[i].cast<double>()).cast<float>();
  static const RegistrationSurface kNone;
  const RegistrationResult r =
      register_points(points_, held_.front().T_W_S.translation(), surface != nullptr ? *surface : kNone, p_);
  ++stats_.frames;
  switch (r.verdict) {
    case RegistrationVerdict::kAccepted: ++stats_.accepted; break;
    case RegistrationVerdict::kTooFewPoints: ++stats_.too_few_points; break;
    case RegistrationVerdict::kNoSurface: ++stats_.no_surface; break;
    case RegistrationVerdict::kPoorFit: ++stats_.poor_fit; break;
    case RegistrationVerdict::kNoGain: ++stats_.no_gain; break;
    case RegistrationVerdict::kDegenerate: ++stats_.degenerate; break;
    case RegistrationVerdict::kStepTooLarge: ++stats_.step_too_large; break;
  }
  if (r.verdict != RegistrationVerdict::kNoSurface && r.verdict != RegistrationVerdict::kTooFewPoints) {
    stats_.last_rmse_before_m = r.rmse_before;
    stats_.last_rmse_after_m = r.verdict == RegistrationVerdict::kAccepted ? r.rmse_after : r.rmse_before;
  }
  const DepthChunkData& first = held_.front();
  if (r.verdict == RegistrationVerdict::kAccepted) {
    const double step = (r.correction * first.T_W_S.translation() - first.T_W_S.translation()).norm();
    stats_.last_step_m = step;
    stats_.max_step_m = std::max(stats_.max_step_m, step);
  }
  if (first.has_truth) {
    const Eigen::Vector2d e0 = pose_error(first.T_W_S, first.T_W_S_truth);
    const Eigen::Vector2d e1 = pose_error(r.correction * first.T_W_S, first.T_W_S_truth);
    ++stats_.truth_frames;
    stats_.sum_error_before_m += e0.x();
    stats_.sum_error_after_m += e1.x();
    stats_.sum_error_before_rad += e0.y();
    stats_.sum_error_after_rad += e1.y();
    const Eigen::Isometry3d T1 = r.correction * first.T_W_S;
    double d0 = 0.0, d1 = 0.0;
    for (const Eigen::Vector3f& x : points_S_) {
      const Eigen::Vector3d xs = x.cast<double>(), xt = first.T_W_S_truth * xs;
      d0 += (first.T_W_S * xs - xt).norm();
      d1 += (T1 * xs - xt).norm();
    }
    const double n = static_cast<double>(std::max<std::size_t>(points_S_.size(), 1));
    stats_.sum_point_error_before_m += d0 / n;
    stats_.sum_point_error_after_m += d1 / n;
  }
  for (DepthChunkData& c : held_) {
    c.T_W_S = r.correction * c.T_W_S;
    ready->push_back(std::move(c));
  }
  held_.clear();
  rows_held_ = 0;
}

}  // namespace hemm::mapping
