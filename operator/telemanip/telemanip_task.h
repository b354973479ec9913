// Telemanipulation's servo task (issue 25, parts 2-3): both hands of the
// bimanual device drive the two remote arms, and feel the operator's local
// model (model-mediated teleoperation: never the network).
//
// Per tick, per hand k (arm k: 0 right, 1 left):
//  1. the newest remote state (RemoteArmsState, from the link) initializes
//     the mapping where the remote G is, once;
//  2. the mapping (arm_mapping.h) turns the hand's pose, the gating
//     dead-man and the grip lever into the commanded T_A_G and gripper;
//  3. while the hand is engaged, the gripper's pointshell at its opening
//     (the remote one's, or the commanded one before any state; the palm's
//     alone, or nothing (grasp_palm_contact), in the grasp phase: from the
//     lever's closing until the hand has left the object, kGraspClear_m) is
//     pulled to
//     the commanded T_A_G by the 6-DoF virtual coupling and rendered with VPS
//     against the snapshot's live voxmap (frame W; the workbench's A is W);
//     the coupling's reaction, at E and in D (force times the translation
//     scale: the hand's work equals the tool's), goes to the device;
//     released, nothing is displayed and the tool follows the command;
//  4. what the grippers hold adds its measured weight, and held by both, the
//     rigid coupling between the hands (held_object.h), to each hand's
//     wrench (model-mediated mode, rendering on);
//  5. both arms' setpoints go into the mailbox the link sends from.
//
// In the direct mode (params.mode; issue 25 part 5) step 3 is the direct
// force-feedback hand instead (direct_hand.h): the robot's wrench through the
// operator end's passivity controller, no VPS; the setpoint carries the
// hand's twist and the port in place of the pose. The gripper and the
// dead-man work as in the model-mediated mode.
//
// Real time: tick() allocates nothing, locks nothing, logs nothing; each
// hand's VPS work is bounded (vps::TickWorkBudget: tick_budget_ns per hand,
// capped in units by `budget`), calibrated at construction on a box voxmap
// of the live voxmap's resolution. Counters and the last wrench per hand
// are the servo thread's: read them after the loop stopped.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "common/concurrency/newest_mailbox.h"
#include "common/haptics/vps/work_budget.h"
#include "operator/device/haptic_device.h"
#include "operator/model/model_thread.h"
#include "operator/servo/servo_tick_tap.h"
#include "operator/servo/servo_loop.h"
#include "operator/telemanip/arm_mapping.h"
#include "operator/telemanip/gripper_tool.h"
#include "operator/telemanip/hand_trace.h"
#include "operator/telemanip/held_object.h"
#include "operator/telemanip/telemanip_link.h"

