#include "common/haptics/proxy/reference_scene.h"

#include <cmath>

#include "common/haptics/proxy/proxy_core.h"

namespace hemm::haptics {

using Eigen::Vector2d;

void add_polygon(ExactScene& scene, const std::vector<Vector2d>& v) {
  for (std::size_t i = 0; i < v.size() && v.size() >= 2; ++i) scene.segments.push_back({v[i], v[(i + 1) % v.size()]});
}

void add_box(ExactScene& scene, const Vector2d& lo, const Vector2d& hi) {
  add_polygon(scene, {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}});
}

void add_thick_wall(ExactScene& scene, const Vector2d& a, const Vector2d& b, double thickness) {
  const Vector2d n = math::perp((b - a).normalized()) * (0.5 * thickness);
  add_polygon(scene, {a - n, b - n, b + n, a + n});
}

std::optional<double> raycast(const ExactScene& scene, const Vector2d& origin, const Vector2d& dir, double max_range) {
  const double dl = dir.norm();
  if (!(dl > 0.0) || !origin.allFinite()) return std::nullopt;
  const Vector2d u = dir / dl;
  double best = max_range;
  bool hit = false;
  for (const ExactSegment& s : scene.segments) {
    const Vector2d e = s.b - s.a;
    const double den = math::cross2(u, e);
    if (std::abs(den) < 1e-15) continue;
    const Vector2d w = s.a - origin;
    const double t = math::cross2(w, e) / den;
    const double q = math::cross2(w, u) / den;
    if (t >= 0.0 && q >= 0.0 && q <= 1.0 && t < best) {
      best = t;
      hit = true;
    }
  }
  for (const ExactCircle& c : scene.circles) {
    const Vector2d f = origin - c.centre;
    const double b = f.dot(u);
    const double cc = f.squaredNorm() - c.radius * c.radius;
    const double disc = b * b - cc;
    if (disc < 0.0) continue;
    double t = -b - std::sqrt(disc);
    if (t < 0.0) t = -b + std::sqrt(disc);
    if (t >= 0.0 && t < best) {
      best = t;
      hit = true;
    }
  }
  if (!hit) return std::nullopt;
  return best;
}

double distance_to_scene(const ExactScene& scene, const Vector2d& p) {
  double best = detail::kInf;
  for (const ExactSegment& s : scene.segments) best = std::min(best, math::distance_to_segment(s.a, s.b, p));
  for (const ExactCircle& c : scene.circles) best = std::min(best, (p - c.centre).norm() - c.radius);
  return best;
}

namespace {

// Ids: [0, segments) are segments, then circles. Brute force: the reference
// favours exactness over speed.
struct ExactAdapter {
  const ExactScene& scene;
  std::size_t gather(const Vector2d& c, double r, std::uint32_t* out, std::size_t cap) const {
    std::size_t n = 0;
    for (std::size_t i = 0; i < scene.segments.size(); ++i) {
      if (math::distance_to_segment(scene.segments[i].a, scene.segments[i].b, c) > r) continue;
      if (n < cap) out[n] = static_cast<std::uint32_t>(i);
      ++n;
    }
    for (std::size_t i = 0; i < scene.circles.size(); ++i) {
      if ((c - scene.circles[i].centre).norm() - scene.circles[i].radius > r) continue;
      if (n < cap) out[n] = static_cast<std::uint32_t>(scene.segments.size() + i);
      ++n;
    }
    return n;
  }
  detail::Surface closest(std::uint32_t id, const Vector2d& x) const {
    if (id < scene.segments.size()) {
      const ExactSegment& s = scene.segments[id];
      return detail::segment_surface(s.a, s.b, math::perp((s.b - s.a).normalized()), x);
    }
    const ExactCircle& c = scene.circles[id - scene.segments.size()];
    const Vector2d v = x - c.centre;
    const double len = v.norm();
    detail::Surface s;
    s.distance = len - c.radius;
    s.normal = len > 1e-12 ? Vector2d(v / len) : Vector2d::UnitX();
    return s;
  }
  double sweep(std::uint32_t id, const Vector2d& x, const Vector2d& dx, double rho) const {
    if (id < scene.segments.size()) {
      const ExactSegment& s = scene.segments[id];
      return detail::segment_sweep(s.a, s.b, x, dx, rho);
    }
    const ExactCircle& c = scene.circles[id - scene.segments.size()];
    return detail::ray_circle(x, dx, c.centre, c.radius + rho);
  }
};

}  // namespace

void reference_tick(const ProxyModel& m, const ExactScene& scene, ProxyData& d, const Eigen::Vector3d& device_W,
                    double scale) {
  detail::god_object_tick(m, ExactAdapter{scene}, d, device_W, scale);
}

ForceError force_error(const std::vector<Eigen::Vector3d>& rendered, const std::vector<Eigen::Vector3d>& truth) {
  ForceError e;
  if (rendered.size() != truth.size()) {
    e.valid = false;
    return e;
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < rendered.size(); ++i) {
    const double err = (rendered[i] - truth[i]).norm();
    sum += err * err;
    e.max = std::max(e.max, err);
  }
  e.count = rendered.size();
  e.rms = e.count > 0 ? std::sqrt(sum / static_cast<double>(e.count)) : 0.0;
  return e;
}

}  // namespace hemm::haptics
