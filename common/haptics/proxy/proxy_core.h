#pragma once
// Internal: the god-object step shared by the map-based proxy and the exact
// reference. Templated on a Scene adapter providing
//   std::size_t gather(const Vector2d& c, double r, uint32_t* out, std::size_t cap) const
//   Surface closest(uint32_t id, const Vector2d& x) const   // distance to the surface + unit normal
//   double sweep(uint32_t id, const Vector2d& x, const Vector2d& dx, double rho) const
//       // first s >= 0 with distance(x + s dx) == rho, +inf if none (x starts farther than rho)
// Not part of the public API.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Core>

#include "common/haptics/proxy/virtual_proxy.h"
#include "common/math/geometry2.h"

namespace hemm::haptics::detail {

using Eigen::Vector2d;

struct Surface {
  double distance = std::numeric_limits<double>::infinity();  // from the proxy centre to the surface
  Vector2d normal = Vector2d::UnitX();                          // unit, from the surface to the proxy
};

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kContactTol = 1e-9;   // m: within this of rho counts as touching
constexpr double kPenetrationTol = 1e-7;  // m: deeper than this is pushed out

// First s >= 0 where |x + s dx - c| == R, for x outside (|x - c| >= R).
inline double ray_circle(const Vector2d& x, const Vector2d& dx, const Vector2d& c, double R) {
  const Vector2d f = x - c;
  const double A = dx.squaredNorm();
  const double Bh = f.dot(dx);  // half of B
  const double C = f.squaredNorm() - R * R;
  if (A <= 0.0 || Bh >= 0.0) return kInf;  // not moving, or moving away
  const double disc = Bh * Bh - A * C;
  if (disc < 0.0) return kInf;
  const double s = (-Bh - std::sqrt(disc)) / A;
  return s >= 0.0 ? s : 0.0;
}

// Distance surface of segment [a, b] (capsule core); seg_normal breaks the tie
// when x lies exactly on the segment.
inline Surface segment_surface(const Vector2d& a, const Vector2d& b, const Vector2d& seg_normal, const Vector2d& x) {
  const Vector2d c = math::closest_point_on_segment(a, b, x);
  const Vector2d v = x - c;
  const double dist = v.norm();
  Surface s;
  s.distance = dist;
  s.normal = dist > 1e-12 ? Vector2d(v / dist) : seg_normal;
  return s;
}

// Swept disc of radius rho against segment [a, b].
inline double segment_sweep(const Vector2d& a, const Vector2d& b, const Vector2d& x, const Vector2d& dx, double rho) {
  double best = std::min(ray_circle(x, dx, a, rho), ray_circle(x, dx, b, rho));
  const Vector2d ab = b - a;
  const double L = ab.norm();
  if (L <= 0.0) return best;
  const Vector2d u = ab / L;
  const Vector2d n = math::perp(u);
  const double h = n.dot(x - a);
  const double sigma = h >= 0.0 ? 1.0 : -1.0;
  const double hn = sigma * n.dot(dx);  // rate of change of |h|
  if (std::abs(h) >= rho && hn < 0.0) {
    const double s = (std::abs(h) - rho) / (-hn);
    const double t = u.dot(x + s * dx - a);
    if (t >= 0.0 && t <= L) best = std::min(best, s);
  }
  return best;
}

// Projection of delta onto the cone {y : n_i . y >= 0 for all i} (2D).
// *slide_on gets the constraint slid along, or -1 (free step or wedged).
inline Vector2d project_cone(const Vector2d* normals, int count, const Vector2d& delta, int* slide_on) {
  *slide_on = -1;
  const double eps = 1e-10 * delta.norm();
  bool violated = false;
  for (int i = 0; i < count; ++i) violated = violated || normals[i].dot(delta) < -eps;
  if (!violated) return delta;
  Vector2d best = Vector2d::Zero();
  double best_violation = kInf;
  for (int i = 0; i < count; ++i) {
    const double v = normals[i].dot(delta);
    if (v >= 0.0) continue;
    const Vector2d cand = delta - v * normals[i];
    bool feasible = true;
    for (int j = 0; j < count && feasible; ++j) feasible = normals[j].dot(cand) >= -eps;
    if (feasible && -v < best_violation) {
      best_violation = -v;
      best = cand;
      *slide_on = i;
    }
  }
  return best;  // zero: wedged in a concave corner
}

// The force law of every proxy (2D scan proxy, 3D point probe): e is the
// spring vector (proxy - device) in device metres; spring + damping along it
// while in contact, unilateral (never pulls), clamped to the peak /
// continuous rating (see ProxyModel). Updates the spring and limiter state.
template <int N>
Eigen::Matrix<double, N, 1> proxy_force(const ProxyModel& m, const Eigen::Matrix<double, N, 1>& e, bool contact,
                                        Eigen::Matrix<double, N, 1>& spring_prev, double& force_filtered,
                                        double& force_limit, bool& clamped) {
  using V = Eigen::Matrix<double, N, 1>;
  const double e_len = e.norm();
  V F = V::Zero();
  if (contact && e_len > 1e-12) {
    const V e_hat = e / e_len;
    const V e_dot = (e - spring_prev) / m.period;
    F = m.stiffness * e + m.damping * e_dot.dot(e_hat) * e_hat;
    if (F.dot(e_hat) < 0.0) F.setZero();  // a surface pushes, never pulls
    spring_prev = e;
  } else {
    spring_prev.setZero();
  }
  const double cont = m.force_continuous;
  const double ramp = std::clamp((force_filtered - 0.5 * cont) / (0.5 * cont), 0.0, 1.0);
  force_limit = m.force_peak - (m.force_peak - cont) * ramp;
  const double f_len = F.norm();
  clamped = f_len > force_limit;
  if (clamped) F *= force_limit / f_len;
  const double alpha = std::min(1.0, m.period / m.continuous_time_constant);
  force_filtered += alpha * (F.norm() - force_filtered);
  return F;
}

template <class Scene>
void god_object_tick(const ProxyModel& m, const Scene& scene, ProxyData& d, const Eigen::Vector3d& device_W,
                     double scale) {
  ++d.ticks;
  if (!device_W.allFinite() || !std::isfinite(scale) || !(scale > 0.0) || d.candidates.size() < 1) {
    ++d.rejected_inputs;
    d.force_W.setZero();
    d.spring_prev.setZero();
    return;
  }
  const double rho = m.probe_radius;
  const std::size_t cap = d.candidates.size();
  std::uint32_t* cand = d.candidates.data();
  Vector2d x = d.initialized ? d.proxy_W : Vector2d(device_W.head<2>());
  d.initialized = true;
  d.device_W = device_W;
  d.work = 0;
  // Every surface evaluation is counted: the tick's cost is bounded by the
  // caps (ProxyModel), and the tests check the count against that bound.
  auto closest = [&](std::uint32_t id, const Vector2d& p) {
    ++d.work;
    return scene.closest(id, p);
  };
  auto sweep = [&](std::uint32_t id, const Vector2d& p, const Vector2d& dp) {
    ++d.work;
    return scene.sweep(id, p, dp, rho);
  };

  // 1. Push the proxy out of surfaces it overlaps: only after the map changed
  //    under it (new scans), never as a result of its own motion.
  {
    std::size_t n = std::min(scene.gather(x, rho + 1e-6, cand, cap), cap);
    bool pushed = false;
    for (int it = 0; it < 4; ++it) {
      bool moved = false;
      for (std::size_t i = 0; i < n; ++i) {
        const Surface s = closest(cand[i], x);
        if (s.distance < rho - kPenetrationTol) {
          x += s.normal * (rho - s.distance);
          moved = true;
        }
      }
      pushed = pushed || moved;
      if (!moved) break;
    }
    if (pushed) ++d.depenetrations;
  }

  // 2. Gather everything the proxy could touch on its way: every position it
  //    takes stays within |goal - x| of the goal (each step moves toward the
  //    goal's projection), so a disc around the goal bounds the path.
  Vector2d goal = device_W.head<2>();
  double reach = (goal - x).norm();
  if (reach > m.max_step) {  // bounded motion per tick (ProxyModel::max_step)
    goal = x + (goal - x) * (m.max_step / reach);
    reach = m.max_step;
  }
  std::size_t n = 0;
  for (int shrink = 0;; ++shrink) {
    n = scene.gather(goal, reach + rho + 1e-6, cand, cap);
    if (n <= cap) break;
    if (shrink == 0) ++d.shrunk_queries;
    if (shrink >= 40) {  // too crowded even standing still: do not move
      goal = x;
      n = cap;
      break;
    }
    goal = x + 0.5 * (goal - x);  // shorter step this tick; the rest next tick
    reach *= 0.5;
  }

  // 3. Move, slide, repeat.
  int active = 0;
  std::array<std::uint32_t, kMaxContacts> active_ids{};
  for (int iter = 0; iter < m.max_iterations; ++iter) {
    active = 0;
    for (std::size_t i = 0; i < n && active < kMaxContacts; ++i) {
      const Surface s = closest(cand[i], x);
      if (s.distance <= rho + kContactTol) {
        active_ids[static_cast<std::size_t>(active)] = cand[i];
        d.contact_normals[static_cast<std::size_t>(active++)] = s.normal;
      }
    }
    const Vector2d delta = goal - x;
    if (delta.norm() <= 1e-12) break;
    int slide_on = -1;
    const Vector2d step = project_cone(d.contact_normals.data(), active, delta, &slide_on);
    const double step_len = step.norm();
    if (step_len <= 1e-12) break;
    double s_min = 1.0;
    for (std::size_t i = 0; i < n && s_min > 0.0; ++i) {
      const Surface s = closest(cand[i], x);
      if (s.distance <= rho + kContactTol) {
        if (s.normal.dot(step) < -1e-9 * step_len) s_min = 0.0;
        continue;
      }
      s_min = std::min(s_min, sweep(cand[i], x, step));
    }
    x += s_min * step;
    if (s_min >= 1.0 && step == delta) break;  // reached the goal freely
    if (s_min * step_len <= 1e-14) break;       // blocked
    if (slide_on >= 0 && s_min >= 1.0) {
      // A tangent step leaves a curved surface (an edge's rounded end, a
      // circle): retract back onto it along its normal, swept like any other
      // motion, so that the next step starts on the surface. Without this the
      // proxy zig-zags toward the constrained minimum and converges slowly.
      const Surface s = closest(active_ids[static_cast<std::size_t>(slide_on)], x);
      const double gap = s.distance - rho;
      // Infinite: the step left a one-sided surface's front (map segments):
      // nothing to retract onto.
      if (gap > kContactTol && std::isfinite(gap)) {
        const Vector2d back = -gap * s.normal;
        double r_min = 1.0;
        for (std::size_t i = 0; i < n && r_min > 0.0; ++i) {
          const Surface si = closest(cand[i], x);
          if (si.distance <= rho + kContactTol) {
            if (si.normal.dot(back) < -1e-9 * gap) r_min = 0.0;
            continue;
          }
          r_min = std::min(r_min, sweep(cand[i], x, back));
        }
        x += r_min * back;
      }
    }
  }
  active = 0;
  for (std::size_t i = 0; i < n && active < kMaxContacts; ++i) {
    const Surface s = closest(cand[i], x);
    if (s.distance <= rho + 10.0 * kContactTol) d.contact_normals[static_cast<std::size_t>(active++)] = s.normal;
  }
  d.contact_count = active;
  d.proxy_W = x;

  // 4. Force: spring + damping along the spring, unilateral, clamped.
  const Vector2d F = proxy_force<2>(m, Vector2d((x - device_W.head<2>()) / scale), active > 0, d.spring_prev,
                                    d.force_filtered, d.force_limit, d.clamped);
  d.force_W = Eigen::Vector3d(F.x(), F.y(), 0.0);
  d.max_work = std::max(d.max_work, d.work);
}

}  // namespace hemm::haptics::detail