namespace hemm::op::telemanip {

struct TelemanipTaskParams {
  FeedbackMode mode = FeedbackMode::kModel;
  std::array<DirectHandParams, kTeleArms> direct{};  // the direct mode's, per hand
  std::array<ArmMappingParams, kTeleArms> mapping{};
  bool render = true;  // model-mediated forces (false: commands only)
  GripperGeometry gripper;
  HeldObjectParams held;  // the held object's weight and two-hand coupling
  // In a grasp phase: the palm's shell against the live voxmap (true) or
  // no contact at all (false; step 3).
  bool grasp_palm_contact = false;
  double contact_stiffness = 3e7;        // N/m^3 (as the 6-DoF probe tool)
  std::int64_t budget = 4000;            // VPS work units per hand per tick
  std::int64_t tick_budget_ns = 100'000; // VPS time per hand per tick (0: none)
  std::int64_t tick_margin_ns = 100'000;
  double calibration_voxel = 0.01;
  int calibration_layers = 4;
  std::array<device::EndEffectorLimits, kTeleArms> limits{};  // the device's (the coupling's design)
  double period_s = 1e-3;
};
// Empty when usable.
std::string validate(const TelemanipTaskParams& p);

struct HandRenderStats {
  std::uint64_t engaged_ticks = 0;
  std::uint64_t contact_ticks = 0;   // engaged with VPS contacts
  std::uint64_t no_model_ticks = 0;  // engaged without a voxmap
  std::uint64_t grasp_ticks = 0;     // engaged in a grasp phase, no contact rendered
  double peak_force_n = 0.0;         // |F| displayed (D)
  double sum_force_n = 0.0;          // over contact ticks
  Eigen::Vector3d last_force_D = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_torque_D = Eigen::Vector3d::Zero();
  std::int64_t last_work = 0;
};

class TelemanipTask final : public servo::ServoTask {
 public:
  // Step 3's grasp phase, per hand: it begins when the remote gripper
  // holds, or the lever closes the fingers kClosingTol_m below the remote
  // opening or kLeverClosing_m below the widest it commanded since the last
  // grasp; it ends when the lever is open again if nothing was held, else
  // once the commanded G is kGraspClear_m from where the grasp was last
  // seen. Meanwhile the fingers are not rendered: what is between them is
  // the object they close on or let go of, whose voxels (a voxel thicker
  // than the truth) met the finger shell before the real pads did at the
  // closing (the hand pushed 2 cm off) and still enclosed it at the release
  // (25 N on the hand, the arm thrown into the box). Nor, by default, is the
  // palm: the live voxmap keeps the grasped object's own voxels, and the
  // left palm, turned 1 rad over the box, sat in its top while carrying
  // (8-50 N on that hand, the box's wrist peaks 45-60 N; without it 16 N).
  // The held object's own pointshell against the voxmap less its voxels is
  // not built: while it is held, its contacts are not felt, only its weight
  // and the two-hand coupling.
  static constexpr double kClosingTol_m = 0.003;
  // At 0 ms the remote gripper keeps up with the lever, so only this tells
  // the closing: at 1 cm the box's finger shell met its voxels 6 mm into the
  // closing (the hand pushed 2 cm, a pad on the box, wrist peaks 47-52 N in
  // 3 of 3 runs). A lever wobbling by more costs finger contact until it
  // is open again (nothing held).
  static constexpr double kLeverClosing_m = 0.003;
  static constexpr double kGraspClear_m = 0.08;
  // Builds the gripper shells, their pair states and the budgets
  // (allocates); throws std::invalid_argument on bad parameters.
  explicit TelemanipTask(const TelemanipTaskParams& p);

  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
            servo::TickOutput& out) noexcept override;
  // The voxmap a tick renders against (the model snapshot's otherwise):
  // tests and benches hand one in. Null: the snapshot's.
  void set_voxmap_override(const vps::Voxmap* vm, std::uint64_t build) noexcept {
    override_vm_ = vm;
    override_build_ = build;
  }

  NewestMailbox<TelemanipSetpoint>& setpoints() noexcept { return setpoints_; }  // the link consumes
  NewestMailbox<RemoteArmsState>& remote() noexcept { return remote_; }           // the link produces
  // Each hand's mapping state every tick (the SIMULATED human consumes).
  NewestMailbox<MappingAnchor>& anchors(int k) noexcept { return anchors_[static_cast<std::size_t>(k)]; }
  // Where the live voxmap's region of interest should follow (the model
  // thread's probe box: the midpoint of both commanded G, W = A); null: nowhere.
  // Set before the loop starts.
  void set_roi_out(NewestMailbox<ProbePosition>* m) noexcept { roi_out_ = m; }
  // Each tick's hand trace sample (hand_trace.h) into trace(), for one
  // consumer (hemm-operator --hand-trace). Set before the loop starts.
  void set_trace(bool on) noexcept { trace_on_ = on; }
  // Each tick into the session recorder's ring (hemm-operator --record):
  // the sample, the voxmap build rendered with, the wrench commanded, the
  // feedback mode (0 model, 1 direct). Set before the loop starts.
  void set_tick_tap(ServoTickTap* tap) noexcept { tick_tap_ = tap; }
  NewestMailbox<HandTraceSample>& trace() noexcept { return trace_; }

