// SimulatedRobot: the SIMULATED mobile manipulator the robot station drives.
// MuJoCo 2.2.2 steps the scene at the config's timestep (1 kHz); each step
// runs the controllers (arm PD + gravity compensation tracking the IK of the
// commanded end-effector target, base (v, omega) -> wheel speeds with
// acceleration limits), odometry, and the safety layer; the laser and sonar
// scan at their rates.
//
// Safety, in order of precedence:
//   * e-stop: wheel servos commanded to 0 at once (they brake at their torque
//     limit), the arm holds;
//   * no operator in control, watchdog expired (no valid command for
//     watchdog_ms), or the command's deadman released: the base decelerates
//     to a stop within its acceleration limits, the arm holds;
//   * collision guard: the base's forward/backward speed and its yaw rate are
//     limited so that it stops short of what its own laser and sonar see, in
//     space they saw free (CollisionGuardParams in robot_side/control/collision_guard.h).
//
// Re-arm: a stop is not undone by its cause going away. After the e-stop
// (engaged from anywhere), a lost link, an expired watchdog, or a time
// without an operator in control (start-up included), the robot follows
// nothing (SAFETY_REARM) until it has received, after the cause cleared, a
// neutral command (the dead-man released, or a command that asks for no
// motion: idle or exploration, navigation with v = omega = 0) and then a
// command with the dead-man pressed. So releasing an e-stop, or a link
// coming back, never resumes what the operator happened to be streaming.
//
// Time is the simulation's: time_ns() = origin + steps * timestep. In real-time
// mode the station sets the origin to its steady clock and steps to it (see
// realtime.h), so sim time and station time agree; tests just step.
//
// Not thread-safe: one thread owns it. MuJoCo stays behind the pimpl.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "robot_side/control/base_control.h"
#include "robot_side/control/arm_keep_out.h"
#include "robot_side/control/collision_guard.h"
#include "robot_side/control/seen_voxels.h"
#include "robot_side/sim/depth_camera.h"
#include "robot_side/sim/range_sensors.h"
#include "robot_side/sim/sim_types.h"

namespace hemm::config {
class RobotConfig;
}

namespace hemm::robot {

// The 3D keep-out's bookkeeping and cost (SimulatedRobot::seen_voxels_stats).
struct SeenVoxelsStats {
  uint64_t frames = 0;          // depth frames integrated
  std::size_t voxels = 0;       // seen voxels now
  std::size_t memory_bytes = 0;  // of the voxel set (the points snapshot adds 12 B a voxel)
  double last_integrate_us = 0.0, max_integrate_us = 0.0;  // per frame, incl. the snapshot
  uint64_t checks = 0;           // arm chain checks (manipulation commands)
  double max_check_us = 0.0, sum_check_us = 0.0;
};

class SimulatedRobot {
 public:
  SimulatedRobot();
  ~SimulatedRobot();
  SimulatedRobot(SimulatedRobot&&) noexcept;
  SimulatedRobot& operator=(SimulatedRobot&&) noexcept;
  SimulatedRobot(const SimulatedRobot&) = delete;
  SimulatedRobot& operator=(const SimulatedRobot&) = delete;

  // Loads an MJCF scene (which includes robot.xml) and applies the config
  // (sim.timestep_s and sim.seed; laser, sonar, base, arm, safety). On error
  // returns why and leaves this object as it was.
  std::optional<std::string> load(const config::RobotConfig& config, const std::string& scene_path);
  bool loaded() const;

  // Simulation time. set_time_origin_ns() shifts the clock (no stepping).
  void set_time_origin_ns(int64_t origin_ns);
  int64_t time_ns() const;
  int64_t timestep_ns() const;

  // Advances n steps (faster than real time; n <= 0 does nothing).
  void step(int n = 1);
  // Steps until time_ns() >= t_ns, at most max_steps; returns steps taken.
  int step_until(int64_t t_ns, int max_steps);

