// The SIMULATED two-arm station's plant: deploy/scenes/workbench.xml in
// MuJoCo 2.2.2. Loads the scene, checks that each arm's chain is
// lwr_arm_model() (offsets, axes, ranges, masses, centres of mass,
// inertias, armature: the controllers' nominal model must be the arm that
// is simulated), reads the mounts, grasp frames and gripper payloads into a
// TwoArmModel, and exchanges what real hardware would: joint readings, wrist
// force-torque and finger pad forces out, joint torques and finger forces in.
// MuJoCo stays in the .cpp; callers that need the engine's truth include
// <mujoco/mujoco.h> and use m() / d().
#pragma once

#include <array>
#include <memory>
#include <string>

#include "common/kinematics/arm7.h"
#include "robot_side/twoarm/twoarm_control.h"
#include "robot_side/twoarm/twoarm_model.h"

struct mjModel_;
struct mjData_;

namespace hemm::twoarm {

class WorkbenchSim {
 public:
  // Throws std::runtime_error naming what is wrong (MuJoCo's message, a
  // missing body or sensor, an arm that is not lwr_arm_model()).
  explicit WorkbenchSim(const std::string& scene_path);
  ~WorkbenchSim();
  WorkbenchSim(const WorkbenchSim&) = delete;
  WorkbenchSim& operator=(const WorkbenchSim&) = delete;

  const TwoArmModel& model() const noexcept { return model_; }
  double timestep_s() const noexcept;
  double time_s() const noexcept;

  // Both arms at joint angles q (velocities zero), fingers at the given
  // strokes, objects at the scene's poses; then mj_forward.
  void reset(const std::array<kinematics::Arm7Vector, kArms>& q, const std::array<double, kArms>& finger_m = {});

  ArmReading reading(Side s) const noexcept;
  // Holds until the next set; values beyond the motors' ranges are clipped by
  // MuJoCo (the actuators' ctrlrange: the torque limits).
  void set_command(Side s, const ArmCommand& c) noexcept;
  void step() noexcept;  // one MuJoCo step

  // Truth.
  Eigen::Isometry3d body_pose_A(const std::string& body) const;  // throws std::invalid_argument on a bad name
  Eigen::Isometry3d grasp_site_A(Side s) const noexcept;       // the scene's grasp site
  mjModel_* m() const noexcept;
  mjData_* d() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  TwoArmModel model_;
};

}  // namespace hemm::twoarm
