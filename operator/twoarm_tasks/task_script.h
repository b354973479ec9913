// The SIMULATED human's plans for the two-arm station's three tasks (issue
// 25, part 6): closed-loop scripts that, from the *believed* remote state
// (an ArmsState as the operator receives it, late by the link's delay) and
// the time, give both arms' grasp-frame targets T_A_G, the grippers' targets
// and the dead-man. Pure: a const plan (TaskScript) plus mutable progress
// (ScriptState), stepped by script_step(); no clock, no I/O.
//
// Move-and-wait: each step's targets move there at a bounded speed, and the
// step ends only when the believed state confirms it (the grasp frame within
// a tolerance of the target and slow, a gripper holding or open, the load
// taken off the wrist) - whatever the delay, the script never acts on what
// it has not seen. The peg's insertion is guarded: down slowly; the wrist
// force tells contact; stuck above the hole, it presses lightly and searches
// in a growing circle until the grasp frame drops into the hole.
//
// Object poses come from the scene's `task:` lines (task_scene.h), never
// from the simulation's truth.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "operator/twoarm_tasks/task_scene.h"
#include "robot_side/twoarm/twoarm_control.h"
#include "wire.pb.h"

namespace hemm::twoarm_tasks {

using twoarm::kArms;
using twoarm::Side;

struct ScriptParams {
  double speed_mps = 0.10;         // free moves
  double slow_speed_mps = 0.04;    // the last centimetres to a grasp or a placement
  double insert_speed_mps = 0.01;  // the guarded insertion
  double rot_speed_radps = 0.5;
  double pos_tol_m = 0.005;        // "reached", free arm
  double carry_tol_m = 0.03;       // "reached" with a load (the arm sags under it)
  double rot_tol_rad = 0.05;
  double settle_speed_mps = 0.01;  // "reached" also needs G this slow
  double grip_force_N = 30.0;      // each finger
  double unloaded_N = 8.0;         // the wrist carries less than this: the load rests
  double open_tol_m = 0.005;
  // Guarded insertion.
  double contact_N = 3.0;         // the wrist's upward force that tells contact
  double in_margin_m = 0.002;     // searching, G drops this far (unpressed): the peg is in the hole
  double min_depth_m = 0.03;      // pressed this far below the entry height: at the hole's bottom
  // Stuck: target this far below where G rests (3 N more on the rim at
  // 1000 N/m): over the hole the peg drops at least this far, whatever its
  // weight and the arm's sag (at 1 mm a search saw no drop for 140 s).
  double press_m = 0.003;
  double search_pitch_m = 0.001;  // the search circle grows this much per turn (the clearance is 1 mm)
  double search_max_m = 0.025;    // through the device the peg sat up to 15.6 mm off G's axis (tilted in the grasp)
  double search_period_s = 1.5;
  double deadman_delay_s = 0.1;
  // Guarded set-down (ScriptStep::lower_until_unloaded): down this slowly
  // (a round trip late, it has gone rtt x this further: 1.5 cm at 3 s),
  // until the two wrists together carry less than unloaded_N; then the
  // targets go back to where G was believed then, this far lower.
  double place_speed_mps = 0.005;
  double place_press_m = 0.003;
  // box: each hand's grasp frame this far in from its end of the box: the
  // left reaches across to the shelf, so it takes its end nearer the edge.
  std::array<double, kArms> box_end_inset_m{0.05, 0.005};
  // box: the opening closes on it at this rate (ScriptStep::grip_speed_mps).
  double box_grip_speed_mps = 0.05;
  // Each arm's grasps from above are turned by this about the fingers'
  // closing axis (which stays along x_A): straight down, the right and left
  // arms stop short at a wrist joint's limit (j6) from their rest postures.
  std::array<double, kArms> tilt_rad{0.5, -0.7};   // released this long at the start (the re-arm wants a neutral command)
};

// One step of a plan: targets given at its start, a wait at its end.
struct ScriptStep {
  std::string name;
  std::array<std::optional<Eigen::Isometry3d>, kArms> pose{};
  // The pose's translation is an offset from the other arm's believed grasp
  // frame at the step's start (its orientation as given): a hand-over.
  std::array<bool, kArms> from_other{};
  // The pose is this arm's own target moved by this offset (a retreat).
  std::array<std::optional<Eigen::Vector3d>, kArms> delta{};
  std::array<std::optional<twoarm::GripperTarget>, kArms> grip{};
  // The opening goes to grip's at this rate [m/s] (0: at once): a hand
  // squeezing the lever slowly, so the pads meet a heavy object gently.
  double grip_speed_mps = 0.0;
  double speed_mps = 0.0;  // 0: ScriptParams::speed_mps
  double tol_m = 0.0;      // 0: ScriptParams::pos_tol_m
  std::array<bool, kArms> wait_reach{}, wait_grasped{}, wait_opened{}, wait_unloaded{};
  double dwell_s = 0.0;  // at least this long in the step
  // Guarded insertion by arm insert_arm (>= 0): G from its start down to
  // bottom_z; entry_z is G's height when the peg's end is at the hole's top.
  int insert_arm = -1;
  double entry_z = 0.0, bottom_z = 0.0;
  // Guarded set-down with both arms: from the step's pose both targets go
  // down together (ScriptParams::place_speed_mps, at most lower_max_m) until
  // the two wrists' vertical forces sum to within unloaded_N - the support
  // carries the load - then to the believed G less place_press_m (up if
  // the descent ran on, down if the arms sag);
  // the step ends unloaded and slow after dwell_s there.
  bool lower_until_unloaded = false;
  double lower_max_m = 0.0;
};

struct TaskScript {
  std::string task;
  ScriptParams p;
  std::vector<ScriptStep> steps;
};

// The three plans from the scene (grasps from above, twoarm::downward_grasp).
// box: both grippers take the box, one at each end, across its 0.20 m side,
//   lift it over the shelf's edge, carry it, set it down on the board, let
//   go, retreat; both targets move together in A (the hands' relative pose
//   is kept).
// peg: the left gripper takes the peg 3 cm below its top, carries it over
//   the hole, inserts it (guarded) to 5 mm above the bottom, lets go.
// bar: the left gripper takes the bar at its middle and lifts it to the
//   hand-over pose; the right takes it 0.12 m right of the left's grasp
//   (where the left is believed to be); the left lets go and retreats.
TaskScript box_script(const TaskScene& scene, const ScriptParams& p = {});
TaskScript peg_script(const TaskScene& scene, const ScriptParams& p = {});
TaskScript bar_script(const TaskScene& scene, const ScriptParams& p = {});

struct ScriptState {
  bool started = false;
  double start_t = 0.0;
  std::size_t step = 0;
  bool step_begun = false;
  double step_t0 = 0.0, move_s = 0.0;
  std::array<Eigen::Isometry3d, kArms> from{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  std::array<Eigen::Isometry3d, kArms> to{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  twoarm::TwoArmTargets targets;
  std::array<double, kArms> grip_from_m{0.0, 0.0};  // the opening at the step's start (grip_speed_mps)
  // Guarded insertion.
  enum class Insert { kDescend, kSearch, kIn } insert = Insert::kDescend;
  double insert_z = 0.0, insert_z0 = 0.0, insert_t0 = 0.0, search_t0 = 0.0, search_z = 0.0;
  // Dropped in while searching: the believed G's x, y then (the peg is in
  // the hole there, wherever it sits in the grasp); the descent goes on there.
  bool insert_xy_set = false;
  Eigen::Vector2d insert_xy = Eigen::Vector2d::Zero();
  int searches = 0;
  // Guarded set-down.
  bool lower_stopped = false;
  double lower_dz = 0.0, lower_stop_t = 0.0;
  // What the step waits on (the last tick's check, for the progress report):
  // per arm the believed G against the step's goal - position [m], turn
  // [rad], speed [m/s]; 0 for an arm the step does not wait on.
  std::array<double, kArms> wait_pos_m{0.0, 0.0}, wait_rot_rad{0.0, 0.0}, wait_speed_mps{0.0, 0.0};
  // When each finished step ended (the operator's clock, t_s): where a
  // run's time went.
  std::vector<double> step_end_t;
  bool done = false;
  double done_t = -1.0;
  std::string error;  // a believed state it cannot read (it then holds its targets)
};

// What a script (and the SIMULATED human's eye) reads of a believed state.
struct BelievedArm {
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_A = Eigen::Vector3d::Zero();   // the environment's on the gripper (wrist sensor)
  Eigen::Vector3d torque_A = Eigen::Vector3d::Zero();
  double opening_m = 0.0;
  bool holding = false;
  twoarm::GripperTarget grip_target;
};
// Both arms and grippers of a believed state (check_arms_state first); an
// error when it is not a two-arm state, *out then partly filled.
std::optional<std::string> read_believed(const wire::ArmsState& s, std::array<BelievedArm, kArms>* out);

struct ScriptOutput {
  bool send = false;  // false until a first believed state has come
  twoarm::TwoArmTargets targets;
  bool deadman = false;
};

// One operator tick at time t_s (seconds, the operator's clock) with the
// newest believed state (nullptr: none yet).
ScriptOutput script_step(const TaskScript& script, ScriptState& st, const wire::ArmsState* believed, double t_s);

}  // namespace hemm::twoarm_tasks
