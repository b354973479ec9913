#include "common/mapping/shape_completion3d.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <numbers>
#include <numeric>

#include <pcl/features/normal_3d.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/search/kdtree.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_cylinder.h>
#include <pcl/sample_consensus/sac_model_normal_plane.h>
#include <pcl/sample_consensus/sac_model_sphere.h>

#include "common/mapping/sample_consensus_fit.h"

namespace hemm::mapping {

using Eigen::Vector3d;

std::string validate(const Shape3dParams& p) {
  const double v[] = {p.inlier_distance, p.normal_angle,  p.max_rms,          p.cluster_tolerance, p.fit_normal_radius,
                      p.min_support_share, p.min_inlier_ratio, p.min_radius, p.max_radius,
                      p.min_arc,         p.min_sphere_spread, p.right_angle_tolerance, p.min_box_height,
                      p.max_box_size,    p.support_snap, p.max_edge_extension,  p.max_free_share,   p.free_sample_step,
                      p.max_inside_share};
  for (double x : v)
    if (!std::isfinite(x) || x < 0.0) return "shape completion 3d: parameters must be finite and >= 0";
  if (!(p.inlier_distance > 0.0) || !(p.cluster_tolerance > 0.0) || !(p.free_sample_step > 0.0) ||
      !(p.max_rms > 0.0))
    return "shape completion 3d: inlier_distance, max_rms, cluster_tolerance, free_sample_step must be > 0";
  if (p.min_points < 4 || p.min_face_points < 3) return "shape completion 3d: min_points >= 4, min_face_points >= 3";
  if (p.max_objects < 1 || p.max_objects > 10000) return "shape completion 3d: max_objects in [1, 10000]";
  if (p.max_iterations < 1 || p.max_iterations > 100000) return "shape completion 3d: max_iterations in [1, 100000]";
  if (p.min_inlier_ratio > 1.0 || p.min_support_share > 1.0 || p.max_free_share > 1.0 || p.max_inside_share > 1.0)
    return "shape completion 3d: ratios must be <= 1";
  if (!(p.max_radius > p.min_radius)) return "shape completion 3d: need min_radius < max_radius";
  if (p.normal_angle > 1.5 || p.right_angle_tolerance > 0.5) return "shape completion 3d: angles too wide";
  return {};
}

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;

// ---- closed forms -----------------------------------------------------------

// Signed distance of the box of half extents h (frame P) and its gradient.
double box_sdf(const Vector3d& x, const Vector3d& h, Vector3d* g, bool* kink, double band) {
  const Vector3d q = x.cwiseAbs() - h;
  const Vector3d s(x.x() < 0 ? -1.0 : 1.0, x.y() < 0 ? -1.0 : 1.0, x.z() < 0 ? -1.0 : 1.0);
  const Vector3d o = q.cwiseMax(0.0);
  if (o.squaredNorm() > 0.0) {
    *g = o.normalized().cwiseProduct(s);
    *kink = false;
    return o.norm();
  }
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (q[i] > q[k]) k = i;
  *g = Vector3d::Zero();
  (*g)[k] = s[k];
  // Inside, the gradient jumps across the medial planes (two faces equally near).
  double second = -1e300;
  for (int i = 0; i < 3; ++i)
    if (i != k) second = std::max(second, q[i]);
  *kink = q[k] - second < band;
  return q[k];
}

// Capped cylinder about z (radius r, half height hh).
double cylinder_sdf(const Vector3d& x, double r, double hh, Vector3d* g, bool* kink, double band) {
  const double rho = std::hypot(x.x(), x.y());
  const Vector3d radial = rho > 1e-12 ? Vector3d(x.x() / rho, x.y() / rho, 0.0) : Vector3d::UnitX();
  const double a = rho - r, b = std::abs(x.z()) - hh;
  const Vector3d axial(0, 0, x.z() < 0 ? -1.0 : 1.0);
  if (a > 0.0 && b > 0.0) {
    const double d = std::hypot(a, b);
    *g = (a * radial + b * axial) / d;
    *kink = false;
    return d;
  }
  if (a > b) {
    *g = radial;
    *kink = rho < band || a - b < band;
    return a > 0.0 ? a : a;
  }
  *g = axial;
  *kink = b - a < band || std::abs(x.z()) < band;
  return b;
}

}  // namespace

double primitive_sdf(const Primitive3& q, const Eigen::Vector3d& x_W, Eigen::Vector3d* grad_W, bool* kink,
                     double kink_band) {
  const Vector3d x = q.T_W_P.inverse() * x_W;
  Vector3d g = Vector3d::UnitZ();
  double d = 0.0;
  switch (q.kind) {
    case PrimitiveKind::kBox:
      d = box_sdf(x, q.half, &g, kink, kink_band);
      break;
    case PrimitiveKind::kCylinder:
      d = cylinder_sdf(x, q.half.x(), q.half.z(), &g, kink, kink_band);
      break;
    case PrimitiveKind::kSphere: {
      const double n = x.norm();
      g = n > 1e-12 ? Vector3d(x / n) : Vector3d::UnitZ();
      *kink = n < kink_band;
      d = n - q.half.x();
      break;
    }
  }
  *grad_W = q.T_W_P.linear() * g;
  return d;
}

