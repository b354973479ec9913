// Device limits the VPS tests design their couplings for (test data, not a
// device driver): a PHANToM Omni as its data sheet gives it (3.3 N peak,
// 1.02 N/mm on its weakest axis, no torque) and an LWR-class arm as the
// bimanual paper gives it (150 N / 25 N m per arm); the arm's stiffness
// figures are those of a Cartesian impedance controller of that class
// (assumed: 5000 N/m, 300 N m/rad). Both at 1 kHz.
#pragma once

#include "common/haptics/vps/coupling.h"

namespace hemm::vps::test {

inline CouplingDeviceLimits omni_like() {
  CouplingDeviceLimits d;
  d.peak_force = 3.3;
  d.max_stiffness = 1020.0;
  return d;
}

inline CouplingDeviceLimits lwr_like() {
  CouplingDeviceLimits d;
  d.peak_force = 150.0;
  d.max_stiffness = 5000.0;
  d.renders_torque = true;
  d.peak_torque = 25.0;
  d.max_rot_stiffness = 300.0;
  return d;
}

}  // namespace hemm::vps::test
