#include "common/haptics/vps/point_probe.h"

#include <algorithm>
#include <cmath>

#include "common/haptics/proxy/proxy_core.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::vps {
namespace {

constexpr int kBisections = 10;
constexpr int kDepenetrationSteps = 4;

}  // namespace

std::string validate(const PointProbeParams& p) {
  if (std::string e = haptics::validate(p.force); !e.empty()) return e;
  if (!(p.max_step > 0.0) || !(p.max_step <= 1.0)) return "point probe: max_step must be in (0, 1] m";
  if (p.max_iterations < 1 || p.max_iterations > 16) return "point probe: max_iterations in [1, 16]";
  if (!(p.march_step_voxels >= 0.05) || !(p.march_step_voxels <= 1.0))
    return "point probe: march_step_voxels in [0.05, 1]";
  return {};
}

void point_probe_reset(PointProbeData& d, const Eigen::Vector3d& at_W) {
  d.initialized = true;
  d.proxy_W = at_W;
  d.spring_prev.setZero();
  d.force_W.setZero();
  d.contact = false;
}

std::uint64_t point_probe_max_work(const PointProbeParams& p, double voxel_size) {
  // Depenetration (phi + gradient each), then per iteration: the contact
  // test and its gradient, the march, the bisection, the retraction; the
  // final contact test.
  const double h = p.march_step_voxels * voxel_size;
  const auto march = static_cast<std::uint64_t>(std::ceil(p.max_step / h));
  return kDepenetrationSteps * 7 + static_cast<std::uint64_t>(p.max_iterations) * (7 + march + kBisections + 8 + 7) + 7;
}

void point_probe_tick(const PointProbeParams& p, const Voxmap* vm, PointProbeData& d, const Eigen::Vector3d& device_W,
                      double scale) noexcept {
  ++d.ticks;
  d.work = 0;
  if (!device_W.allFinite() || !std::isfinite(scale) || !(scale > 0.0)) {
    ++d.rejected_inputs;
    d.force_W.setZero();
    d.spring_prev.setZero();
    d.contact = false;
    return;
  }
  d.device_W = device_W;
  if (!d.initialized) point_probe_reset(d, device_W);
  const double rho = p.force.probe_radius;
  Eigen::Vector3d x = d.proxy_W;
  bool contact = false;

  if (vm == nullptr || !(vm->voxel_size > 0.0)) {
    x = device_W;  // nothing to touch
  } else {
    const double h = p.march_step_voxels * vm->voxel_size;
    const double tol = 1e-2 * vm->voxel_size;  // within this of rho counts as touching
    auto phi = [&](const Eigen::Vector3d& q) {
      ++d.work;
      return sdf_hermite(*vm, q);
    };
    auto normal = [&](const Eigen::Vector3d& q) -> Eigen::Vector3d {
      d.work += 6;
      const Eigen::Vector3d g = sdf_gradient(*vm, q);
      const double n = g.norm();
      return n > 1e-9 ? Eigen::Vector3d(g / n) : Eigen::Vector3d::Zero();
    };

    // 1. Out of a surface that a new snapshot put through the proxy.
    bool pushed = false;
    for (int it = 0; it < kDepenetrationSteps; ++it) {
      const double f = phi(x);
      if (f >= rho - tol) break;
      const Eigen::Vector3d n = normal(x);
      if (n.isZero()) break;  // flat far field (deep inside): nowhere to go
      x += (rho - f) * n;
      pushed = true;
    }
    if (pushed) ++d.depenetrations;

    // 2. Bounded motion toward the device point.
    Eigen::Vector3d goal = device_W;
    const double reach = (goal - x).norm();
    if (reach > p.max_step) goal = x + (goal - x) * (p.max_step / reach);

    // 3. Move (swept), slide on the tangent plane, retract onto the surface.
    for (int iter = 0; iter < p.max_iterations; ++iter) {
      Eigen::Vector3d delta = goal - x;
      if (delta.norm() <= 1e-12) break;
      bool slid = false;
      Eigen::Vector3d n = Eigen::Vector3d::Zero();
      if (phi(x) <= rho + tol) {
        n = normal(x);
        const double dn = delta.dot(n);
        if (dn < 0.0) {
          delta -= dn * n;
          slid = true;
        }
      }
      double len = delta.norm();
      if (len <= 1e-12) break;
      if (len > p.max_step) {  // a retraction may have added to it: keep the march bounded
        delta *= p.max_step / len;
        len = p.max_step;
      }
      // March until phi drops below rho, then bisect the crossing.
      const int steps = std::max(1, static_cast<int>(std::ceil(len / h)));
      double s_free = 0.0, s_hit = -1.0;
      for (int k = 1; k <= steps; ++k) {
        const double s = static_cast<double>(k) / steps;
        if (phi(x + s * delta) < rho - tol) {
          s_hit = s;
          break;
        }
        s_free = s;
      }
      if (s_hit > 0.0) {
        for (int b = 0; b < kBisections; ++b) {
          const double mid = 0.5 * (s_free + s_hit);
          if (phi(x + mid * delta) < rho - tol) s_hit = mid; else s_free = mid;
        }
      }
      if (slid && s_hit > 0.0) {
        // A slide that runs into the surface it slides on (a curved or
        // bumpy field: the tangent plane is only local): step to the hit and
        // back out onto phi = rho along the normal there, if that is a small
        // correction (a real wall ahead, a concave corner, stops the slide).
        Eigen::Vector3d y = x + s_hit * delta;
        const double push = rho - phi(y);
        const Eigen::Vector3d ny = normal(y);
        if (push > 0.0 && push < 0.5 * vm->voxel_size && !ny.isZero()) {
          y += push * ny;
          if (phi(y) >= rho - tol) {
            x = y;
            continue;
          }
        }
      }
      x += s_free * delta;
      if (s_hit < 0.0 && !slid) break;                // reached the goal freely
      if (s_free * len <= 1e-12) break;               // blocked
      if (slid && s_hit < 0.0) {
        // A tangent step leaves a curved surface: back onto it along its
        // normal (at most to the layer the step started from).
        const double gap = phi(x) - rho;
        if (gap > tol && gap < vm->voxel_size) {
          const Eigen::Vector3d nb = normal(x);
          if (!nb.isZero()) x -= gap * nb;
        }
      }
    }
    const double f = phi(x);
    d.phi = f;
    contact = f <= rho + 10.0 * tol;
    if (contact) d.normal_W = normal(x);
  }
  d.proxy_W = x;
  d.contact = contact;
  const Eigen::Vector3d F = haptics::detail::proxy_force<3>(p.force, Eigen::Vector3d((x - device_W) / scale), contact,
                                                            d.spring_prev, d.force_filtered, d.force_limit, d.clamped);
  d.force_W = F;
  d.max_work = std::max(d.max_work, d.work);
}

}  // namespace hemm::vps