Eigen::AlignedBox3d primitive_bounds(const Primitive3& q) {
  Eigen::AlignedBox3d b;
  const Vector3d h = q.kind == PrimitiveKind::kSphere ? Vector3d::Constant(q.half.x()) : q.half;
  for (int c = 0; c < 8; ++c) {
    const Vector3d corner((c & 1) ? h.x() : -h.x(), (c & 2) ? h.y() : -h.y(), (c & 4) ? h.z() : -h.z());
    b.extend(q.T_W_P * corner);
  }
  return b;
}

namespace {

Cloud::Ptr cloud_of(const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& idx) {
  Cloud::Ptr c(new Cloud);
  c->reserve(idx.size());
  for (std::uint32_t k : idx) c->push_back(pcl::PointXYZ(cells[k].p.cast<float>().x(), cells[k].p.cast<float>().y(),
                                                        cells[k].p.cast<float>().z()));
  return c;
}

Normals::Ptr normals_of(const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& idx) {
  Normals::Ptr c(new Normals);
  c->reserve(idx.size());
  for (std::uint32_t k : idx) {
    pcl::Normal n;
    n.normal_x = static_cast<float>(cells[k].n.x());
    n.normal_y = static_cast<float>(cells[k].n.y());
    n.normal_z = static_cast<float>(cells[k].n.z());
    c->push_back(n);
  }
  return c;
}


struct PlaneFit {
  Vector3d n = Vector3d::UnitZ();  // toward the sensor
  double d = 0.0;                  // n.x + d = 0
  std::vector<std::uint32_t> inliers;
  double rms = 0.0;
};

double cos_of(double a) { return std::cos(a); }

// One plane through the cells idx (global indices): NORMAL_PLANE RANSAC, then
// inliers recomputed (distance and normal) against the refined plane.
bool fit_plane(const Shape3dParams& p, const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& idx,
               PlaneFit& out) {
  if (idx.size() < 3) return false;
  using M = pcl::SampleConsensusModelNormalPlane<pcl::PointXYZ, pcl::Normal>;
  M::Ptr m(new M(cloud_of(cells, idx)));
  m->setInputNormals(normals_of(cells, idx));
  m->setNormalDistanceWeight(0.1);
  Eigen::VectorXf c;
  if (!ransac_refined<M>(m, p.inlier_distance, p.max_iterations, c) || c.size() < 4) return false;
  Vector3d n(c[0], c[1], c[2]);
  if (!(n.norm() > 1e-9)) return false;
  double d = c[3] / n.norm();
  n.normalize();
  // Toward the sensor: the side most inliers' normals face.
  double sum = 0.0;
  for (std::uint32_t k : idx) sum += n.dot(cells[k].n);
  if (sum < 0.0) {
    n = -n;
    d = -d;
  }
  out.n = n;
  out.d = d;
  out.inliers.clear();
  double ss = 0.0;
  const double cmin = cos_of(p.normal_angle);
  for (std::uint32_t k : idx) {
    const double e = n.dot(cells[k].p) + d;
    if (std::abs(e) <= p.inlier_distance && n.dot(cells[k].n) >= cmin) {
      out.inliers.push_back(k);
      ss += e * e;
    }
  }
  out.rms = out.inliers.empty() ? 0.0 : std::sqrt(ss / static_cast<double>(out.inliers.size()));
  return out.inliers.size() >= 3;
}

// Connected groups of the cells idx (radius `tol`), largest first.
std::vector<std::vector<std::uint32_t>> clusters_of(const std::vector<CellSample3>& cells,
                                                    const std::vector<std::uint32_t>& idx, double tol) {
  std::vector<std::vector<std::uint32_t>> out;
  if (idx.empty()) return out;
  Cloud::Ptr c = cloud_of(cells, idx);
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(c);
  std::vector<std::uint8_t> done(idx.size(), 0);
  pcl::Indices nb;
  std::vector<float> d2;
  std::vector<std::uint32_t> stack;
  for (std::uint32_t s = 0; s < idx.size(); ++s) {
    if (done[s]) continue;
    std::vector<std::uint32_t> group;
    stack.assign(1, s);
    done[s] = 1;
    while (!stack.empty()) {
      const std::uint32_t k = stack.back();
      stack.pop_back();
      group.push_back(idx[k]);
      tree.radiusSearch(c->points[k], tol, nb, d2);
      for (const auto j : nb) {
        if (done[static_cast<std::size_t>(j)]) continue;
        done[static_cast<std::size_t>(j)] = 1;
        stack.push_back(static_cast<std::uint32_t>(j));
      }
    }
    out.push_back(std::move(group));
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  return out;
}

// Distance of cell k to the primitive's surface and whether it was seen from outside.
bool on_primitive(const Primitive3& q, const CellSample3& c, double tol) {
  Vector3d g;
  bool kink = false;
  const double d = primitive_sdf(q, c.p, &g, &kink, 0.0);
  return std::abs(d) <= tol;
}

// The share of samples inside the primitive (inset by a sample step, and
// beyond `exclude` of the seen surface) that the camera saw free.
double free_share(const Shape3dParams& p, const Primitive3& q, const SeenFree& seen_free) {
  if (!seen_free) return 0.0;
  const Eigen::AlignedBox3d b = primitive_bounds(q);
  const double st = p.free_sample_step;
  std::size_t inside = 0, free = 0;
  for (double z = b.min().z() + 0.5 * st; z < b.max().z(); z += st)
    for (double y = b.min().y() + 0.5 * st; y < b.max().y(); y += st)
      for (double x = b.min().x() + 0.5 * st; x < b.max().x(); x += st) {
        const Vector3d v(x, y, z);
        Vector3d g;
        bool kink = false;
        if (primitive_sdf(q, v, &g, &kink, 0.0) > -st) continue;  // only well inside
        ++inside;
        if (seen_free(v)) ++free;
        if (inside > 200000) break;  // bounded: a huge primitive is refused elsewhere
      }
  return inside > 0 ? static_cast<double>(free) / static_cast<double>(inside) : 0.0;
}

// Seen cells more than inlier_distance inside q, over its object's cell count.
double inside_share(const Shape3dParams& p, const Primitive3& q, const std::vector<CellSample3>& cells,
                    std::size_t object_cells) {
  const Eigen::AlignedBox3d b = primitive_bounds(q);
  std::size_t inside = 0;
  for (const CellSample3& c : cells) {
    if (!b.contains(c.p)) continue;
    Vector3d g;
    bool kink = false;
    if (primitive_sdf(q, c.p, &g, &kink, 0.0) < -p.inlier_distance) ++inside;
  }
  return static_cast<double>(inside) / static_cast<double>(std::max<std::size_t>(1, object_cells));
}

bool seen_from_outside(const Primitive3& q, const std::vector<CellSample3>& cells,
                       const std::vector<std::uint32_t>& inl) {
  std::size_t out = 0;
  for (std::uint32_t k : inl) {
    Vector3d g;
    bool kink = false;
    primitive_sdf(q, cells[k].p, &g, &kink, 0.0);
    if (g.dot(cells[k].n) > 0.0) ++out;
  }
  return out * 10 >= inl.size() * 9;
}

struct Fit {
  Primitive3 q;
  std::vector<std::uint32_t> inliers;
};

bool fit_sphere(const Shape3dParams& p, const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& obj,
                Fit& out) {
  using M = pcl::SampleConsensusModelSphere<pcl::PointXYZ>;
  M::Ptr m(new M(cloud_of(cells, obj)));
  m->setRadiusLimits(p.min_radius, p.max_radius);
  Eigen::VectorXf c;
  if (!ransac_refined<M>(m, p.inlier_distance, p.max_iterations, c) || c.size() < 4) return false;
  Primitive3 q;
  q.kind = PrimitiveKind::kSphere;
  q.T_W_P = Eigen::Translation3d(Vector3d(c[0], c[1], c[2])) * Eigen::Isometry3d::Identity();
  q.half = Vector3d::Constant(std::abs(static_cast<double>(c[3])));
  if (!(q.half.x() >= p.min_radius && q.half.x() <= p.max_radius)) return false;
  out.inliers.clear();
  double ss = 0.0;
  Vector3d mean = Vector3d::Zero();
  for (std::uint32_t k : obj) {
    const double e = (cells[k].p - q.T_W_P.translation()).norm() - q.half.x();
    if (std::abs(e) > p.inlier_distance) continue;
    out.inliers.push_back(k);
    ss += e * e;
    mean += cells[k].n;
  }
  if (out.inliers.size() < p.min_points) return false;
  q.rms = std::sqrt(ss / static_cast<double>(out.inliers.size()));
  q.inliers = static_cast<std::uint32_t>(out.inliers.size());
  q.points = static_cast<std::uint32_t>(obj.size());
  // A cap, not a flat patch: the inliers' normals spread.
  mean.normalize();
  double spread = 0.0;
  for (std::uint32_t k : out.inliers) spread = std::max(spread, std::acos(std::clamp(mean.dot(cells[k].n), -1.0, 1.0)));
  if (q.rms > p.max_rms || spread < p.min_sphere_spread ||
      static_cast<double>(q.inliers) < p.min_inlier_ratio * static_cast<double>(obj.size()) ||
      !seen_from_outside(q, cells, out.inliers))
    return false;
  out.q = q;
  return true;
}


Eigen::Matrix3d frame_with_z(const Vector3d& z) {
  const Vector3d a = std::abs(z.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
  const Vector3d x = (a - a.dot(z) * z).normalized();
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = z.cross(x);
  R.col(2) = z;
  return R;
}

bool fit_cylinder(const Shape3dParams& p, const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& obj,
                  const Shape3dModel& model, Fit& out) {
  using M = pcl::SampleConsensusModelCylinder<pcl::PointXYZ, pcl::Normal>;
  const Vector3d up = model.have_support ? Vector3d(model.support.head<3>()) : Vector3d::UnitZ();
  const std::vector<std::uint32_t>* input = &obj;
  std::vector<std::uint32_t> no_top;
  if (model.have_support) {
    // A standing cylinder's top cap is no part of its side: RANSAC on the
    // cells not facing up along the support's normal.
    for (std::uint32_t k : obj)
      if (cells[k].n.dot(up) < std::cos(p.normal_angle)) no_top.push_back(k);
    if (no_top.size() >= p.min_points) input = &no_top;
  }
  M::Ptr m(new M(cloud_of(cells, *input)));
  m->setInputNormals(normals_of(cells, *input));
  m->setNormalDistanceWeight(0.1);
  m->setRadiusLimits(p.min_radius, p.max_radius);
  Eigen::VectorXf c;
  if (!ransac_refined<M>(m, p.inlier_distance, p.max_iterations, c) || c.size() < 7) return false;
  Vector3d axis(c[3], c[4], c[5]);
  if (!(axis.norm() > 1e-9)) return false;
  axis.normalize();
  // Up along the support normal (or W's z) when the axis is nearly so: caps are then top and bottom.
  if (axis.dot(up) < 0.0) axis = -axis;
  Vector3d a0(c[0], c[1], c[2]);
  double r = std::abs(static_cast<double>(c[6]));
  // The RANSAC cylinder's own inliers (before the axis is snapped below).
  std::vector<std::uint32_t> sac_in;
  for (std::uint32_t k : *input) {
    const Vector3d v = cells[k].p - a0;
    if (std::abs((v - v.dot(axis) * axis).norm() - r) <= p.inlier_distance) sac_in.push_back(k);
  }
  if (model.have_support) {
    // Standing or lying on the support: the axis exactly so, then the circle
    // refitted across it (Kasa least squares on the RANSAC inliers).
    const double tilt = std::acos(std::clamp(axis.dot(up), -1.0, 1.0));
    if (tilt < p.right_angle_tolerance) axis = up;
    if (std::abs(tilt - 0.5 * std::numbers::pi) < p.right_angle_tolerance)
      axis = (axis - axis.dot(up) * up).normalized();
    const Eigen::Matrix3d F = frame_with_z(axis);
    Eigen::MatrixXd A(0, 3);
    Eigen::VectorXd bvec(0);
    std::vector<Eigen::Vector2d> uv;
    // Not the cells at either end: a cap's rim holds cap points inside the radius.
    double tlo = 1e300, thi = -1e300;
    for (std::uint32_t k : sac_in) {
      const double t = (cells[k].p - a0).dot(axis);
      tlo = std::min(tlo, t);
      thi = std::max(thi, t);
    }
    const double trim = 2.5 * p.inlier_distance;
    for (std::uint32_t k : sac_in) {
      const double t = (cells[k].p - a0).dot(axis);
      if (t < tlo + trim || t > thi - trim) continue;
      uv.emplace_back(F.col(0).dot(cells[k].p), F.col(1).dot(cells[k].p));
    }
    if (uv.size() >= 3) {
      A.resize(static_cast<Eigen::Index>(uv.size()), 3);
      bvec.resize(static_cast<Eigen::Index>(uv.size()));
      for (std::size_t i = 0; i < uv.size(); ++i) {
        A.row(static_cast<Eigen::Index>(i)) << 2.0 * uv[i].x(), 2.0 * uv[i].y(), 1.0;
        bvec[static_cast<Eigen::Index>(i)] = uv[i].squaredNorm();
      }
      const Vector3d sol = A.colPivHouseholderQr().solve(bvec);
      const double r2 = sol[2] + sol[0] * sol[0] + sol[1] * sol[1];
      if (sol.allFinite() && r2 > 0.0) {
        const double along = axis.dot(a0);
        a0 = sol[0] * F.col(0) + sol[1] * F.col(1) + along * axis;
        r = std::sqrt(r2);
      }
    }
  }
  if (!(r >= p.min_radius && r <= p.max_radius)) return false;
  const Eigen::Matrix3d R = frame_with_z(axis);
  std::vector<std::uint32_t> side;
  std::vector<double> ang;
  double ss = 0.0, lo = 1e300, hi = -1e300;
  for (std::uint32_t k : obj) {
    const Vector3d v = cells[k].p - a0;
    const double t = v.dot(axis);
    const Vector3d radial = v - t * axis;
    const double e = radial.norm() - r;
    if (std::abs(e) > p.inlier_distance || radial.norm() < 1e-9) continue;
    lo = std::min(lo, t);
    hi = std::max(hi, t);
    // The side proper (its arc, fit error, seen from outside): normals
    // across the axis (not a cap's rim).
    if (radial.normalized().dot(cells[k].n) < std::cos(p.normal_angle)) continue;
    side.push_back(k);
    ss += e * e;
    const Vector3d l = R.transpose() * radial;
    ang.push_back(std::atan2(l.y(), l.x()));
  }
  if (side.size() < p.min_points) return false;
  const double rms = std::sqrt(ss / static_cast<double>(side.size()));
  const double arc = arc_spanned(ang);
  // The top: cells clearly within the radius at or above the side's top
  // end (by position: on a small cylinder the 5 cm normals blend top and side).
  std::vector<std::uint32_t> cap;
  double top = hi;
  for (std::uint32_t k : obj) {
    const Vector3d v = cells[k].p - a0;
    const double t = v.dot(axis);
    const double rho = (v - t * axis).norm();
    if (rho <= r - 0.5 * p.inlier_distance && t >= hi - 3.0 * p.inlier_distance) cap.push_back(k);
  }
  if (cap.size() >= 3) {
    // The cap's height: the mean of its cells (a plane's noise, not its highest cell).
    double s = 0.0;
    for (std::uint32_t k : cap) s += (cells[k].p - a0).dot(axis);
    top = std::max(hi, s / static_cast<double>(cap.size()));
  }
  double bottom = lo;
  // Standing on the support: down to it.
  if (model.have_support && axis.dot(up) > std::cos(p.right_angle_tolerance)) {
    const Vector3d n = model.support.head<3>();
    const double t_support = -(n.dot(a0) + model.support[3]) / n.dot(axis);
    if (t_support < lo && lo - t_support <= p.support_snap) bottom = t_support;
  }
  // Lying on the support (axis along it): the lowest side point must be near it; nothing to extend.
  Primitive3 q;
  q.kind = PrimitiveKind::kCylinder;
  q.T_W_P.linear() = R;
  q.T_W_P.translation() = a0 + 0.5 * (top + bottom) * axis;
  q.half = Vector3d(r, r, 0.5 * (top - bottom));
  q.rms = rms;
  q.arc = arc;
  q.points = static_cast<std::uint32_t>(obj.size());
  // Explained: the object's cells on the capped cylinder's surface.
  std::vector<std::uint32_t> inl;
  for (std::uint32_t k : obj)
    if (on_primitive(q, cells[k], 1.5 * p.inlier_distance)) inl.push_back(k);
  q.inliers = static_cast<std::uint32_t>(inl.size());
  if (rms > p.max_rms || arc < p.min_arc || !(q.half.z() > 0.0) ||
      static_cast<double>(inl.size()) < p.min_inlier_ratio * static_cast<double>(obj.size()) ||
      !seen_from_outside(q, cells, side))
    return false;
  out.q = q;
  out.inliers = std::move(inl);
  return true;
}

// The smallest-area rectangle round the points (u, v), searched over angles
// in 1 degree steps: its angle, centre (u, v) and half sizes.
void min_rectangle(const std::vector<Eigen::Vector2d>& pts, double* angle, Eigen::Vector2d* centre,
                   Eigen::Vector2d* half) {
  double best = 1e300;
  for (int a = 0; a < 90; ++a) {
    const double t = a * std::numbers::pi / 180.0;
    const Eigen::Vector2d e0(std::cos(t), std::sin(t)), e1(-std::sin(t), std::cos(t));
    double lo0 = 1e300, hi0 = -1e300, lo1 = 1e300, hi1 = -1e300;
    for (const auto& q : pts) {
      lo0 = std::min(lo0, e0.dot(q));
      hi0 = std::max(hi0, e0.dot(q));
      lo1 = std::min(lo1, e1.dot(q));
      hi1 = std::max(hi1, e1.dot(q));
    }
    const double area = (hi0 - lo0) * (hi1 - lo1);
    if (area < best) {
      best = area;
      *angle = t;
      *centre = 0.5 * (lo0 + hi0) * e0 + 0.5 * (lo1 + hi1) * e1;
      *half = Eigen::Vector2d(0.5 * (hi0 - lo0), 0.5 * (hi1 - lo1));
    }
  }
}

// Whether the box's side along side * R.col(a) was seen although no plane
// was fitted to it: at least min_face_points of the object's cells off the
// faces' planes lie at or beyond the seen edge (within the other axes'
// extents). A low side (a book's 3 cm front) has too few rows for its 5 cm
// normals to leave the top's: they are blended, so no face fit takes them,
// and moving that edge out by the top's sample spacing put the book's front
// 6-19 mm proud of where the camera saw it (the shape log, home table).
// Its cells pin the edge instead (their median, when beyond it).
bool side_seen(const Shape3dParams& p, const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& obj,
               const std::vector<std::uint8_t>& on_face, const Eigen::Matrix3d& R, int a, int side,
               const Vector3d& lo_seen, const Vector3d& hi_seen, Vector3d* lo, Vector3d* hi) {
  const double tol = p.inlier_distance;
  const double edge = side > 0 ? hi_seen[a] : lo_seen[a];
  std::vector<double> at;
  for (std::uint32_t k : obj) {
    if (on_face[k]) continue;
    const Vector3d l = R.transpose() * cells[k].p;
    if (side * (l[a] - edge) < -1.5 * tol) continue;
    bool within = true;
    for (int b = 0; b < 3; ++b)
      if (b != a) within = within && l[b] >= lo_seen[b] - tol && l[b] <= hi_seen[b] + tol;
    if (within) at.push_back(l[a]);
  }
  if (at.size() < p.min_face_points) return false;
  std::nth_element(at.begin(), at.begin() + static_cast<std::ptrdiff_t>(at.size() / 2), at.end());
  const double median = at[at.size() / 2];
  if (side > 0) (*hi)[a] = std::max((*hi)[a], median);
  else (*lo)[a] = std::min((*lo)[a], median);
  return true;
}

bool fit_box(const Shape3dParams& p, const std::vector<CellSample3>& cells, const std::vector<std::uint32_t>& obj,
             const Shape3dModel& model, Fit& out) {
  // Up to three planes in turn on what the previous ones left.
  std::vector<PlaneFit> faces;
  std::vector<std::uint32_t> rest = obj;
  for (int i = 0; i < 3 && rest.size() >= p.min_face_points; ++i) {
    PlaneFit f;
    if (!fit_plane(p, cells, rest, f) || f.inliers.size() < p.min_face_points || f.rms > p.max_rms) break;
    // At right angles to the faces so far, or it is not this box's.
    bool ok = true;
    for (const PlaneFit& g : faces) ok = ok && std::abs(f.n.dot(g.n)) < std::sin(p.right_angle_tolerance);
    if (!ok) break;
    std::vector<std::uint32_t> next;
    std::vector<std::uint8_t> in(cells.size(), 0);
    for (std::uint32_t k : f.inliers) in[k] = 1;
    for (std::uint32_t k : rest)
      if (!in[k]) next.push_back(k);
    rest.swap(next);
    faces.push_back(std::move(f));
  }
  if (faces.empty()) return false;
  // A convex corner: each face behind the other faces' planes.
  for (std::size_t i = 0; i < faces.size(); ++i)
    for (std::size_t j = 0; j < faces.size(); ++j) {
      if (i == j) continue;
      std::size_t behind = 0;
      for (std::uint32_t k : faces[j].inliers)
        if (faces[i].n.dot(cells[k].p) + faces[i].d <= p.inlier_distance) ++behind;
      if (behind * 10 < faces[j].inliers.size() * 9) return false;
    }
  Eigen::Matrix3d R;
  const Vector3d up = model.have_support ? Vector3d(model.support.head<3>()) : Vector3d::UnitZ();
  bool slab = false;
  if (faces.size() == 1) {
    // One face: a box only as a slab on the support (its top parallel to it).
    if (!model.have_support || faces[0].n.dot(up) < std::cos(p.right_angle_tolerance)) return false;
    slab = true;
    const Eigen::Matrix3d F = frame_with_z(faces[0].n);
    std::vector<Eigen::Vector2d> uv;
    for (std::uint32_t k : faces[0].inliers) uv.emplace_back(F.col(0).dot(cells[k].p), F.col(1).dot(cells[k].p));
    double ang = 0.0;
    Eigen::Vector2d c2, h2;
    min_rectangle(uv, &ang, &c2, &h2);
    R.col(0) = std::cos(ang) * F.col(0) + std::sin(ang) * F.col(1);
    R.col(2) = faces[0].n;
    R.col(1) = R.col(2).cross(R.col(0));
  } else {
    R.col(0) = faces[0].n;
    R.col(1) = (faces[1].n - faces[1].n.dot(R.col(0)) * R.col(0)).normalized();
    R.col(2) = R.col(0).cross(R.col(1));
  }
  // Extents: the inliers in the box axes; each face's own plane bounds its side.
  Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
  double ss = 0.0;
  std::size_t n_in = 0;
  std::vector<std::uint32_t> inl;
  // Extents: every cell of the object on a face's plane (by distance: the
  // cells at an edge have blended normals and are no face's inliers, but
  // they are what pins the edge).
  for (std::uint32_t k : obj) {
    for (const PlaneFit& f : faces) {
      const double e = f.n.dot(cells[k].p) + f.d;
      if (std::abs(e) > p.inlier_distance) continue;
      const Vector3d l = R.transpose() * cells[k].p;
      lo = lo.cwiseMin(l);
      hi = hi.cwiseMax(l);
      ss += e * e;
      ++n_in;
      inl.push_back(k);
      break;
    }
  }
  for (const PlaneFit& f : faces) {
    for (int a = 0; a < 3; ++a) {
      const double c = R.col(a).dot(f.n);
      if (c > 0.9) hi[a] = -f.d / c;
      if (c < -0.9) lo[a] = f.d / -c;
    }
  }
  // Down to the support when the bottom is near it (a box on the table; a slab always).
  if (model.have_support) {
    const Vector3d n = model.support.head<3>();
    for (int a = 0; a < 3; ++a) {
      const double c = R.col(a).dot(n);
      if (std::abs(c) < std::cos(p.right_angle_tolerance)) continue;
      // The support plane at coordinate t along axis a: n.(R (.., t, ..)) + d = 0, near the box.
      const Vector3d mid = R * (0.5 * (lo + hi));
      const double t = R.col(a).dot(mid) - (n.dot(mid) + model.support[3]) / c;
      if (c > 0 && t < lo[a] && (lo[a] - t <= p.support_snap || slab)) lo[a] = t;
      if (c < 0 && t > hi[a] && (t - hi[a] <= p.support_snap || slab)) hi[a] = t;
    }
  }
  // Sides with no face of their own (nor the support): out by half the
  // sample spacing of the cells at that edge (see the header), unless the
  // side itself was seen: then its cells pin it (side_seen).
  const Vector3d lo_seen = lo, hi_seen = hi;
  std::vector<std::uint8_t> on_face(cells.size(), 0);
  for (std::uint32_t k : inl) on_face[k] = 1;
  for (int a = 0; a < 3; ++a) {
    for (const int side : {-1, 1}) {
      bool face = false;
      for (const PlaneFit& f : faces) face = face || side * R.col(a).dot(f.n) > 0.9;
      if (model.have_support && side * R.col(a).dot(Vector3d(model.support.head<3>())) < -0.9) face = true;
      if (face) continue;
      if (side_seen(p, cells, obj, on_face, R, a, side, lo_seen, hi_seen, &lo, &hi)) continue;
      const Vector3d u = side * R.col(a);
      const double edge = side > 0 ? hi[a] : lo[a];
      double sum = 0.0;
      int n = 0;
      for (std::uint32_t k : inl) {
        if (std::abs(R.col(a).dot(cells[k].p) - edge) > 1.5 * p.inlier_distance || !(cells[k].range_pitch > 0.0)) continue;
        const double c = u.dot(cells[k].view);
        sum += cells[k].range_pitch / std::sqrt(std::max(0.01, 1.0 - c * c));
        ++n;
      }
      if (n == 0) continue;
      const double ext = std::min(p.max_edge_extension, 0.5 * sum / n);
      (side > 0 ? hi[a] : lo[a]) += side * ext;
    }
  }
  const Vector3d size = hi - lo;
  if (!(size.minCoeff() >= p.min_box_height) || size.maxCoeff() > p.max_box_size) return false;
  Primitive3 q;
  q.kind = PrimitiveKind::kBox;
  q.T_W_P.linear() = R;
  q.T_W_P.translation() = R * (0.5 * (lo + hi));
  q.half = 0.5 * size;
  q.rms = std::sqrt(ss / static_cast<double>(std::max<std::size_t>(1, n_in)));
  q.faces = static_cast<int>(faces.size());
  // Explained: the object's cells on the box's surface (edges included,
  // whose blended normals keep them off every face's fit).
  inl.clear();
  for (std::uint32_t k : obj)
    if (on_primitive(q, cells[k], 1.5 * p.inlier_distance)) inl.push_back(k);
  q.inliers = static_cast<std::uint32_t>(inl.size());
  q.points = static_cast<std::uint32_t>(obj.size());
  if (q.rms > p.max_rms || static_cast<double>(inl.size()) < p.min_inlier_ratio * static_cast<double>(obj.size()))
    return false;
  out.q = q;
  out.inliers = std::move(inl);
  return true;
}

}  // namespace

void complete_shapes_3d(const Shape3dParams& p, const std::vector<CellSample3>& cells, const SeenFree& seen_free,
                        Shape3dModel& out) {
  std::vector<Primitive3> previous;
  previous.swap(out.primitives);
  out.owner.assign(cells.size(), -1);
  out.have_support = false;
  out.support.setZero();
  out.support_cells = 0;
  out.objects = 0;
  out.kept = 0;
  out.refused_free = 0;
  out.refused_inside = 0;
  if (!p.enabled || !validate(p).empty() || cells.size() < p.min_points) return;
  std::vector<std::uint32_t> all(cells.size());
  std::iota(all.begin(), all.end(), 0u);
  std::vector<std::uint8_t> taken(cells.size(), 0);
  {
    PlaneFit f;
    if (fit_plane(p, cells, all, f) &&
        static_cast<double>(f.inliers.size()) >= p.min_support_share * static_cast<double>(cells.size())) {
      out.have_support = true;
      out.support << f.n, f.d;
      out.support_cells = f.inliers.size();
      for (std::uint32_t k : f.inliers) taken[k] = 1;
    }
  }
  std::vector<std::uint32_t> rest;
  for (std::uint32_t k = 0; k < cells.size(); ++k)
    if (!taken[k]) rest.push_back(k);
  const double tol = p.inlier_distance;
  // The objects' cells with normals estimated afresh (PCL) at the fits' scale.
  std::vector<CellSample3> local = cells;
  if (p.fit_normal_radius > 0.0 && rest.size() >= 3) {
    Cloud::Ptr c = cloud_of(cells, rest);
    pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
    pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
    ne.setInputCloud(c);
    ne.setSearchMethod(tree);
    ne.setRadiusSearch(p.fit_normal_radius);
    Normals nn;
    ne.compute(nn);
    for (std::size_t i = 0; i < rest.size(); ++i) {
      Vector3d n(nn.points[i].normal_x, nn.points[i].normal_y, nn.points[i].normal_z);
      if (!n.allFinite() || n.norm() < 0.5) continue;  // too few neighbours: the given normal stays
      CellSample3& q = local[rest[i]];
      n.normalize();
      q.n = n.dot(q.view) < 0.0 ? Vector3d(-n) : n;
    }
  }
  for (const std::vector<std::uint32_t>& obj : clusters_of(local, rest, p.cluster_tolerance)) {
    if (obj.size() < p.min_points || out.objects == p.max_objects) break;  // largest first
    ++out.objects;
    // Each kind that passes its tests and closes no space seen free; the one
    // explaining most of the object's cells wins (a box's corner can pass
    // as a wide cylinder's arc, but the box explains more).
    Fit fit;
    bool ok = false;
    for (int kind = 0; kind < 3; ++kind) {
      Fit f;
      const bool passed = kind == 0   ? fit_sphere(p, local, obj, f)
                          : kind == 1 ? fit_cylinder(p, local, obj, out, f)
                                      : fit_box(p, cells, obj, out, f);
      if (!passed) continue;
      if (free_share(p, f.q, seen_free) > p.max_free_share) {
        ++out.refused_free;
        continue;
      }
      if (inside_share(p, f.q, cells, obj.size()) > p.max_inside_share) {
        ++out.refused_inside;
        continue;
      }
      if (!ok || f.q.inliers > fit.q.inliers) {
        fit = std::move(f);
        ok = true;
      }
    }
    if (!ok) {
      // Temporal coherence: a previous primitive the object's cells still lie on.
      for (const Primitive3& q : previous) {
        std::size_t on = 0;
        for (std::uint32_t k : obj) on += on_primitive(q, cells[k], tol) ? 1 : 0;
        if (on >= p.min_points && static_cast<double>(on) >= p.min_inlier_ratio * static_cast<double>(obj.size()) &&
            free_share(p, q, seen_free) <= p.max_free_share &&
            inside_share(p, q, cells, obj.size()) <= p.max_inside_share) {
          fit.q = q;
          fit.q.kept = true;
          ok = true;
          ++out.kept;
          break;
        }
      }
    }
    if (!ok) continue;
    fit.q.points = static_cast<std::uint32_t>(obj.size());
    const auto id = static_cast<std::int32_t>(out.primitives.size());
    out.primitives.push_back(fit.q);
    // The primitive stands for its object's cells on or inside it, and the
    // support's: where the table meets a box, the table cells' normals are
    // blended with the box's face (5 cm PCL normals), and their raw patches
    // would put solid in front of the fitted face. Never another object's.
    auto own = [&](std::uint32_t k) {
      Vector3d g;
      bool kink = false;
      if (out.owner[k] < 0 && primitive_sdf(fit.q, cells[k].p, &g, &kink, 0.0) <= 2.0 * tol) out.owner[k] = id;
    };
    for (std::uint32_t k : obj) own(k);
    for (std::uint32_t k = 0; k < cells.size(); ++k)
      if (taken[k]) own(k);
  }
}

std::string primitive_csv_header() {
  return "kind,cx,cy,cz,zx,zy,zz,xx,xy,xz,hx,hy,hz,rms,inliers,points,faces,arc,kept";
}

std::string primitive_csv_row(const Primitive3& q) {
  const char* kind = q.kind == PrimitiveKind::kBox ? "box" : q.kind == PrimitiveKind::kCylinder ? "cylinder" : "sphere";
  const Vector3d c = q.T_W_P.translation(), z = q.T_W_P.linear().col(2), x = q.T_W_P.linear().col(0);
  char buf[512];
  std::snprintf(buf, sizeof buf, "%s,%.5f,%.5f,%.5f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%.5f,%u,%u,%d,%.3f,%d",
                kind, c.x(), c.y(), c.z(), z.x(), z.y(), z.z(), x.x(), x.y(), x.z(), q.half.x(), q.half.y(), q.half.z(),
                q.rms, q.inliers, q.points, q.faces, q.arc, q.kept ? 1 : 0);
  return buf;
}

namespace {
constexpr std::size_t kCellFloats = 10;
static_assert(std::endian::native == std::endian::little, "the cell log is little-endian float32");
}  // namespace

std::string cells_to_bytes(const std::vector<CellSample3>& cells) {
  std::string out(cells.size() * kCellFloats * sizeof(float), '\0');
  std::size_t o = 0;
  for (const CellSample3& c : cells) {
    const float f[kCellFloats] = {static_cast<float>(c.p.x()),    static_cast<float>(c.p.y()),    static_cast<float>(c.p.z()),
                                  static_cast<float>(c.n.x()),    static_cast<float>(c.n.y()),    static_cast<float>(c.n.z()),
                                  static_cast<float>(c.view.x()), static_cast<float>(c.view.y()), static_cast<float>(c.view.z()),
                                  static_cast<float>(c.range_pitch)};
    std::memcpy(out.data() + o, f, sizeof f);
    o += sizeof f;
  }
  return out;
}

std::string cells_from_bytes(const std::string& bytes, std::vector<CellSample3>* out) {
  constexpr std::size_t rec = kCellFloats * sizeof(float);
  if (bytes.size() % rec != 0) return "shape log cells: size is not a whole number of cells";
  std::vector<CellSample3> cells(bytes.size() / rec);
  for (std::size_t i = 0; i < cells.size(); ++i) {
    float f[kCellFloats];
    std::memcpy(f, bytes.data() + i * rec, rec);
    for (float v : f)
      if (!std::isfinite(v)) return "shape log cells: cell " + std::to_string(i) + " is not finite";
    CellSample3& c = cells[i];
    c.p = Vector3d(f[0], f[1], f[2]);
    c.n = Vector3d(f[3], f[4], f[5]);
    c.view = Vector3d(f[6], f[7], f[8]);
    c.range_pitch = f[9];
    if (std::abs(c.n.norm() - 1.0) > 1e-3 || std::abs(c.view.norm() - 1.0) > 1e-3 || c.range_pitch < 0.0)
      return "shape log cells: cell " + std::to_string(i) + " has no unit normal or view";
  }
  out->swap(cells);
  return {};
}

}  // namespace hemm::mapping
