// The grasped object's mass and centre of mass from the remote wrist (issue
// 25, part 4): recursive least squares over gravity-only static samples of
// the environment's wrench on the gripper at G (ArmState force_A / torque_A,
// the wrist sensor with the gripper's own weight taken out) and the grasp
// frame's pose T_A_G.
//
// Model, in G (R = R_A_G, g_G = R^T g_A, h = m c_G the first moment):
//
//   f_G = R^T f_A = m g_G + b_f
//   t_G = R^T t_A = c_G x m g_G + b_t = -[g_G]x h + b_t
//
// linear in theta = (m, h, b_f, b_t) (10 parameters): y = Phi theta + noise,
// Phi = [g_G 0 I 0; 0 -[g_G]x 0 I]. The biases b_f, b_t (constant in G: the
// sensor is rigid with the flange) are what the robot's gripper compensation
// leaves; they separate from m and h only across orientations (or with tare
// samples of the empty gripper), so they get a prior (sigma) and m, h a
// wide one. c_G = h / m; its covariance by first-order propagation.
//
// A sample counts only when the grasp frame is static: |v| and |omega| small
// and the acceleration from the previous sample's twist (finite difference
// over at most max_sample_gap_s) small, so m a stays a small share of m g.
// Once the estimate has settled (min_samples_for_gate), a sample whose
// innovation is beyond gate_chi2 (6 DoF) is an outlier: the object resting on
// the bench, a contact. Non-finite or non-rotation input is refused and
// changes nothing.
//
// Pure, allocation-free (fixed-size Eigen): run on the model thread at the
// ArmsState rate (docs/telemanipulation_model.md).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/mesh/triangle_mesh.h"

namespace hemm::mapping {

struct GraspEstimateParams {
  Eigen::Vector3d gravity_A = Eigen::Vector3d(0, 0, -9.81);
  double force_sigma_n = 0.5;        // per-axis measurement noise
  double torque_sigma_nm = 0.05;
  double prior_mass_sigma_kg = 10.0;
  double prior_moment_sigma_kgm = 2.0;     // of h = m c
  double prior_force_bias_sigma_n = 2.0;   // 0: no bias estimated
  double prior_torque_bias_sigma_nm = 0.3;
  double max_speed = 0.05;                 // m/s
  double max_angular_speed = 0.3;          // rad/s
  double max_acceleration = 0.5;           // m/s^2 (finite difference of v)
  double max_angular_acceleration = 3.0;   // rad/s^2
  double max_sample_gap_s = 0.05;
  double gate_chi2 = 22.46;                // 6 DoF, 99.9 %; 0: no gate
  int min_samples_for_gate = 30;
};

// Empty when usable (positive sigmas, thresholds, finite gravity).
std::optional<std::string> validate(const GraspEstimateParams& p);

// One ArmsState sample of one arm while its gripper holds.
struct GraspSample {
  std::int64_t stamp_ns = 0;
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_A = Eigen::Vector3d::Zero();   // environment on the gripper at G
  Eigen::Vector3d torque_A = Eigen::Vector3d::Zero();
};

enum class GraspSampleResult : std::uint8_t {
  kUsed = 0,
  kNonFinite,      // refused: nothing changed
  kNotRotation,    // refused: nothing changed
  kNotMonotonic,   // refused: stamp not after the previous one
  kNoAcceleration, // first sample or a gap: kept as the previous, not used
  kMoving,         // too fast or accelerating: not used
  kOutlier,        // beyond the innovation gate: not used
};
const char* to_string(GraspSampleResult r);

using GraspVector = Eigen::Matrix<double, 10, 1>;
using GraspMatrix = Eigen::Matrix<double, 10, 10>;

struct GraspEstimator {
  GraspVector theta = GraspVector::Zero();  // m, h (3), b_f (3), b_t (3)
  GraspMatrix P = GraspMatrix::Zero();      // its covariance
  bool has_previous = false;
  std::int64_t previous_stamp_ns = 0;
  Eigen::Vector3d previous_v_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d previous_omega_A = Eigen::Vector3d::Zero();
  std::uint64_t used = 0;
  std::uint64_t refused = 0;   // non-finite, not a rotation, not monotonic
  std::uint64_t moving = 0;
  std::uint64_t outliers = 0;
};

// The prior: zero mean, the params' sigmas.
GraspEstimator make_grasp_estimator(const GraspEstimateParams& p);

// A sample while holding the object.
GraspSampleResult add_grasp_sample(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s);
// A sample of the empty gripper (m = 0, h = 0 known): it pins the biases, so
// one orientation while holding then suffices.
GraspSampleResult add_tare_sample(const GraspEstimateParams& p, GraspEstimator* e, const GraspSample& s);

struct GraspEstimate {
  double mass_kg = 0.0;
  double mass_variance = 0.0;
  Eigen::Vector3d com_G = Eigen::Vector3d::Zero();
  Eigen::Matrix3d com_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d force_bias_G = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_bias_G = Eigen::Vector3d::Zero();
  std::uint64_t samples = 0;
  bool valid = false;  // mass positive and more than twice its sigma
};
GraspEstimate current_estimate(const GraspEstimator& e);

// The held object's body in O = G of the grasping hand (T_O_G = identity)
// from an estimate: its mass and centre of mass, and the inertia of a solid
// box of `size` about it (the voxels between the fingers give the size; the
// wrench cannot tell the inertia at rest).
mesh::MassProperties body_from_estimate(const GraspEstimate& e, const Eigen::Vector3d& size);

}  // namespace hemm::mapping
