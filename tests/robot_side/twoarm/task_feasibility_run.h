// The feasibility harness (shared by tests/robot_side/twoarm/task_feasibility_test.cpp
// and the benchmark tests/bench/twoarm_task_table.cpp): a task script
// (operator/twoarm_tasks/task_script.h) drives TwoArmRobot directly - no
// network, dead-man pressed - over a SIMULATED delayed, lossy link in-process
// (commands late by rtt/2, the believed state late by rtt/2, `loss` of each
// lost, seeded), and the truth judge (task_truth.h, MuJoCo truth only) says
// whether the task succeeded. Simulated time only (no wall clock).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <random>
#include <stdexcept>
#include <string>

#include "operator/twoarm_tasks/task_script.h"
#include "robot_side/twoarm/arms_wire.h"
#include "robot_side/twoarm/task_truth.h"
#include "robot_side/twoarm/twoarm_robot.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace hemm::test::twoarm_feasibility {

namespace ht = hemm::twoarm;
namespace hs = hemm::twoarm_tasks;
namespace hw = hemm::wire;


struct FeasibilityRun {
  ht::TaskVerdict verdict;
  bool script_done = false;
  double script_done_s = -1.0;
  std::size_t steps_done = 0;
  std::string last_step;
  int searches = 0;
  uint64_t refusals = 0;
  std::string detail;  // where the arms are against the step's targets, for a failing run
};

// The box with both hands (issue 25 task a) runs in the shipped
// deploy/scenes/workbench_box.xml: workbench.xml with the box and the shelf
// moved within both arms' reach (in workbench.xml's layout the left arm finds
// no grasp over the box's or the shelf's ends; docs/telemanipulation_tasks.md).
inline std::string two_hand_box_scene() { return hemm::test::workbench_box_scene(); }

// The scene a task runs in: the box with both hands in the moved layout.
inline std::string feasibility_scene(ht::Task task) { return task == ht::Task::kBox ? two_hand_box_scene() : hemm::test::kWorkbenchScene; }

// hole_error: how far the operator's idea of the hole (its task: line) is
// off the truth; the guarded insertion has to find it.
inline hs::TaskScript feasibility_script(ht::Task task, const Eigen::Vector3d& hole_error = Eigen::Vector3d::Zero()) {
  hs::TaskSceneResult scene = hs::load_task_scene(feasibility_scene(task));
  if (!scene.scene) throw std::runtime_error(scene.error);
  scene.scene->hole_top += hole_error;
  switch (task) {
    case ht::Task::kBox: return hs::box_script(*scene.scene);
    case ht::Task::kPeg: return hs::peg_script(*scene.scene);
    case ht::Task::kBar: return hs::bar_script(*scene.scene);
  }
  throw std::logic_error("task");
}