  // A command received at robot time now_ns (the watchdog's clock). Invalid
  // commands (non-finite numbers, unknown mode, absurd targets) are rejected
  // with a reason and change nothing. A manipulation command's target is
  // solved by IK at once; an unreachable one is replaced by the nearest
  // reachable pose and flagged SAFETY_JOINT_LIMIT.
  // A manipulation target whose arm pose would reach into the floor, the
  // base or what the robot's own sensors have seen (recent scans; with the
  // depth camera its seen voxels) is refused too (ArmKeepOut in
  // robot_side/control/arm_keep_out.h), counted by reason; when the IK's solution
  // is refused for the base or the scene, the elbow-up solution of the same
  // target is tried first. A manipulation command without the deadman moves
  // nothing: its target is not solved (nor refused).
  std::optional<std::string> set_command(const BaseArmCommand& command, int64_t now_ns);
  // The robot's own neutral command (an IDLE command: e.g. when the session
  // changes mode). It stops what the old command was doing; it is not the
  // operator's, so it does not count towards the re-arm and feeds no watchdog.
  void stop_commanded_motion(uint64_t seq);
  // False while motion is held until re-armed (see "Re-arm" above).
  bool armed() const;
  uint64_t rejected_commands() const;
  struct ArmRefusals {
    uint64_t floor = 0, base = 0, scene = 0;
    ArmRefusal last = ArmRefusal::kNone;  // the newest refusal's reason
    uint64_t last_seq = 0;                // and its command's sequence number
  };
  ArmRefusals arm_refusals() const;
  // The 3D keep-out's bookkeeping (seen voxels from the depth camera, on the
  // depth worker thread with kWorker) and the arm checks' cost (simulation
  // thread, in set_command). With kWorker the voxel figures are those of
  // the newest snapshot the simulation thread took.
  SeenVoxelsStats seen_voxels_stats() const;

  void set_operator_in_control(bool in_control);  // set by the authenticated session
  void set_estop(bool engaged);
  bool estop() const;
  void set_link_lost(bool lost);  // reported as SAFETY_LINK_LOST (the session stops the robot itself)

  RobotStateSim state() const;
  // Scans completed since the last call, oldest first (at most 64 kept).
  std::vector<RangeScanData> take_scans();

  const kinematics::Arm5Model& arm_model() const;
  Eigen::Isometry3d T_R_A() const;  // arm base frame in the robot base frame
  const SimLaserParams& laser_params() const;
  const SimSonarParams& sonar_params() const;
  const SkidSteerGeometry& base_geometry() const;
  void enable_sensors(bool laser, bool sonar);  // benchmarks; default from config
  // The SIMULATED depth camera on the arm's wrist (off until enabled): its
  // frame S sits at params.T_mount_S in the end-effector frame E. Frames are
  // cast at params.rate_hz; each carries the odometry pose T_W_S at
  // acquisition (odometry x arm forward kinematics of the measured joints)
  // and the true one. A reason if params are invalid (nothing changes then).
  // kInline casts within the step that takes the frame (deterministic, for
  // tests); kWorker on a thread of its own from that step's geometry, so the
  // simulation thread is not made late (frames due while one is being cast
  // are skipped: depth_frames_skipped()).
  enum class DepthCasting { kInline, kWorker };
  std::optional<std::string> enable_depth_camera(const SimDepthCameraParams& params,
                                                 DepthCasting casting = DepthCasting::kInline);
  std::uint64_t depth_frames_skipped() const;
  void disable_depth_camera();
  // Depth frames completed since the last call, oldest first (at most 4 kept:
  // newest wins).
  std::vector<mapping::DepthImage> take_depth_images();

  // ---- SIMULATION ONLY (tests, evaluation) ----
  // Teleports the base (zero velocity); odometry restarts at the same pose.
  void set_base_pose_sim(const Pose2& T_W_R);
  // Teleports the arm (zero velocity) and holds it there.
  void set_arm_q_sim(const kinematics::Arm5Vector& q);
  // The end-effector site pose in the arm base frame, from MuJoCo's own
  // kinematics of the current state.
  Eigen::Isometry3d mujoco_T_A_E_sim() const;
  // Number of active contacts between robot geoms and the named world geom
  // (or any non-robot geom but the floor when the name is empty).
  int robot_contacts_sim(const std::string& world_geom = "") const;
  // Contacts between the arm's geoms (arm_base and its links) and any
  // non-robot geom, counted every step, and the tool's (arm_link5: the
  // forearm tip capsule and the payload sphere) true clearance to the world,
  // measured up to 0.10 m (beyond: 0.10).
  struct ArmContactStats {
    uint64_t contact_steps = 0;  // steps with at least one arm contact
    uint64_t contacts = 0;       // contacts summed over steps
    double tool_clearance = 0.10;      // m, now
    double tool_min_clearance = 0.10;  // m, the smallest so far
  };
  ArmContactStats arm_contacts_sim() const;
  // The MuJoCo state for a live view: time, qpos and every active contact
  // with its force (scans and state are the caller's). Reuses out's storage.
  void view_frame_sim(SimViewFrame* out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Sensor parameters from the config (also used by the station to describe them).
SimLaserParams laser_params_from_config(const config::RobotConfig& config);
SimSonarParams sonar_params_from_config(const config::RobotConfig& config);
// The depth camera of config depth_camera (enabled or not).
SimDepthCameraParams depth_camera_params_from_config(const config::RobotConfig& config);

}  // namespace hemm::robot
