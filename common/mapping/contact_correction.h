// The surface the remote arm actually touched, where the local voxmap
// disagrees (issue 25, part 4): a rigid offset o of the rendered surface (the
// voxmap moved by o in A), estimated from the remote's contacts and applied
// rate-limited, as the 2D registration corrects the map.
//
// Per ArmsState sample of one arm (its G pose, the environment's wrench at G
// in A, with the held object's modelled wrench taken out by the caller) and
// the gripper's pointshell in G (points, inward normals):
//
//  * The robot touches (|f| > contact_force_n for `persistence` samples):
//    the contact point is where the wrench's line of action,
//    p = p_G + (f x t) / |f|^2 + s f^, meets the gripper: among the pointshell
//    points within line_tolerance_m of that line whose inward normal faces
//    along f^ (a frictionless push), the one reaching furthest along -f^ (the
//    support point towards the surface); none: no single contact, skipped. The real surface passes through that point c with
//    normal n = f^, so the corrected model should have sdf(c) = 0: the
//    observation is n . o_true = n . o + sdf_o(c) (sdf_o: the voxmap's signed
//    distance with the current estimate applied).
//  * The model says deep contact (the pointshell's deepest point at the
//    remote's pose more than deep_penetration_m inside) while the robot feels
//    nothing (|f| < free_force_n for `persistence` samples): the real surface
//    is at least that deep behind: the observation moves the surface back
//    along the model's normal there until that point just touches.
//  * Otherwise (free in both, or the robot's contact agrees within noise):
//    nothing changes.
//
// The observations feed a filter on o (3D, zero prior, a slow random walk so
// it follows a drifting map): each moves o along its own normal only, with the
// Kalman gain of that direction (n^T P n / (n^T P n + sigma^2)); a full gain
// would leak residuals sideways through the measured normal's noise. A residual at the voxmap's stored distance limit (far outside /
// inside) is a bound, not a distance: the estimate moves by it without
// shrinking the covariance, and the next samples finish the step.
//
// Rate limit: the rendered surface follows the estimate at most slew_m_per_s
// (slew_surface_offset, every servo tick), so a contact of stiffness K feels
// the correction change by at most K slew dt per tick (K slew per second):
// 5 mm/s by default, 10 N/s at K = 2000 N/m.
//
// Pure, allocation-free: observe_contact on the model thread at the state
// rate, slew_surface_offset on the servo thread (docs/telemanipulation_model.md).
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/haptics/vps/pointshell.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::mapping {

struct ContactCorrectionParams {
  double contact_force_n = 3.0;        // |f| above: the remote touches
  double free_force_n = 1.0;           // |f| below: it touches nothing
  int persistence = 10;                // consecutive samples to confirm either (40 ms at 250 Hz)
  double line_tolerance_m = 0.01;      // the line of action must pass this close to a gripper point
  double min_normal_cos = 0.5;         // that point's inward normal . f^ at least this
  double deep_penetration_m = 0.004;   // the model's penetration that contradicts a free robot
  double measurement_sigma_m = 0.002;  // one observation's uncertainty along its normal
  double prior_sigma_m = 0.05;
  double drift_sigma_m_per_sqrt_s = 0.002;  // random walk of the true offset
  double max_offset_m = 0.05;          // the estimate never goes beyond (clamped)
  double slew_m_per_s = 0.005;         // the applied offset's rate limit
};
std::optional<std::string> validate(const ContactCorrectionParams& p);

// The voxmap as the model renders it: the voxmap and its pose in A.
struct CorrectedVoxmap {
  const vps::Voxmap* voxmap = nullptr;
  Eigen::Isometry3d T_A_V = Eigen::Isometry3d::Identity();
};

// One remote sample of one arm.
struct ContactSample {
  std::int64_t stamp_ns = 0;
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();
  Eigen::Vector3d force_A = Eigen::Vector3d::Zero();   // environment on the gripper at G
  Eigen::Vector3d torque_A = Eigen::Vector3d::Zero();
};

enum class ContactObservation : std::uint8_t {
  kNone = 0,           // nothing to correct (free and free, or not yet confirmed)
  kRobotContact,       // the robot's contact point corrected the estimate
  kModelTooDeep,       // a free robot where the model penetrates: surface moved back
  kNoSingleContact,    // the line of action misses the gripper: skipped
  kNonFinite,          // refused: nothing changed
  kNotRotation,        // refused: nothing changed
  kNotMonotonic,       // refused: stamp not after the previous one
};
const char* to_string(ContactObservation o);

struct ContactCorrection {
  Eigen::Vector3d offset_A = Eigen::Vector3d::Zero();  // estimate of o
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();         // its covariance
  int contact_run = 0;  // consecutive samples above contact_force_n
  int free_run = 0;     // consecutive samples below free_force_n
  bool has_stamp = false;
  std::int64_t last_stamp_ns = 0;
  // Last located contact (for the view and the report).
  Eigen::Vector3d last_point_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_normal_A = Eigen::Vector3d::Zero();
  double last_residual_m = 0.0;
  std::uint64_t robot_contacts = 0, model_too_deep = 0, skipped = 0, refused = 0;
};
ContactCorrection make_contact_correction(const ContactCorrectionParams& p);

// The model's signed distance at x_A with the offset applied (positive outside).
double corrected_sdf(const CorrectedVoxmap& map, const Eigen::Vector3d& offset_A, const Eigen::Vector3d& x_A);

ContactObservation observe_contact(const ContactCorrectionParams& p, const CorrectedVoxmap& map,
                                   const vps::PointShell& gripper_G, const ContactSample& s, ContactCorrection* c);

// The offset the renderer applies, moved towards `target` by at most
// slew_m_per_s * dt (one servo tick). Returns the applied offset.
Eigen::Vector3d slew_surface_offset(const ContactCorrectionParams& p, const Eigen::Vector3d& target, double dt,
                                    Eigen::Vector3d* applied_A);

}  // namespace hemm::mapping
