#include "operator/model/scan_registration.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/transformation_estimation.h>

namespace hemm::op {

using Eigen::Vector2d;

std::string validate(const RegistrationParams& p) {
  const double v[] = {p.max_correspondence, p.min_inlier_ratio, p.max_rms, p.max_step_translation,
                      p.max_step_rotation,  p.min_constraint};
  for (double x : v)
    if (!std::isfinite(x) || x < 0.0) return "registration: parameters must be finite and >= 0";
  if (!(p.max_correspondence > 0.0) || p.max_correspondence > 2.0)
    return "registration: max_correspondence in (0, 2] m";
  if (p.max_iterations < 1 || p.max_iterations > 200) return "registration: max_iterations in [1, 200]";
  if (p.min_points < 3 || p.min_target_points < 3) return "registration: min_points and min_target_points >= 3";
  if (p.min_inlier_ratio > 1.0 || p.min_constraint > 0.5) return "registration: ratio <= 1, min_constraint <= 0.5";
  return {};
}

namespace {

// PCL's ICP loop (correspondences, convergence) with a 2D point-to-line
// estimate: minimises sum (n_i . (R p_i + t - q_i))^2 over x, y, yaw, with
// n_i the target surface's normal, linearised in yaw and solved by least
// squares each iteration. Point-to-point (PCL's TransformationEstimation2D)
// converges slowly on walls -- sliding along a surface costs it nothing --
// and stopped 40 % short of a 1 deg error in the tests.
class PointToLine2D final : public pcl::registration::TransformationEstimation<pcl::PointNormal, pcl::PointNormal> {
 public:
  using Cloud = pcl::PointCloud<pcl::PointNormal>;
  void estimateRigidTransformation(const Cloud& src, const Cloud& tgt, Matrix4& T) const override {
    const std::size_t n = std::min(src.size(), tgt.size());
    solve([&](auto&& f) { for (std::size_t i = 0; i < n; ++i) f(src[i], tgt[i]); }, T);
  }
  void estimateRigidTransformation(const Cloud& src, const pcl::Indices& is, const Cloud& tgt,
                                   Matrix4& T) const override {
    solve([&](auto&& f) { for (std::size_t i = 0; i < is.size() && i < tgt.size(); ++i) f(src[static_cast<std::size_t>(is[i])], tgt[i]); }, T);
  }
  void estimateRigidTransformation(const Cloud& src, const pcl::Indices& is, const Cloud& tgt,
                                   const pcl::Indices& it, Matrix4& T) const override {
    solve([&](auto&& f) {
      for (std::size_t i = 0; i < is.size() && i < it.size(); ++i)
        f(src[static_cast<std::size_t>(is[i])], tgt[static_cast<std::size_t>(it[i])]);
    }, T);
  }
  void estimateRigidTransformation(const Cloud& src, const Cloud& tgt, const pcl::Correspondences& c,
                                   Matrix4& T) const override {
    solve([&](auto&& f) {
      for (const pcl::Correspondence& k : c)
        f(src[static_cast<std::size_t>(k.index_query)], tgt[static_cast<std::size_t>(k.index_match)]);
    }, T);
  }

