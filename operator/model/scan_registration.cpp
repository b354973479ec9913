#include "operator/model/scan_registration.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/correspondence_estimation.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
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
  const double w[] = {p.correction_per_metre,      p.correction_per_radian, p.turn_correction_per_radian,
                      p.turn_correction_per_metre, p.max_correction_speed,  p.max_correction_turn_rate,
                      p.hold_out_translation,      p.hold_out_rotation};
  for (double x : w)
    if (!std::isfinite(x) || x < 0.0) return "registration: correction limits must be finite and >= 0";
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

// The nearest target point within a radius, in the plane: a uniform grid of
// cells at least the radius wide (points counting-sorted into one index
// array), so a query reads 3 x 3 cells and allocates nothing. PCL's k-d tree
// query goes through FLANN, which opens an OpenMP region and allocates on
// every query: a few microseconds each, and under AddressSanitizer enough to
// starve the model thread on two cores.
class NearestGrid2D {
 public:
  void build(const pcl::PointCloud<pcl::PointNormal>& c, double radius) {
    n_ = 0;
    if (c.empty()) return;
    float x0 = c[0].x, y0 = c[0].y, x1 = x0, y1 = y0;
    for (const auto& q : c) {
      x0 = std::min(x0, q.x), x1 = std::max(x1, q.x);
      y0 = std::min(y0, q.y), y1 = std::max(y1, q.y);
    }
    // Cells no smaller than the radius, and no more than ~4M of them.
    const double ext = std::max(static_cast<double>(x1 - x0), static_cast<double>(y1 - y0));
    cell_ = std::max(radius, ext / 2048.0);
    x0_ = x0;
    y0_ = y0;
    nx_ = static_cast<int>((x1 - x0) / cell_) + 1;
    ny_ = static_cast<int>((y1 - y0) / cell_) + 1;
    start_.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_) + 1, 0);
    for (const auto& q : c) ++start_[cell_of(q.x, q.y) + 1];
    for (std::size_t i = 1; i < start_.size(); ++i) start_[i] += start_[i - 1];
    order_.resize(c.size());
    fill_ = start_;
    for (std::size_t i = 0; i < c.size(); ++i) order_[static_cast<std::size_t>(fill_[cell_of(c[i].x, c[i].y)]++)] = static_cast<int>(i);
    cloud_ = &c;
    n_ = c.size();
  }
  // The nearest point no farther than sqrt(max_d2) (radius <= the build's), or -1.
  int nearest(float x, float y, double max_d2, double* d2_out) const {
    if (n_ == 0 || !std::isfinite(x) || !std::isfinite(y)) return -1;
    const int cx = static_cast<int>(std::floor((x - x0_) / cell_)), cy = static_cast<int>(std::floor((y - y0_) / cell_));
    int best = -1;
    double best_d2 = max_d2;
    for (int j = std::max(0, cy - 1); j <= std::min(ny_ - 1, cy + 1); ++j)
      for (int i = std::max(0, cx - 1); i <= std::min(nx_ - 1, cx + 1); ++i) {
        const std::size_t cell = static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(i);
        for (int k = start_[cell]; k < start_[cell + 1]; ++k) {
          const auto& q = (*cloud_)[static_cast<std::size_t>(order_[static_cast<std::size_t>(k)])];
          const double dx = q.x - x, dy = q.y - y, d2 = dx * dx + dy * dy;
          if (d2 <= best_d2) {
            best_d2 = d2;
            best = order_[static_cast<std::size_t>(k)];
          }
        }
      }
    if (best >= 0 && d2_out) *d2_out = best_d2;
    return best;
  }

 private:
  std::size_t cell_of(float x, float y) const {
    const int i = std::clamp(static_cast<int>((x - x0_) / cell_), 0, nx_ - 1);
    const int j = std::clamp(static_cast<int>((y - y0_) / cell_), 0, ny_ - 1);
    return static_cast<std::size_t>(j) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(i);
  }
  const pcl::PointCloud<pcl::PointNormal>* cloud_ = nullptr;
  std::size_t n_ = 0;
  double cell_ = 1.0;
  float x0_ = 0.0f, y0_ = 0.0f;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_, fill_, order_;
};

// PCL's correspondence step of the ICP loop, answered by the grid (built
// once per scan over the target).
class GridCorrespondences final
    : public pcl::registration::CorrespondenceEstimationBase<pcl::PointNormal, pcl::PointNormal> {
 public:
  explicit GridCorrespondences(const NearestGrid2D* grid) : grid_(grid) { corr_name_ = "GridCorrespondences"; }
  void determineCorrespondences(pcl::Correspondences& out, double max_distance) override {
    out.clear();
    if (!input_) return;
    const double max_d2 = max_distance * max_distance;
    out.reserve(input_->size());
    for (std::size_t i = 0; i < input_->size(); ++i) {
      double d2 = 0.0;
      const int j = grid_->nearest((*input_)[i].x, (*input_)[i].y, max_d2, &d2);
      if (j >= 0) out.emplace_back(static_cast<int>(i), j, static_cast<float>(d2));
    }
  }
  void determineReciprocalCorrespondences(pcl::Correspondences& out, double max_distance) override {
    determineCorrespondences(out, max_distance);  // not used: reciprocal matching is off
  }
  Ptr clone() const override { return Ptr(new GridCorrespondences(*this)); }

 private:
  const NearestGrid2D* grid_;
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
}

std::size_t RegistrationTarget::size() const { return impl_->cloud->size(); }

