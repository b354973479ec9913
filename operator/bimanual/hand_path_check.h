// Whether a SIMULATED human's hand path suits its arm of the SIMULATED
// bimanual device, checked before the device runs (the VPS scenes,
// operator/vps/vps_bimanual.h, and the 6-DoF probe tool of the networked
// station, operator/station/tool6_bimanual.h, map scripted paths into D):
// the path starts where that hand rests (the object or tool appears where the
// hand holds it at the first tick, so a jump would start it off the path);
// along the whole path it stays inside the arm's workspace box (the
// controller walls it off outside), within the arm's reach with the elbow
// bent at least kMinElbowBend_rad (a flange pose fixes the bend of the S-R-S
// arm, arm7.h: near the stretched elbow the arm is singular and the hand
// stalls short of the path), and with the wrist centre and the handle out of
// the table's collision-avoidance zone (which would hold the hand above it).
#pragma once

#include <functional>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "operator/device/bimanual/simulated_bimanual_device.h"

namespace hemm::op {

// How far a path's start may be from where the hand rests.
inline constexpr double kStartTolerance_m = 0.005;
inline constexpr double kStartTolerance_rad = 0.05;
// The least elbow bend a path may need (|q4|, kinematics::elbow_bend): 20
// degrees keeps the arm's Jacobian well away from the stretched-elbow
// singularity where the SIMULATED hand stalled (assembly drill, README).
inline constexpr double kMinElbowBend_rad = 0.35;

struct HandPathIssue {
  enum class Kind {
    kStartPosition,     // the start is more than kStartTolerance_m from the rest
    kStartOrientation,  // ... or more than kStartTolerance_rad
    kWorkspace,         // leaves the arm's workspace box
    kPosture,           // beyond the reach, elbow nearly stretched, or into the table zone
  };
  Kind kind;
  // What is wrong, where and when, without a field name (the caller names
  // the field and adds what to change), e.g. "the path leaves the SIMULATED
  // right arm's workspace at t = 3.2 s (D: ...; box ... to ...)".
  std::string message;
};

// T_D_E(t): where the hand (the handle's E frame, in D) is asked to be at t.
using HandPath = std::function<Eigen::Isometry3d(double t_s)>;

// Checks arm `arm`'s path over [0, duration_s] every 10 ms against a device
// that has not run yet (its hands at their rest). nullopt: the path suits.
std::optional<HandPathIssue> check_hand_path(const device::bimanual::SimulatedBimanualDevice& dev,
                                             device::bimanual::ArmSide arm, const HandPath& T_D_E, double duration_s);

// "x y z" with 6 significant digits (for the messages).
std::string vector_text(const Eigen::Vector3d& v);

}  // namespace hemm::op