 private:
  template <class ForEach>
  static void solve(ForEach&& for_each, Matrix4& T) {
    Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
    for_each([&](const pcl::PointNormal& p, const pcl::PointNormal& q) {
      const Vector2d n(q.normal_x, q.normal_y), pp(p.x, p.y), qq(q.x, q.y);
      const Eigen::Vector3d a(n.x(), n.y(), n.dot(Vector2d(-pp.y(), pp.x())));
      const double b = -n.dot(pp - qq);
      AtA += a * a.transpose();
      Atb += a * b;
    });
    // A little damping: a corridor leaves one direction unconstrained
    // (handled after the fit); it must not blow up the solve.
    AtA += 1e-9 * (AtA.trace() + 1.0) * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d x = AtA.ldlt().solve(Atb);
    T = Matrix4::Identity();
    const double c = std::cos(x.z()), s = std::sin(x.z());
    T(0, 0) = static_cast<float>(c);
    T(0, 1) = static_cast<float>(-s);
    T(1, 0) = static_cast<float>(s);
    T(1, 1) = static_cast<float>(c);
    T(0, 3) = static_cast<float>(x.x());
    T(1, 3) = static_cast<float>(x.y());
  }
};

pcl::PointNormal point_normal(double x, double y, const Vector2d& n) {
  pcl::PointNormal q;
  q.x = static_cast<float>(x);
  q.y = static_cast<float>(y);
  q.z = 0.0f;
  q.normal_x = static_cast<float>(n.x());
  q.normal_y = static_cast<float>(n.y());
  q.normal_z = 0.0f;
  q.curvature = 0.0f;
  return q;
}

}  // namespace

struct RegistrationTarget::Impl {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud{new pcl::PointCloud<pcl::PointXYZ>};
  std::vector<Vector2d> normals;
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
};

RegistrationTarget::RegistrationTarget() : impl_(std::make_unique<Impl>()) {}
RegistrationTarget::~RegistrationTarget() = default;
RegistrationTarget::RegistrationTarget(RegistrationTarget&&) noexcept = default;
RegistrationTarget& RegistrationTarget::operator=(RegistrationTarget&&) noexcept = default;

void RegistrationTarget::build(const mapping::LocalMap& map, std::int64_t before_ns) {
  impl_->cloud->clear();
  impl_->normals.clear();
  for (const mapping::Segment2& s : map.segments) {
    if (s.kind != mapping::SensorKind::kLaser || s.interpolated || s.shadow || s.stamp_ns >= before_ns) continue;
    // Points every ~4 cm along the segment, starting at a (the next
    // segment's a is this one's b): dense enough for point-to-line
    // matching, half the k-d tree of every return.
    const double len = (s.b - s.a).norm();
    if (len < 0.04 && !impl_->normals.empty() &&
        (Vector2d((*impl_->cloud).back().x, (*impl_->cloud).back().y) - s.a).norm() < 0.04)
      continue;
    const int pieces = std::max(1, static_cast<int>(std::ceil(len / 0.04)));
    for (int k = 0; k < pieces; ++k) {
      const Vector2d q = s.a + (s.b - s.a) * (static_cast<double>(k) / pieces);
      impl_->cloud->push_back(pcl::PointXYZ(static_cast<float>(q.x()), static_cast<float>(q.y()), 0.0f));
      impl_->normals.push_back(s.normal);
    }
  }
  if (!impl_->cloud->empty()) impl_->tree.setInputCloud(impl_->cloud);
}

std::size_t RegistrationTarget::size() const { return impl_->cloud->size(); }

namespace {

struct Fit {
  double rms = 0.0;
  double inlier_ratio = 0.0;
  Eigen::Matrix2d nnT = Eigen::Matrix2d::Zero();  // mean n n^T over inliers
};

// Point-to-line residuals of the scan points (already moved) against the target.
Fit check_fit(const RegistrationParams& p, const pcl::PointCloud<pcl::PointXYZ>& pts,
              const RegistrationTarget::Impl& t) {
  Fit f;
  std::vector<int> idx(1);
  std::vector<float> d2(1);
  double sum = 0.0;
  int inliers = 0;
  const double max2 = p.max_correspondence * p.max_correspondence;
  for (const pcl::PointXYZ& q : pts) {
    if (t.tree.nearestKSearch(q, 1, idx, d2) < 1 || d2[0] > max2) continue;
    const pcl::PointXYZ& m = (*t.cloud)[static_cast<std::size_t>(idx[0])];
    const Vector2d& n = t.normals[static_cast<std::size_t>(idx[0])];
    const double r = n.dot(Vector2d(q.x - m.x, q.y - m.y));
    sum += r * r;
    f.nnT += n * n.transpose();
    ++inliers;
  }
  if (inliers > 0) {
    f.rms = std::sqrt(sum / inliers);
    f.nnT /= inliers;
  }
  f.inlier_ratio = pts.empty() ? 0.0 : static_cast<double>(inliers) / static_cast<double>(pts.size());
  return f;
}

}  // namespace

RegistrationResult register_scan(const RegistrationParams& p, const mapping::RangeScan2D& scan,
                                 const RegistrationTarget& target) {
  RegistrationResult r;
  if (!p.enabled || scan.kind != mapping::SensorKind::kLaser) {
    r.reason = "not a laser scan or disabled";
    return r;
  }
  const RegistrationTarget::Impl& t = target.impl();
  if (static_cast<int>(t.cloud->size()) < p.min_target_points) {
    r.reason = "too few map points";
    return r;
  }
  pcl::PointCloud<pcl::PointXYZ>::Ptr src(new pcl::PointCloud<pcl::PointXYZ>);
  const math::Pose2 T_W_S = math::compose(scan.T_W_R, scan.T_R_S);
  for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
    if (!mapping::beam_is_return(scan, i)) continue;
    const double a = mapping::beam_angle(scan, i), rr = scan.ranges[i];
    const Vector2d q = math::apply(T_W_S, Vector2d(rr * std::cos(a), rr * std::sin(a)));
    src->push_back(pcl::PointXYZ(static_cast<float>(q.x()), static_cast<float>(q.y()), 0.0f));
  }
  r.points = static_cast<int>(src->size());
  if (r.points < p.min_points) {
    r.reason = "too few returns";
    return r;
  }
  r.attempted = true;
  // ICP in coordinates relative to the sensor: rotations are then about the
  // sensor, and float precision does not depend on where W's origin is.
  const Eigen::Vector3f o(static_cast<float>(T_W_S.x), static_cast<float>(T_W_S.y), 0.0f);
  pcl::PointCloud<pcl::PointNormal>::Ptr src_o(new pcl::PointCloud<pcl::PointNormal>),
      tgt_o(new pcl::PointCloud<pcl::PointNormal>);
  float reach = 0.0f;
  for (const auto& q : *src) {
    src_o->push_back(point_normal(q.x - o.x(), q.y - o.y(), Vector2d::UnitX()));
    reach = std::max(reach, std::max(std::abs(q.x - o.x()), std::abs(q.y - o.y())));
  }
  reach += static_cast<float>(2.0 * p.max_correspondence);  // the map the returns can match
  for (std::size_t i = 0; i < t.cloud->size(); ++i) {
    const auto& q = (*t.cloud)[i];
    if (std::abs(q.x - o.x()) > reach || std::abs(q.y - o.y()) > reach) continue;
    tgt_o->push_back(point_normal(q.x - o.x(), q.y - o.y(), t.normals[i]));
  }
  if (static_cast<int>(tgt_o->size()) < p.min_target_points) {
    r.reason = "too few map points in range";
    return r;
  }
  pcl::IterativeClosestPoint<pcl::PointNormal, pcl::PointNormal> icp;
  icp.setTransformationEstimation(std::make_shared<PointToLine2D>());
  icp.setMaxCorrespondenceDistance(p.max_correspondence);
  icp.setMaximumIterations(p.max_iterations);
  icp.setTransformationEpsilon(1e-10);
  icp.setEuclideanFitnessEpsilon(1e-10);
  icp.setInputSource(src_o);
  icp.setInputTarget(tgt_o);
  pcl::PointCloud<pcl::PointNormal> aligned;
  icp.align(aligned);
  if (!icp.hasConverged()) {
    r.reason = "ICP did not converge";
    return r;
  }
  const Eigen::Matrix4f M = icp.getFinalTransformation();
  double yaw = std::atan2(static_cast<double>(M(1, 0)), static_cast<double>(M(0, 0)));
  Vector2d tr(M(0, 3), M(1, 3));
  // The fit, on the points moved by the estimate (back in W).
  pcl::PointCloud<pcl::PointXYZ> moved;
  for (const auto& q : aligned) moved.push_back(pcl::PointXYZ(q.x + o.x(), q.y + o.y(), 0.0f));
  const Fit f = check_fit(p, moved, t);
  r.rms = f.rms;
  r.inlier_ratio = f.inlier_ratio;
  if (f.inlier_ratio < p.min_inlier_ratio) {
    r.reason = "too few returns match the map";
    return r;
  }
  if (f.rms > p.max_rms) {
    r.reason = "residual too large";
    return r;
  }
  // Degenerate directions (a corridor): keep only the translation the
  // matched normals constrain.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(f.nnT);
  if (es.eigenvalues()(0) < p.min_constraint) {
    const Vector2d weak = es.eigenvectors().col(0);
    tr -= tr.dot(weak) * weak;
    r.degenerate = true;
  }
  if (tr.norm() > p.max_step_translation || std::abs(yaw) > p.max_step_rotation) {
    r.reason = "step too large";
    return r;
  }
  // The motion found is about the sensor origin o: p' = R (p - o) + o + t.
  // As a W transform: T = Trans(o + t) * Rot(yaw) * Trans(-o).
  const math::Pose2 to_o{-o.x(), -o.y(), 0.0}, from_o{o.x() + tr.x(), o.y() + tr.y(), yaw};
  r.delta = math::compose(from_o, to_o);
  r.accepted = true;
  return r;
}

Localizer::Localizer(const RegistrationParams& p) : p_(p) {}

RegistrationResult Localizer::place(mapping::RangeScan2D& scan, const mapping::LocalMap& map) {
  scan.T_W_R = correct(scan.T_W_R);
  RegistrationResult r;
  if (!p_.enabled || scan.kind != mapping::SensorKind::kLaser) return r;
  if (!target_valid_) {
    target_.build(map, std::numeric_limits<std::int64_t>::max());
    target_valid_ = true;
  }
  r = register_scan(p_, scan, target_);
  if (!r.attempted) return r;
  ++stats_.attempted;
  if (!r.accepted) {
    ++stats_.rejected;
    return r;
  }
  ++stats_.accepted;
  if (r.degenerate) ++stats_.degenerate;
  stats_.last_rms = r.rms;
  stats_.last_step = std::hypot(r.delta.x, r.delta.y);
  stats_.correction = math::compose(r.delta, stats_.correction);
  scan.T_W_R = math::compose(r.delta, scan.T_W_R);
  return r;
}

}  // namespace hemm::op
