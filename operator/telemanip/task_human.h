// The SIMULATED human doing one of the two-arm station's tasks (issue 25,
// part 6) THROUGH THE LINK: its plan is the task script
// (operator/twoarm_tasks/task_script.h), stepped at ~100 Hz on its own
// thread (the human's "brain": it may allocate) with the *believed*
// ArmsState - the newest the link accepted, late by the delay - and its
// hands carry the plan out on the bimanual device through the task's own
// mapping: each arm's target T_A_G becomes where that hand must be in D
// (arm_mapping.h hand_pose_D, with the indexing anchor the servo task
// publishes), the gripper target a lever position (the mapping's lever ->
// gripper map inverted by the opening; a joystick handle's forward axis
// stands in for a lever), and the dead-man is MappedHumanScript's habit
// (DeadmanHabit: it watches the robot's status) and-ed with the script's
// own (released for its first 0.1 s). The human pulls the handle there with
// its arm's spring (device/bimanual/human.h), so the remote arm follows the
// hand's real motion, the rendered wrench included.
//
// Threads: the network thread publishes believed states into
// believed(); the brain thread (start(), or tick() from a test) steps the
// script and publishes each hand's wish into that hand's mailbox; each
// TaskHumanHand::at() (the device's hardware or servo thread: one consumer
// per mailbox) takes the newest wish and anchor, allocation-free.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "common/concurrency/newest_mailbox.h"
#include "operator/device/bimanual/human.h"
#include "operator/telemanip/arm_mapping.h"
#include "operator/telemanip/telemanip_human.h"
#include "operator/twoarm_tasks/task_script.h"
#include "wire.pb.h"

namespace hemm::config {
class TelemanipConfig;
}
namespace hemm::report {
class TelemanipTaskProgress;
}
namespace hemm::device::bimanual {
struct SimulationConfig;
}

namespace hemm::op::telemanip {

// What the brain wants of one hand now.
struct TaskHandWish {
  bool active = false;  // the script has targets (a first believed state came)
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();  // where that arm's G should go
  double lever = 0.0;   // lever position as a fraction of its travel (0 open)
  bool deadman = false; // the script's dead-man
};

// The lever fraction whose opening (grip_to_gripper) is the target's
// opening, clamped to [0, 1] (a person closes until it holds: the force is
// what the lever gives there).
double lever_for_gripper(const ArmMappingParams& p, const twoarm::GripperTarget& g) noexcept;

struct TaskProgress {
  std::string task;
  bool started = false, done = false;
  double done_s = -1.0;  // from the script's start
  std::size_t steps_done = 0, steps = 0;
  std::string last_step;
  int searches = 0;
  std::string error;
  std::uint64_t ticks = 0;
  // ScriptState's wait_* of the last tick (what the step waits on).
  std::array<double, 2> wait_pos_m{0.0, 0.0}, wait_rot_rad{0.0, 0.0}, wait_speed_mps{0.0, 0.0};
  std::vector<double> step_done_s;  // each finished step's end, from the script's start
  std::uint32_t clutch_presses = 0;  // the hands' indexing (TaskIndexing::presses, both)
  double indexing_pause_s = 0.0;     // the plan's time spent waiting on the clutch (resume_s included)
  std::array<double, 2> drift_offset_max_m{0.0, 0.0};  // the direct mode's drift correction, largest |offset|
};

// The SIMULATED human's indexing with the clutch (arm_mapping.h): a hand
// whose target lies more than reach_m from where it rests asks for it; the
// hand whose handle carries the clutch presses it while either asks, for
// hold_s, and the hands move back towards their rest poses meanwhile (both
// arms' mappings share the one clutch: a person re-centres both hands at
// once). Shared by both hands of one human (atomics: each hand's at() runs
// on the device's thread, allocation- and lock-free).
struct TaskIndexingParams {
  double reach_m = 0.09;     // the device's rest leaves ~0.13 m towards the operator (tasks doc)
  double hold_s = 0.8;       // the clutch held this long
  double cooldown_s = 0.5;   // at least this long between releases and the next press
  // The plan waits while the clutch is held and this long after its release
  // (the hands settle on the new anchor): a person indexing holds the motion;
  // the plan running on meanwhile put the hand 2-4 cm behind its target at
  // the release, a step the remote arm then took in 0.1 s.
  double resume_s = 0.3;
};
struct TaskIndexing {
  TaskIndexingParams p;
  std::array<std::atomic<bool>, 2> wants{};
  std::array<std::atomic<bool>, 2> held{};  // the clutch pressed, by the hand that holds it
  std::array<std::atomic<std::uint32_t>, 2> presses{};  // the clutch presses by hand (the one that holds it)
};

// The SIMULATED human's eye on the remote arms in the direct mode. There the
// hands move the remote targets by velocity, so whatever the passivity
// controller withholds, and every twist the link loses, leaves the remote G
// short of where the hand's mapping puts it (TDPA's position drift); at 0 ms
// round trip the first move of the bar ended 2.5 cm short and the plan
// waited on it for 90 s. A person watching the display moves the hand on
// until the gripper is where they want it. Per arm, the brain integrates what
// the believed G lacks of the plan's target into an offset of the target it
// gives the hand:
//  * only once the target has stood still for wait_s (the believed state is
//    a round trip late: a moving target's lack is the delay's, not drift)
//    and not while the hands index;
//  * slowly: the loop closes through the round trip, and gain x round trip
//    well under pi/2 keeps it from ringing (0.25/s: 0.75 rad at 3 s);
//  * not against a contact: an axis of A whose wrist force (torque) pushes
//    back against its lack by more than contact_N (contact_Nm) is not
//    integrated - a press, a held load's weight, is the plan's;
//  * bounded (max_m, max_rad).
// Off (gain 0) in the model-mediated mode, where the mapping is a position
// map and the remote G sits where the hand puts it.
struct DriftCorrectionParams {
  double gain_per_s = 0.0;
  double wait_s = 0.5;  // the runner: the link's round trip + 0.5 s
  double max_m = 0.15, max_rad = 1.5;
  double contact_N = 3.0, contact_Nm = 0.3;
};
// Empty when usable.
std::string validate(const DriftCorrectionParams& p);
struct DriftOffset {
  Eigen::Vector3d p_A = Eigen::Vector3d::Zero();  // added to the target's position
  Eigen::Vector3d r_A = Eigen::Vector3d::Zero();  // rotation vector, applied before the target's orientation (in A)
};
// One integration step of dt for one arm (pure): the lack of the believed
// arm b against the plan's target, per axis unless its contact resists it.
void integrate_drift(const DriftCorrectionParams& p, const Eigen::Isometry3d& target,
                     const twoarm_tasks::BelievedArm& b, double dt, DriftOffset* o) noexcept;
// The target the hand is given: translated by o.p_A, turned by exp(o.r_A) in A.
Eigen::Isometry3d offset_target(const Eigen::Isometry3d& target, const DriftOffset& o) noexcept;

class TaskHumanBrain {
 public:
  // Throws std::invalid_argument on bad mapping parameters or an empty plan.
  TaskHumanBrain(twoarm_tasks::TaskScript script, const std::array<ArmMappingParams, 2>& mapping);
  ~TaskHumanBrain();  // stop()
  TaskHumanBrain(const TaskHumanBrain&) = delete;
  TaskHumanBrain& operator=(const TaskHumanBrain&) = delete;

