// Value types of the SIMULATED robot station: commands in, state and range
// scans out. Plain data; conversions to/from hemm::wire are in wire_convert.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/kinematics/arm5.h"
#include "common/math/frames.h"
#include "wire.pb.h"

namespace hemm::robot {

// Planar pose T_W_R: position (m) and heading (rad, CCW from +x); the one
// SE(2) type of the project.
using math::Pose2;

// What the operator asks for (see hemm.wire.Command).
struct BaseArmCommand {
  int64_t stamp_ns = 0;  // operator clock at sending (informational)
  uint64_t seq = 0;      // stream sequence number, reported back as last_command_seq
  wire::Mode mode = wire::MODE_IDLE;
  double v = 0.0;        // m/s, frame R
  double omega = 0.0;    // rad/s
  Eigen::Vector3d arm_target_R = Eigen::Vector3d::Zero();  // end-effector position, frame R
  double wrist_pitch = 0.0;  // tool pitch, rad
  double wrist_roll = 0.0;   // forearm roll q4, rad
  bool deadman = false;
  // Where the depth camera's pan-tilt head should look (hemm.wire.Gaze);
  // present false: the command carries none (an older operator).
  struct Gaze {
    bool present = false;
    bool active = false;
    Eigen::Vector3d point_W = Eigen::Vector3d::Zero();  // odometry world frame W
  } gaze;
};

// The pan-tilt head's state (hemm.wire.HeadState); present false without one.
struct HeadStateSim {
  bool present = false;
  double pan = 0.0, tilt = 0.0;        // encoder readings, rad
  double pan_setpoint = 0.0, tilt_setpoint = 0.0;
  bool gaze_active = false;
  uint64_t gaze_refusals = 0;
  int last_gaze_refusal = 0;           // robot::GazeRefusal as int
  uint64_t last_gaze_refused_seq = 0;
  double pan_truth = 0.0, tilt_truth = 0.0;  // SIMULATION ONLY
};

struct RobotStateSim {
  int64_t stamp_ns = 0;
  Pose2 T_W_R_odom;   // from wheel odometry (drifts)
  Pose2 T_W_R_truth;  // SIMULATION ONLY: MuJoCo's pose, for evaluation
  double v = 0.0;       // m/s, forward speed from wheel odometry (what a real robot knows)
  double omega = 0.0;   // rad/s, yaw rate from wheel odometry
  double v_truth = 0.0;      // SIMULATION ONLY: MuJoCo's forward speed
  double omega_truth = 0.0;  // SIMULATION ONLY: MuJoCo's yaw rate
  double wheel_left = 0.0;   // measured wheel surface speed, m/s
  double wheel_right = 0.0;
  kinematics::Arm5Vector q = kinematics::Arm5Vector::Zero();
  kinematics::Arm5Vector qd = kinematics::Arm5Vector::Zero();
  kinematics::Arm5Vector tau = kinematics::Arm5Vector::Zero();
  Eigen::Isometry3d T_R_E = Eigen::Isometry3d::Identity();
  uint32_t safety = 0;  // OR of hemm::wire::SafetyFlags
  wire::Mode mode = wire::MODE_IDLE;
  uint64_t last_command_seq = 0;
  // Arm targets refused so far (floor, base and scene together), the newest
  // refusal's reason (robot::ArmRefusal as int: 0 none, 1 floor, 2 base, 3
  // scene) and the refused command's sequence number.
  uint64_t arm_refusals = 0;
  int last_arm_refusal = 0;
  uint64_t last_refused_seq = 0;
  HeadStateSim head;
};

enum class RangeSensorKind { kLaser, kSonar };

// One complete scan. Beam i points at angle_min + i * angle_step in frame S
// (rotation about z_S); its range is measured from the origin of S. A beam with
// valid[i] == 0 is a dropout or has no return within the limits: its range is
// set to range_max and is never an obstacle (never an obstacle at 0 m).
// no_return[i] == 1 (valid 0) tells the two apart: nothing up to range_max
// (free space along the beam), not a dropout (no information).
struct RangeScanData {
  int64_t stamp_ns = 0;
  uint32_t scan_id = 0;
  RangeSensorKind kind = RangeSensorKind::kLaser;
  std::string sensor_name;
  Pose2 T_W_R_odom;   // odometry pose at acquisition
  Pose2 T_W_R_truth;  // SIMULATION ONLY
  Eigen::Isometry3d T_R_S = Eigen::Isometry3d::Identity();
  double angle_min = 0.0;
  double angle_step = 0.0;
  double range_min = 0.0;
  double range_max = 0.0;
  double beam_width = 0.0;  // rad, full cone (sonar), 0 for the laser
  std::vector<float> ranges;
  std::vector<uint8_t> valid;  // 1 valid, 0 invalid
  std::vector<uint8_t> no_return;  // empty, or per beam: 1 = nothing up to range_max

  size_t size() const { return ranges.size(); }
};

// SIMULATION ONLY: what the robot station's live view draws (robot_side/view):
// the MuJoCo state to pose its own copy of the scene, the true contacts, and
// the newest scans with the true pose of their acquisition.
struct SimContact {
  Eigen::Vector3d pos_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_W = Eigen::Vector3d::Zero();  // on geom2 from geom1 (normal and friction)
  int geom1 = -1, geom2 = -1;                         // MuJoCo geom ids of the scene
};
struct SimViewFrame {
  int64_t t_ns = 0;              // simulation time
  std::vector<double> qpos;      // the scene model's qpos
  std::vector<SimContact> contacts;
  std::vector<RangeScanData> scans;  // newest scan of each sensor
  RobotStateSim state;
  bool link_up = false, in_control = false;
};

}  // namespace hemm::robot
