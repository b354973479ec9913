// The truth judge of the two-arm station's three tasks (issue 25, part 6):
// whether a task succeeded, from the SIMULATED workbench's MuJoCo truth only
// (body poses, contacts, contact forces, the pads' touch sensors), never from
// what the robot or the operator believe. Const model + mutable data, as
// MuJoCo's: TaskTruthModel resolves the scene's names once (throws on a scene
// that lacks them); task_truth_tick() accumulates each tick, allocation-free;
// task_truth_verdict() judges at the end.
//
// The tasks and what counts (the tolerances are TaskTruthParams'):
//   box  the 2 kg box rests on the shelf board: in contact with it and with
//        nothing else, released (no finger touches it), its centre within
//        goal_xy_tol_m of the board's top centre and goal_z_tol_m of its
//        resting height, tilted at most max_tilt_rad.
//   peg  the peg is in the fixture's hole at least min_insert_depth_m deep
//        (hole top minus the peg's lower end), its axis within
//        max_axis_offset_m of the hole's and tilted at most max_tilt_rad.
//   bar  the bar is held by the right gripper only: both right pads touch
//        it, no left finger does, and it touches nothing of the scene.
//   For all, never dropped: after lift-off (the object off its start
//   supports with a finger on it) the object is never unsupported - no
//   finger touches it and it rests on no goal support (the shelf board, the
//   fixture) - for longer than drop_window_s, and it never touches the floor.
//
// Forces (all from MuJoCo's contacts): per gripper the net contact force the
// world exerts on it (fingers and palm; the held object's load included),
// i.e. what an ideal wrist sensor reads without the gripper's own weight and
// inertia: peak, and RMS over the ticks that gripper touches anything; the
// peak object-environment contact force (the sum of the normal forces
// between the task's object and everything but the grippers); the peak
// squeeze (the sum of the four pads' touch sensors). Success also needs the
// wrist peaks within wrist_force_limit_N (the robot's force limit) plus
// wrist_force_margin_N (the limit is a spring's, overshoot of a few percent
// while yielding is the controller's), and the object contact peak within
// object_contact_limit_N.
//
// Completion time: when the task's end condition began to hold without a
// break until the end (simulation time).
#pragma once

#include <array>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "robot_side/twoarm/workbench_sim.h"

namespace hemm::twoarm {

enum class Task { kBox = 0, kPeg = 1, kBar = 2 };
const char* to_string(Task t);
// The task to_string names (nullopt: none of them).
std::optional<Task> task_from_string(std::string_view name);

struct TaskTruthParams {
  double goal_xy_tol_m = 0.03;       // box: from the shelf board's top centre
  double goal_z_tol_m = 0.01;        // box: from its resting height on the board
  double max_tilt_rad = 5.0 * std::numbers::pi / 180.0;
  double min_insert_depth_m = 0.025;  // peg (the hole is 0.040 deep)
  double max_axis_offset_m = 0.002;   // peg
  double drop_window_s = 0.05;
  double pad_touch_N = 1.0;           // a pad "touches" above this
  double wrist_force_limit_N = 40.0;  // the robot's (RobotConfig.twoarm force_limit_N)
  double wrist_force_margin_N = 4.0;
  double object_contact_limit_N = 80.0;
  // box: it must have been carried by this many hands (issue 25 task a: both);
  // a gripper carries it when both its pads press on it while it is off every support.
  int box_hands = 2;
};

// The scene's names the judge needs, resolved once.
struct TaskTruthModel {
  Task task = Task::kBox;
  TaskTruthParams p;
  int object_body = -1;
  int floor_geom = -1;
  std::vector<int> start_support_geoms;  // what the object starts on
  std::vector<int> goal_support_geoms;   // where it may rest: shelf board, fixture
  std::array<std::vector<int>, kArms> gripper_bodies;  // palm body and both fingers
  std::array<std::array<int, 2>, kArms> finger_bodies{};
  std::array<std::array<int, 2>, kArms> pad_sensor_adr{};
  // The goal: box - the board's top centre (A = W here); peg - the hole's
  // top centre, its axis +z.
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();
  double object_half_height_m = 0.0;  // box: resting height above the board; peg: half its length
};

// Throws std::runtime_error naming what the scene lacks.
TaskTruthModel make_task_truth_model(const WorkbenchSim& sim, Task task, const TaskTruthParams& p = {});

// One tick's look at the truth (also what the unit tests check piece by piece).
struct TaskTruthSample {
  double t_s = 0.0;
  bool on_start_support = false, on_goal_support = false, on_other = false, on_floor = false;
  std::array<bool, kArms> finger_on_object{};   // any finger of that gripper touches the object
  std::array<int, kArms> pads_on_object{};      // how many of its pads touch it (0-2)
  std::array<Eigen::Vector3d, kArms> gripper_force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<bool, kArms> gripper_in_contact{};
  double object_env_force_N = 0.0;
  double squeeze_N = 0.0;
  std::array<double, kArms> hand_squeeze_N{};  // each gripper's two pads
  bool goal = false;  // the task's end condition holds now
  // The measures the end condition is made of.
  double goal_xy_err_m = 0.0, goal_z_err_m = 0.0, tilt_rad = 0.0, depth_m = 0.0, axis_offset_m = 0.0;
};

struct TaskTruthData {
  bool lifted = false, dropped = false, touched_floor = false;
  double lift_time_s = -1.0;
  double unsupported_since_s = -1.0;
  double goal_since_s = -1.0;  // < 0: the end condition does not hold now
  std::array<double, kArms> wrist_peak_N{};
  std::array<double, kArms> wrist_peak_t_s{};  // when each peak was (simulation time)
  std::array<Eigen::Vector3d, kArms> wrist_peak_force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  std::array<double, kArms> wrist_sum_sq{};
  std::array<long, kArms> wrist_contact_ticks{};
  double object_env_peak_N = 0.0;
  double object_env_peak_t_s = 0.0;
  double squeeze_peak_N = 0.0;
  std::array<double, kArms> hand_squeeze_peak_N{};
  std::array<bool, kArms> carried{};  // both pads of that gripper on the object, off every support
  long ticks = 0;
  TaskTruthSample last;
};

TaskTruthSample task_truth_sample(const TaskTruthModel& model, const WorkbenchSim& sim) noexcept;
// Allocation-free; call after each plant step.
void task_truth_tick(const TaskTruthModel& model, const WorkbenchSim& sim, TaskTruthData& data) noexcept;

struct TaskVerdict {
  bool success = false;
  bool goal = false;       // the end condition holds at the end
  bool dropped = false;
  bool forces_ok = false;
  double completion_s = -1.0;  // when the end condition began to hold for good; < 0: it does not
  std::array<double, kArms> wrist_peak_N{};
  std::array<double, kArms> wrist_peak_t_s{};  // when (simulation time): which step it was in
  std::array<Eigen::Vector3d, kArms> wrist_peak_force_A{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  // its direction
  std::array<double, kArms> wrist_rms_N{};  // over that gripper's contact ticks
  double object_env_peak_N = 0.0;
  double object_env_peak_t_s = 0.0;
  double squeeze_peak_N = 0.0;
  std::array<double, kArms> hand_squeeze_peak_N{};
  std::array<bool, kArms> carried{};
  TaskTruthSample end;
  std::string why;  // what failed, for a failing verdict
};

TaskVerdict task_truth_verdict(const TaskTruthModel& model, const TaskTruthData& data);

}  // namespace hemm::twoarm