  // The network thread's side: each accepted ArmsState (the one producer).
  NewestMailbox<wire::ArmsState>& believed() noexcept { return believed_; }
  // Hand k's wishes (its TaskHumanHand is the one consumer).
  NewestMailbox<TaskHandWish>& wishes(int k) noexcept { return wishes_[static_cast<std::size_t>(k)]; }
  // Both hands' indexing (task_hands hands it to them).
  TaskIndexing& indexing() noexcept { return indexing_; }
  // The direct mode's drift correction (before start(); throws
  // std::invalid_argument on bad parameters).
  void set_drift_correction(const DriftCorrectionParams& p);

  // One step of the plan at t_s (seconds, any monotonic clock): the brain
  // thread's, or a test's (then do not start()).
  void tick(double t_s);
  // The brain thread: tick() every 1/rate_hz on the steady clock.
  void start(double rate_hz = 100.0);
  void stop();
  bool done() const noexcept { return done_.load(std::memory_order_acquire); }
  TaskProgress progress() const;  // any thread

 private:
  twoarm_tasks::TaskScript script_;
  std::array<ArmMappingParams, 2> mapping_;
  NewestMailbox<wire::ArmsState> believed_;
  std::array<NewestMailbox<TaskHandWish>, 2> wishes_;
  TaskIndexing indexing_;
  // The brain thread's. The script runs on a clock that stops while the
  // hands index (TaskIndexingParams::resume_s); its step and done times are
  // kept on the caller's clock.
  twoarm_tasks::ScriptState st_;
  std::uint64_t ticks_ = 0;
  double last_t_ = -1.0, last_index_t_ = -1.0, paused_s_ = 0.0, start_t_ = 0.0, done_t_ = -1.0;
  std::vector<double> step_end_t_;
  DriftCorrectionParams drift_;
  std::array<DriftOffset, 2> drift_offset_{};
  std::array<Eigen::Isometry3d, 2> last_target_{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  std::array<double, 2> last_move_t_{0.0, 0.0}, drift_max_m_{0.0, 0.0};
  std::atomic<bool> done_{false}, stop_{false};
  mutable std::mutex mu_;
  TaskProgress progress_;  // guarded by mu_
  std::thread thread_;
};

// One hand of the SIMULATED task human (the device's HumanScript).
class TaskHumanHand final : public device::bimanual::HumanScript {
 public:
  // Without the mapping engaged (released, or clutched) the hand moves back
  // towards its rest pose this fast (a person re-centring the hand).
  static constexpr double kReturnSpeed_mps = 0.25;
  static constexpr double kReturnRate_radps = 1.0;
  static constexpr double kTurnGain_per_s = 1.5;    // of the remaining turn error, per second
  static constexpr double kTurnBiasMax_rad = 0.25;  // the most it turns beyond its spring's target
  // rest: the hand at rest (pose, grasp). lever_travel_m > 0: the handle's
  // grip lever travel; 0: the lever is the joystick's forward axis.
  // robot_safety: the robot's newest status (TelemanipLink::set_safety_out),
  // or null (the script's dead-man alone). Throws std::invalid_argument on
  // bad mapping parameters or null mailboxes.
  // indexing (optional, shared by both hands): this hand is `hand` (0
  // right, 1 left); clutch_buttons: the button bits of its handle that are
  // a clutch (this hand presses them; 0: it holds none).
  TaskHumanHand(const device::bimanual::HumanTarget& rest, const ArmMappingParams& mapping,
                NewestMailbox<TaskHandWish>* wishes, NewestMailbox<MappingAnchor>* anchors, double lever_travel_m,
                const std::atomic<std::uint32_t>* robot_safety, TaskIndexing* indexing = nullptr, int hand = 0,
                std::uint32_t clutch_buttons = 0);
  device::bimanual::HumanTarget at(double t_s) const noexcept override;

