// Real-time pacing of the SIMULATED robot: steps to absolute deadlines of the
// steady clock (no drift from accumulated sleep errors). Tests and benchmarks
// that want speed call SimulatedRobot::step() directly instead.
#pragma once

#include <cstdint>

#include "common/clock/steady_clock.h"
#include "common/realtime/timing_stats.h"
#include "robot_side/sim/simulated_robot.h"

namespace hemm::robot {

using hemm::steady_now_ns;

struct PacingStats {
  int steps = 0;
  int64_t max_lateness_ns = 0;  // worst start of a step after its deadline
  int late_steps = 0;           // steps that started more than one period late
};

// Steps `n_steps` steps, step k no earlier than start_ns + k * timestep, where
// start_ns is the steady clock at the call. The robot's clock is aligned to
// the steady clock first, so its time stamps are station time. With
// `timing`, each step's wake lateness, compute and period go into it too
// (common/realtime; the robot station's loop keeps the same).
PacingStats step_realtime(SimulatedRobot& robot, int n_steps, rt::TimingStats* timing = nullptr);

}  // namespace hemm::robot
