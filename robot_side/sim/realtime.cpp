#include "robot_side/sim/realtime.h"

#include <algorithm>

namespace hemm::robot {

PacingStats step_realtime(SimulatedRobot& robot, int n_steps, rt::TimingStats* timing) {
  PacingStats st;
  const int64_t dt = robot.timestep_ns();
  if (dt <= 0) return st;
  const int64_t start = steady_now_ns();
  robot.set_time_origin_ns(start);
  rt::TickTiming t;
  t.period_ns = dt;
  t.what = "step";
  for (int k = 0; k < n_steps; ++k) {
    const int64_t deadline = start + k * dt;
    rt::sleep_until_ns(deadline);
    const int64_t wake = steady_now_ns();
    const int64_t late = wake - deadline;
    st.max_lateness_ns = std::max(st.max_lateness_ns, late);
    if (late > dt) ++st.late_steps;
    robot.step(1);
    ++st.steps;
    if (timing != nullptr) {
      t.deadline_ns = deadline;
      t.wake_ns = wake;
      t.done_ns = steady_now_ns();
      rt::record_tick(*timing, t);
      t.prev_wake_ns = wake;
      ++t.tick;
    }
  }
  return st;
}

}  // namespace hemm::robot