  const TelemanipTaskParams& params() const noexcept { return p_; }
  const GripperToolSet& grippers() const noexcept { return tools_; }
  const vps::ToolParams& tool_params(int k) const noexcept { return tool_params_[static_cast<std::size_t>(k)]; }
  // Servo thread, or after the loop stopped.
  const ArmMappingState& mapping(int k) const noexcept { return map_[static_cast<std::size_t>(k)]; }
  const ArmCommandOut& command(int k) const noexcept { return cmd_[static_cast<std::size_t>(k)]; }
  const HandRenderStats& render_stats(int k) const noexcept { return stats_[static_cast<std::size_t>(k)]; }
  // The held object's state (holds, peak squeeze, felt weights).
  const HeldObjectState& held() const noexcept { return held_; }
  // The direct mode's hand (its passivity port, what it showed and sent).
  const DirectHandState& direct_hand(int k) const noexcept { return direct_[static_cast<std::size_t>(k)]; }
  std::uint64_t direct_resets() const noexcept { return direct_resets_; }
  const vps::TickWorkBudget& budget(int k) const noexcept { return budget_[static_cast<std::size_t>(k)]; }
  const vps::WorkRateCalibration& calibration() const noexcept { return calibration_; }
  std::uint64_t ticks() const noexcept { return ticks_; }
  // The newest remote state a tick took (null: none).
  const RemoteArmsState* latest_remote() const noexcept { return remote_.latest(); }

 private:
  struct Hand {
    std::vector<vps::ToolState> states;  // one per shell (sized at start)
    int shell = 0;                       // the one in use
    std::uint64_t voxmap_build = 0;      // the build its pair state belongs to
    // The grasp phase (kClosingTol_m, kGraspClear_m).
    bool grasp = false;
    bool grasp_held = false;  // the remote gripper held in this grasp phase
    Eigen::Vector3d grasp_p_A = Eigen::Vector3d::Zero();
    double open_ref_m = 0.0;  // the widest commanded opening since the last grasp ended
  };
  // This tick's grasp phase of hand k (updates it).
  bool grasp_phase(int k, const RemoteArmsState* remote) noexcept;
  // Step 4: the held object's wrench added to both hands' commands.
  void render_held(const RemoteArmsState& remote, device::DeviceCommand& command) noexcept;
  void publish_trace(const device::DeviceSample& in, const RemoteArmsState* remote, const device::DeviceCommand& command) noexcept;
  // Shell i: the opening's (GripperToolSet::tools), the palm's past them.
  const vps::ProbeTool& shell_tool(int i) const noexcept;
  int palm_shell() const noexcept { return static_cast<int>(tools_.tools.size()); }
  void render_hand(int k, const vps::Voxmap* vm, std::uint64_t build, double opening, bool grasping, std::int64_t deadline_ns,
                   device::EndEffectorCommand& c) noexcept;

  TelemanipTaskParams p_;
  GripperToolSet tools_;
  std::array<vps::ToolParams, kTeleArms> tool_params_{};
  std::array<Hand, kTeleArms> hands_;
  std::array<vps::TickWorkBudget, kTeleArms> budget_{};
  vps::WorkRateCalibration calibration_;
  std::array<ArmMappingState, kTeleArms> map_{};
  std::array<ArmCommandOut, kTeleArms> cmd_{};
  std::array<HandRenderStats, kTeleArms> stats_{};
  HeldObjectState held_;
  HeldObjectWrench held_w_;  // this tick's (zero when not rendered)
  std::array<DirectHandState, kTeleArms> direct_{};
  std::uint64_t direct_epoch_ = 0;  // the robot's frame epoch the ports count in
  bool direct_epoch_seen_ = false;
  std::uint64_t direct_resets_ = 0;
  NewestMailbox<TelemanipSetpoint> setpoints_;
  NewestMailbox<RemoteArmsState> remote_;
  std::array<NewestMailbox<MappingAnchor>, kTeleArms> anchors_;
  NewestMailbox<ProbePosition>* roi_out_ = nullptr;
  ServoTickTap* tick_tap_ = nullptr;
  ServoTickRecord tap_record_;
  bool trace_on_ = false;
  NewestMailbox<HandTraceSample> trace_;
  const vps::Voxmap* override_vm_ = nullptr;
  std::uint64_t override_build_ = 0;
  std::uint64_t ticks_ = 0;
};

}  // namespace hemm::op::telemanip
