#pragma once
// Time-domain passivity observer (Hannaford & Ryu) for a logged haptic
// interaction. Sample k holds the force F_k the environment applied to the
// device (zero-order hold until sample k+1) and the device position x_k. The
// energy that flowed INTO the environment up to sample n is
//   E_n = sum_{k < n} -F_k . (x_{k+1} - x_k).
// A passive environment starting at rest has E_n >= 0 for all n: whatever it
// gave back it had received first. E_n < -tolerance means the rendering
// generated energy (an active, potentially unstable contact).
#include <cstddef>
#include <vector>

#include <Eigen/Core>

namespace hemm::haptics {

struct PassivityReport {
  double energy_final = 0.0;   // J, E_N
  double energy_min = 0.0;     // J, min_n E_n (0 at n = 0)
  std::size_t index_min = 0;   // n at the minimum
  double generated = 0.0;      // J, max(0, -energy_min)
  // Contact episodes: runs of samples with nonzero force. A passive contact
  // ends with its stored energy released, so each episode's net inflow must
  // be >= -tolerance too; the worst one is reported.
  std::size_t episodes = 0;
  double worst_episode_energy = 0.0;
  std::size_t worst_episode_start = 0;
  bool passive = true;
  bool valid = true;           // false: mismatched lengths or non-finite samples
};

PassivityReport passivity_observer(const std::vector<Eigen::Vector3d>& force,
                                   const std::vector<Eigen::Vector3d>& position, double tolerance_J);

// Same from velocities: x_{k+1} - x_k = v_k * dt.
PassivityReport passivity_observer_velocity(const std::vector<Eigen::Vector3d>& force,
                                            const std::vector<Eigen::Vector3d>& velocity, double dt,
                                            double tolerance_J);

}  // namespace hemm::haptics
