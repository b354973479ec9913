// 6-DoF virtual coupling between the haptic device pose and the virtual tool
// (a rigid body with mass and inertia), integrated semi-implicitly.
//
// Gain design (design_coupling), per device, from the sampled-data passivity
// condition of Colgate & Schenkel and the device's limits:
//  * A device with physical damping b, sampled at T with a zero-order hold,
//    renders a virtual spring-damper (K, B) passively if b > K T / 2 + |B|.
//    The worst case the device can meet through the coupling is the tool held
//    still by a rigid contact: it then feels the coupling (K, B) itself. So
//    K T / 2 + B <= margin * b. When b is not given, the device's rated
//    maximum stiffness K_max (at the same T, B = 0) says b >= K_max T / 2.
//  * The coupling damping B is what the hand feels as viscosity while the tool
//    is held: B v_max stays within a share of the peak force.
//  * K <= K_max, and the tool's explicit spring stays discretely stable:
//    K <= m (omega_dt / T)^2.
//  * The tool would ring on a weak coupling damper, so it gets damping to the
//    world (implicit, dissipative, felt only as drag c v through the spring),
//    sized for the damping ratio zeta with B and kept within a drag budget.
// Rotation: the same with torques, the smallest principal moment of inertia
// and the device's torque limits; a device that renders no torque gets a
// rotational coupling sized for the tool alone (its torque is never displayed,
// so it is outside the device's passivity condition).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/haptics/vps/contact.h"

namespace hemm::vps {

struct RigidBodyState {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // centre of mass, world
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();   // world
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // world
  Eigen::Isometry3d pose() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = orientation.toRotationMatrix();
    T.translation() = position;
    return T;
  }
};

struct CouplingParams {
  double dt = 1e-3;
  double mass = 0.5;
  Eigen::Matrix3d inertia_body = Eigen::Matrix3d::Identity() * 1e-3;  // about the centre of mass
  double k_lin = 1000.0, b_lin = 10.0;  // N/m, N s/m
  double k_rot = 10.0, b_rot = 0.1;     // N m/rad, N m s/rad
  double linear_damping = 0.0;          // to the world (N s/m), optional
  double angular_damping = 0.0;
};

// What the gain design needs to know about one end-effector of a device.
// The values are the device's (its backend publishes them); nothing here
// depends on a particular device.
struct CouplingDeviceLimits {
  double dt = 1e-3;                 // servo period T [s]
  double peak_force = 0.0;          // [N]
  double max_stiffness = 0.0;       // rated renderable stiffness at dt [N/m]
  double physical_damping = 0.0;    // b [N s/m]; 0: not known, use max_stiffness * dt / 2
  double max_speed = 0.1;           // hand speed the damping budget is checked at [m/s]
  bool renders_torque = false;
  double peak_torque = 0.0;         // [N m]
  double max_rot_stiffness = 0.0;   // [N m/rad]
  double physical_rot_damping = 0.0;  // [N m s/rad]; 0: use max_rot_stiffness * dt / 2
  double max_angular_speed = 1.0;   // [rad/s]
};

struct CouplingDesignOptions {
  double passivity_margin = 0.8;      // K T/2 + B <= margin * b
  double damping_share = 0.25;        // share of the passivity budget given to B
  double damping_force_share = 0.1;   // B * max_speed <= share * peak force
  double drag_force_share = 0.25;     // (B + c) * max_speed <= share * peak force
  double zeta = 0.7;                  // target damping ratio of the tool on the coupling
  double omega_dt = 0.5;              // discrete stability of the explicit springs
};

// The designed gains and the figures they were checked against.
struct CouplingDesign {
  CouplingParams params;
  double device_damping = 0.0;        // b used [N s/m]
  double passivity_lhs = 0.0;         // K T/2 + B
  double passivity_bound = 0.0;       // margin * b
  double damping_force_at_max_speed = 0.0;  // B * max_speed [N]
  double drag_at_max_speed = 0.0;     // (B + c) * max_speed [N]: free-motion drag felt
  double rot_device_damping = 0.0;
  double rot_passivity_lhs = 0.0;
  double rot_passivity_bound = 0.0;
};

// Applies the rule above for a tool of `mass` and `inertia_body` (about its
// centre of mass). Limits must be positive where used; they are the caller's
// (validated) configuration.
CouplingDesign design_coupling(double mass, const Eigen::Matrix3d& inertia_body, const CouplingDeviceLimits& device,
                               const CouplingDesignOptions& options = {});

// Largest effective contact stiffness (N/m) the tool integration tolerates.
double max_contact_stiffness(const CouplingParams& p, double omega_dt = 0.5);

// The deepest penetration the coupling is expected to produce, to size the
// voxmaps' distance layers (layers_for_depth): the coupling's force when the
// hand leads the tool by `max_lead` (capped by the device's peak force:
// beyond it the hand no longer feels more) over the stiffness of the
// smallest contact patch that must hold it (pressure stiffness times its
// area, or the per-point stiffness times its points).
double max_expected_penetration(const CouplingParams& p, double max_lead, double peak_force,
                                double contact_stiffness);

// One step: the coupling spring-damper pulls the tool towards the device pose
// T_W_D (velocities v_D, w_D); `contact` acts on the tool (torque about its
// centre of mass). `device_wrench` (may be null) gets the wrench to display on
// the device (the coupling's reaction), `coupling_wrench` (may be null) the
// coupling wrench on the tool.
void step_virtual_coupling(const CouplingParams& p, const Eigen::Isometry3d& T_W_D, const Eigen::Vector3d& v_D,
                           const Eigen::Vector3d& w_D, const Wrench& contact, RigidBodyState* tool,
                           Wrench* device_wrench, Wrench* coupling_wrench = nullptr);

double kinetic_energy(const CouplingParams& p, const RigidBodyState& s);
// Energy stored in the coupling spring for device pose T_W_D.
double coupling_potential(const CouplingParams& p, const RigidBodyState& s, const Eigen::Isometry3d& T_W_D);

}  // namespace hemm::vps