// One run: the robot at 1 kHz, the script at 100 Hz, the state at 250 Hz,
// each direction late by rtt/2 and losing `loss` of its messages.
inline FeasibilityRun feasibility_run(ht::Task task, double rtt_s, double loss, uint64_t seed, double max_s,
                                      const Eigen::Vector3d& hole_error = Eigen::Vector3d::Zero()) {
  ht::TwoArmRobot robot(feasibility_scene(task), ht::TwoArmRobotOptions{});
  robot.set_link(true, true);
  const ht::TaskTruthModel tm = ht::make_task_truth_model(robot.sim(), task);
  ht::TaskTruthData data;
  const hs::TaskScript script = feasibility_script(task, hole_error);
  hs::ScriptState st;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto one_way_ns = static_cast<int64_t>(std::llround(rtt_s * 0.5e9));
  std::deque<std::pair<int64_t, hw::ArmsCommand>> to_robot;
  std::deque<std::pair<int64_t, hw::ArmsState>> to_operator;
  hw::ArmsState believed;
  bool have_believed = false;
  uint64_t seq = 0;
  // HEMM_TASK_TRACE=1: each step's start, with the object and the grasp frame (truth).
  const bool trace = std::getenv("HEMM_TASK_TRACE") != nullptr;
  std::size_t traced_step = ~std::size_t{0};
  const auto ticks = static_cast<long>(max_s * 1000.0);
  for (long k = 0; k < ticks; ++k) {
    const int64_t now = robot.time_ns();
    // A constant delay is the path's least: the commands are as fresh as the
    // link allows (the watchdog judges the age beyond it, net::judge_message_age).
    while (!to_robot.empty() && to_robot.front().first <= now) {
      robot.command(to_robot.front().second, ++seq, now);
      to_robot.pop_front();
    }
    while (!to_operator.empty() && to_operator.front().first <= now) {
      believed = std::move(to_operator.front().second);
      have_believed = true;
      to_operator.pop_front();
    }
    if (k % 10 == 0) {
      const hs::ScriptOutput out = hs::script_step(script, st, have_believed ? &believed : nullptr, 1e-9 * static_cast<double>(now));
      if (out.send && u(rng) >= loss) {
        hw::ArmsCommand c;
        ht::to_wire(out.targets, out.deadman, &c);
        c.set_stamp_ns(now);
        to_robot.emplace_back(now + one_way_ns, std::move(c));
      }
    }
    if (trace && st.step != traced_step) {
      traced_step = st.step;
      const Eigen::Vector3d o = robot.sim().body_pose_A(ht::to_string(task)).translation();
      const Eigen::Vector3d g = robot.sim().grasp_site_A(task == ht::Task::kBox ? ht::Side::kRight : ht::Side::kLeft).translation();
      const Eigen::Matrix3d R = robot.sim().body_pose_A(ht::to_string(task)).linear();
      std::printf("  %7.3f s: step %zu (%s); object %.4f %.4f %.4f tilted %.3f rad, G %.4f %.4f %.4f, searches %d\n", 1e-9 * static_cast<double>(now), st.step,
                  st.step < script.steps.size() ? script.steps[st.step].name.c_str() : "done", o.x(), o.y(), o.z(), std::acos(std::clamp(R(2, 2), -1.0, 1.0)), g.x(), g.y(), g.z(), st.searches);
    }
    robot.step();
    ht::task_truth_tick(tm, robot.sim(), data);
    // Sampled after the tick, as the station streams it (before the first
    // tick TwoArmRobot::state() has no grasp poses yet: identity).
    if (k % 4 == 0 && u(rng) >= loss) {
      hw::ArmsState s;
      robot.state(&s);
      to_operator.emplace_back(now + one_way_ns, std::move(s));
    }
    // Done: the human stops; the truth is judged 1 s later.
    if (st.done && robot.time_ns() * 1e-9 > st.done_t + 1.0) break;
  }
  FeasibilityRun r;
  r.verdict = ht::task_truth_verdict(tm, data);
  r.script_done = st.done;
  r.script_done_s = st.done_t;
  r.steps_done = st.step;
  r.last_step = st.step < script.steps.size() ? script.steps[st.step].name : "done";
  r.searches = st.searches;
  r.refusals = robot.counters().refusals;
  char line[256];
  for (std::size_t a = 0; a < 2; ++a) {
    const Eigen::Vector3d g = robot.sim().grasp_site_A(static_cast<ht::Side>(a)).translation(), to = st.to[a].translation();
    std::snprintf(line, sizeof line, "[arm %zu: G %.3f %.3f %.3f, step target %.3f %.3f %.3f, %.3f rad off] ", a, g.x(), g.y(), g.z(),
                  to.x(), to.y(), to.z(), Eigen::AngleAxisd(robot.sim().grasp_site_A(static_cast<ht::Side>(a)).linear().transpose() * st.to[a].linear()).angle());
    r.detail += line;
    const ht::ArmReading rd = robot.sim().reading(static_cast<ht::Side>(a));
    for (int i = 0; i < 7; ++i) {
      std::snprintf(line, sizeof line, "%.2f ", rd.q(i));
      r.detail += line;
    }
    const auto& o = robot.control_output().arm[a];
    std::snprintf(line, sizeof line, " force-limited %d torque-limited %d |joint-limit torque| %.1f N m ", o.force_limited, o.torque_limited, o.tau_limits.norm());
    r.detail += line;
  }
  r.detail += st.error + " last refusal: " + robot.counters().last_refusal_detail;
  return r;
}

inline std::string feasibility_row(ht::Task task, double rtt_s, uint64_t seed, const FeasibilityRun& r) {
  const ht::TaskVerdict& v = r.verdict;
  char line[512];
  std::snprintf(line, sizeof line, "| %s | %4.0f | %llu | %s | %6.1f | %6.1f | %5.1f / %5.1f | %5.1f / %5.1f | %5.1f / %5.1f | %5.1f | %s%s |\n",
                ht::to_string(task), rtt_s * 1e3, static_cast<unsigned long long>(seed), v.success ? "yes" : "NO", v.completion_s,
                r.script_done_s, v.wrist_peak_N[0], v.wrist_rms_N[0], v.wrist_peak_N[1], v.wrist_rms_N[1], v.hand_squeeze_peak_N[0],
                v.hand_squeeze_peak_N[1], v.object_env_peak_N, r.last_step.c_str(), v.success ? "" : (" - " + v.why).c_str());
  return line;
}

inline void feasibility_print(ht::Task task, double rtt_s, uint64_t seed, const FeasibilityRun& r) {
  std::fputs(feasibility_row(task, rtt_s, seed, r).c_str(), stdout);
  std::fflush(stdout);
}

// The table's header, matching feasibility_print's rows.
inline const char* feasibility_header() {
  return "| task | rtt [ms] | seed | success | completion [s] | script done [s] | right wrist peak / RMS [N] | left wrist peak / RMS [N] | "
         "peak squeeze right / left [N] | object-env peak [N] | last step |\n"
         "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
}

}  // namespace hemm::test::twoarm_feasibility
