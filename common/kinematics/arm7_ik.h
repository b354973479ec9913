// Inverse kinematics of the 7-DoF arm (damped least squares with joint-limit
// projection) and the reachability index of the bimanual paper's Fig. 2: the
// fraction of sampled end-effector orientations the IK reaches at a point.
// Pure, allocation-free per call (fixed-size Eigen).
#pragma once

#include <span>
#include <vector>

#include "common/kinematics/arm7.h"

namespace hemm::kinematics {

struct Arm7IkOptions {
  int max_iterations = 60;
  double position_tolerance_m = 1e-4;
  double orientation_tolerance_rad = 1e-3;
  double rotation_weight_m = 0.2;  // metres of position error worth 1 rad of orientation error
  double damping = 1e-2;           // initial Levenberg-Marquardt damping [m]
  double max_step_rad = 0.4;       // per iteration, infinity norm
};

struct Arm7IkResult {
  Arm7Vector q = Arm7Vector::Zero();
  bool converged = false;  // within both tolerances and the joint limits
  double position_error_m = 0.0;
  double orientation_error_rad = 0.0;
  int iterations = 0;
};

// The flange pose T_A_J7 = T_target from `q_seed`. Always returns q within the
// limits and finite; non-finite input gives converged = false.
Arm7IkResult inverse_kinematics(const Arm7Model& model, const Eigen::Isometry3d& T_A_target, const Arm7Vector& q_seed,
                                const Arm7IkOptions& options = {});

// n orientations spread near-uniformly over SO(3) (a deterministic
// super-Fibonacci spiral).
std::vector<Eigen::Quaterniond> sample_orientations(int n);

// A fixed set of start postures spread over the joint space (within limits).
std::vector<Arm7Vector> ik_seed_postures(const Arm7Model& model);

struct ReachabilityResult {
  int reached = 0;
  int sampled = 0;
  double index() const { return sampled > 0 ? static_cast<double>(reached) / sampled : 0.0; }
};

// For each orientation R_k: does the IK reach the flange pose (p_A, R_k) from
// any of `seeds` (tried in order, after the last success at this point)?
ReachabilityResult reachability(const Arm7Model& model, const Eigen::Vector3d& p_A,
                                std::span<const Eigen::Quaterniond> orientations, std::span<const Arm7Vector> seeds,
                                const Arm7IkOptions& options = {});

}  // namespace hemm::kinematics