namespace {

struct Fit {
  double rms = 0.0;
  double inlier_ratio = 0.0;
  Eigen::Matrix2d nnT = Eigen::Matrix2d::Zero();  // mean n n^T over inliers
};

// Point-to-line residuals of the scan points (already moved) against the
// target, both relative to the sensor.
Fit check_fit(const RegistrationParams& p, const pcl::PointCloud<pcl::PointNormal>& pts,
              const pcl::PointCloud<pcl::PointNormal>& tgt, const NearestGrid2D& grid) {
  Fit f;
  double sum = 0.0;
  int inliers = 0;
  const double max2 = p.max_correspondence * p.max_correspondence;
  for (const pcl::PointNormal& q : pts) {
    const int j = grid.nearest(q.x, q.y, max2, nullptr);
    if (j < 0) continue;
    const pcl::PointNormal& m = tgt[static_cast<std::size_t>(j)];
    const Vector2d n(m.normal_x, m.normal_y);
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
  NearestGrid2D grid;
  grid.build(*tgt_o, p.max_correspondence);
  pcl::IterativeClosestPoint<pcl::PointNormal, pcl::PointNormal> icp;
  icp.setTransformationEstimation(std::make_shared<PointToLine2D>());
  icp.setCorrespondenceEstimation(std::make_shared<GridCorrespondences>(&grid));
  // The grid answers every query: PCL's own k-d tree of the target is never built.
  icp.setSearchMethodTarget(std::make_shared<pcl::search::KdTree<pcl::PointNormal>>(), true);
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
  // The fit, on the points moved by the estimate.
  const Fit f = check_fit(p, aligned, *tgt_o, grid);
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
  r.delta_about = Vector2d(o.x(), o.y());
  r.translation = tr;
  r.yaw = yaw;
  r.delta = motion_about(r.delta_about, tr, yaw);
  r.accepted = true;
  return r;
}

math::Pose2 motion_about(const Vector2d& o, const Vector2d& t, double yaw) {
  // p' = R (p - o) + o + t, as a W transform: Trans(o + t) * Rot(yaw) * Trans(-o).
  const math::Pose2 to_o{-o.x(), -o.y(), 0.0}, from_o{o.x() + t.x(), o.y() + t.y(), yaw};
  return math::compose(from_o, to_o);
}

Localizer::Localizer(const RegistrationParams& p) : p_(p) {}

RegistrationResult Localizer::place(mapping::RangeScan2D& scan, const mapping::LocalMap& map) {
  const math::Pose2 odom_pose = scan.T_W_R;
  scan.T_W_R = correct(scan.T_W_R);
  RegistrationResult r;
  if (!p_.enabled || scan.kind != mapping::SensorKind::kLaser) return r;
  // The odometry's motion and the scan time since the previous laser scan
  // bound the correction's change (a gap allows no more than 0.1 s worth);
  // the chunks of one scan share its stamp and so its allowance; a scan older
  // than the newest (reordered) may not change it at all.
  if (scan.stamp_ns > budget_stamp_ns_) {
    const math::Pose2& odom = odom_pose;
    double ds = 0.0, dth = 0.0, dt = 0.1;
    if (budget_stamp_ns_ != 0) {
      ds = std::hypot(odom.x - budget_odom_.x, odom.y - budget_odom_.y);
      dth = std::abs(math::wrap_angle(odom.theta - budget_odom_.theta));
      dt = std::min(static_cast<double>(scan.stamp_ns - budget_stamp_ns_) * 1e-9, 0.1);
    }
    budget_stamp_ns_ = scan.stamp_ns;
    budget_odom_ = odom;
    budget_translation_ =
        std::min(p_.max_correction_speed * dt, p_.correction_per_metre * ds + p_.correction_per_radian * dth);
    budget_yaw_ = std::min(p_.max_correction_turn_rate * dt,
                           p_.turn_correction_per_radian * dth + p_.turn_correction_per_metre * ds);
  }
  const bool older = scan.stamp_ns < budget_stamp_ns_;
  double zero_t = 0.0, zero_yaw = 0.0;
  double& allow_t = older ? zero_t : budget_translation_;
  double& allow_yaw = older ? zero_yaw : budget_yaw_;
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
  // The same fraction of the translation and the rotation, about the same
  // point: the applied step is on the line to the found one.
  const double tn = r.translation.norm();
  double f = 1.0;
  if (tn > allow_t) f = std::min(f, allow_t / tn);
  if (std::abs(r.yaw) > allow_yaw) f = std::min(f, allow_yaw / std::abs(r.yaw));
  allow_t = std::max(0.0, allow_t - f * tn);
  allow_yaw = std::max(0.0, allow_yaw - f * std::abs(r.yaw));
  if (f < 1.0) {
    // Held out of the map only when what is left exceeds the laser's noise.
    r.limited = (1.0 - f) * tn > p_.hold_out_translation || (1.0 - f) * std::abs(r.yaw) > p_.hold_out_rotation;
    if (r.limited) ++stats_.limited;
    r.delta = motion_about(r.delta_about, f * r.translation, f * r.yaw);
  }
  stats_.last_rms = r.rms;
  stats_.last_inlier_ratio = r.inlier_ratio;
  stats_.max_rms = std::max(stats_.max_rms, r.rms);
  // The robot's own displacement by the step (not the sensor's).
  const math::Pose2 moved = math::compose(r.delta, scan.T_W_R);
  stats_.last_step = std::hypot(moved.x - scan.T_W_R.x, moved.y - scan.T_W_R.y);
  stats_.max_step = std::max(stats_.max_step, stats_.last_step);
  stats_.correction = math::compose(r.delta, stats_.correction);
  scan.T_W_R = moved;
  return r;
}

}  // namespace hemm::op
