#include "robot_side/sim/realtime.h"

#include <algorithm>
#include <chrono>
#include <thread>

namespace hemm::robot {


PacingStats step_realtime(SimulatedRobot& robot, int n_steps) {
  PacingStats st;
  const int64_t dt = robot.timestep_ns();
  if (dt <= 0) return st;
  const int64_t start = steady_now_ns();
  robot.set_time_origin_ns(start);
  for (int k = 0; k < n_steps; ++k) {
    const int64_t deadline = start + k * dt;
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(deadline)));
    const int64_t late = steady_now_ns() - deadline;
    st.max_lateness_ns = std::max(st.max_lateness_ns, late);
    if (late > dt) ++st.late_steps;
    robot.step(1);
    ++st.steps;
  }
  return st;
}

}  // namespace hemm::robot
