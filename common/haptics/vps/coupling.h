// 6-DoF virtual coupling between the haptic device pose and the virtual tool
// (a rigid body with mass and inertia), integrated semi-implicitly.
//
// Gain rule (documented choice):
//  * Passivity of the device side (Colgate & Schenkel): a device with physical
//    damping b_dev sampled at T stays passive for coupling stiffness
//    K < 2 b_dev / T; the caller passes the stiffness its device allows
//    (device_max_stiffness) and the coupling never exceeds it.
//  * Discrete stability of the tool: symplectic Euler of a mass-spring is
//    stable for w T < 2 (w = sqrt(K/m)); we keep w T <= omega_dt (default 0.5)
//    for the coupling and, through max_contact_stiffness(), for the contact
//    stiffness seen by the tool: K <= m (omega_dt / T)^2.
//  * Damping b = 2 zeta sqrt(K m) (zeta = 1, critical), applied implicitly so
//    it only removes energy whatever its size.
// Rotation: the same rule with the smallest principal moment of inertia.
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

// Applies the rule above. Returns gains for the given body and rate.
CouplingParams design_coupling(double mass, const Eigen::Matrix3d& inertia_body, double dt,
                               double device_max_stiffness, double device_max_rot_stiffness,
                               double omega_dt = 0.5);

// Largest effective contact stiffness (N/m) the tool integration tolerates.
double max_contact_stiffness(const CouplingParams& p, double omega_dt = 0.5);

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