 private:
  // The clutch's cycle (the hand that holds it): true while pressed.
  bool clutch_step(double t_s) const noexcept;

  device::bimanual::HumanTarget rest_;
  ArmMappingParams mapping_;
  NewestMailbox<TaskHandWish>* wishes_;
  NewestMailbox<MappingAnchor>* anchors_;
  double lever_travel_m_;
  const std::atomic<std::uint32_t>* robot_safety_;
  // The consumer's side (the one thread that calls at()).
  mutable TaskHandWish wish_;
  mutable MappingAnchor anchor_;
  mutable DeadmanHabit deadman_;
  // The human's correction of its grasp's turn: what the commanded G still
  // lacks of the wish's orientation, integrated into a further turn of the
  // hand (a person turns a little more until the gripper on its display is
  // right; the hand's own spring leaves it some hundredths of a radian short,
  // k times that at the gripper with rotation scale k).
  mutable Eigen::Vector3d turn_bias_D_ = Eigen::Vector3d::Zero();
  mutable double last_t_s_ = -1.0;
  TaskIndexing* indexing_;
  int hand_;
  std::uint32_t clutch_buttons_;
  // Where the hand was asked to be last (the return towards rest starts there).
  mutable Eigen::Vector3d last_p_D_;
  mutable Eigen::Quaterniond last_q_D_;
  mutable bool clutch_held_ = false;
  mutable double clutch_t0_ = 0.0, clutch_released_t_ = -1e9;
};

// The task settings (telemanip.task, task_scene, task_settle_s): empty when
// usable; task "" is no task. scene_path: task_scene resolved against the
// config's directory (config_path; "" if no task).
std::string check_task_config(const config::TelemanipConfig& c, const std::string& config_path,
                              std::string* scene_path);
// The plan of a task from its scene file: throws std::invalid_argument with
// file:line: reason (task_scene.h) or an unknown task.
twoarm_tasks::TaskScript task_plan(const std::string& task, const std::string& scene_path);

// The runner's pieces (telemanip_runner.cpp). Both hands of the task human
// for the SIMULATED device `sim` (rest poses; a grip-force handle's lever
// travel, else its joystick stands in for the lever), each on its arm's
// mapping and the servo task's anchors.
std::array<std::shared_ptr<const device::bimanual::HumanScript>, 2> task_hands(
    const device::bimanual::SimulationConfig& sim, const std::array<ArmMappingParams, 2>& mapping,
    const std::array<NewestMailbox<MappingAnchor>*, 2>& anchors, TaskHumanBrain& brain,
    const std::atomic<std::uint32_t>* robot_safety);
void fill_task_report(const TaskProgress& p, report::TelemanipTaskProgress* out);

}  // namespace hemm::op::telemanip
