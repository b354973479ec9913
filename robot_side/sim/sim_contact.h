// SIMULATION ONLY: one MuJoCo contact as the live views draw it (position,
// force in W, geoms), for the mobile robot's and the two-arm station's views.
// MuJoCo stays out of this header.
#pragma once

#include "robot_side/sim/sim_types.h"

struct mjModel_;
struct mjData_;

namespace hemm::robot {

// Contact i of d (0 <= i < d->ncon); false (out unchanged) for an excluded
// contact (not a touch: e.g. the arm's inactive clearance probes).
bool sim_contact(const mjModel_* m, const mjData_* d, int i, SimContact* out) noexcept;

}  // namespace hemm::robot
