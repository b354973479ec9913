#include "common/haptics/proxy/passivity.h"

#include <algorithm>
#include <cmath>

namespace hemm::haptics {

namespace {

template <class StepFn>
PassivityReport observe(const std::vector<Eigen::Vector3d>& force, std::size_t steps, StepFn dx,
                        double tolerance_J) {
  PassivityReport r;
  double E = 0.0;
  bool in_episode = false;
  double episode_start_E = 0.0;
  std::size_t episode_start = 0;
  auto close_episode = [&]() {
    const double net = E - episode_start_E;
    ++r.episodes;
    if (net < r.worst_episode_energy || r.episodes == 1) {
      r.worst_episode_energy = net;
      r.worst_episode_start = episode_start;
    }
  };
  for (std::size_t k = 0; k < steps; ++k) {
    const bool contact = force[k].squaredNorm() > 0.0;
    if (contact && !in_episode) {
      in_episode = true;
      episode_start_E = E;
      episode_start = k;
    } else if (!contact && in_episode) {
      in_episode = false;
      close_episode();
    }
    E += -force[k].dot(dx(k));
    if (E < r.energy_min) {
      r.energy_min = E;
      r.index_min = k + 1;
    }
  }
  if (in_episode) close_episode();
  r.energy_final = E;
  r.generated = std::max(0.0, -r.energy_min);
  r.passive = r.energy_min >= -tolerance_J && (r.episodes == 0 || r.worst_episode_energy >= -tolerance_J);
  return r;
}

bool all_finite(const std::vector<Eigen::Vector3d>& v) {
  return std::all_of(v.begin(), v.end(), [](const Eigen::Vector3d& x) { return x.allFinite(); });
}

}  // namespace

PassivityReport passivity_observer(const std::vector<Eigen::Vector3d>& force,
                                   const std::vector<Eigen::Vector3d>& position, double tolerance_J) {
  if (force.size() != position.size() || !all_finite(force) || !all_finite(position) ||
      !std::isfinite(tolerance_J)) {
    PassivityReport bad;
    bad.valid = false;
    bad.passive = false;
    return bad;
  }
  const std::size_t steps = force.empty() ? 0 : force.size() - 1;
  return observe(force, steps, [&](std::size_t k) { return Eigen::Vector3d(position[k + 1] - position[k]); },
                 tolerance_J);
}

PassivityReport passivity_observer_velocity(const std::vector<Eigen::Vector3d>& force,
                                            const std::vector<Eigen::Vector3d>& velocity, double dt,
                                            double tolerance_J) {
  if (force.size() != velocity.size() || !all_finite(force) || !all_finite(velocity) || !std::isfinite(dt) ||
      !(dt > 0.0) || !std::isfinite(tolerance_J)) {
    PassivityReport bad;
    bad.valid = false;
    bad.passive = false;
    return bad;
  }
  return observe(force, force.size(), [&](std::size_t k) { return Eigen::Vector3d(velocity[k] * dt); },
                 tolerance_J);
}

}  // namespace hemm::haptics
