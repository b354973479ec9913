// A grasped object in the operator's local model (issue 25, part 3): a rigid
// body (mass, centre of mass, inertia) simulated at the servo rate and coupled
// to each hand that holds it by a 6-DoF spring-damper, the virtual coupling's
// form (vps/coupling.h) with the spring attached at the hand's grasp frame G
// instead of the centre of mass. Held by one hand, that hand feels the weight,
// the inertia and the torque of an offset centre of mass; held by two, the
// object couples them: statics share the weight, and moving the hands apart or
// together stretches the two springs in series, a squeeze along the grasp line.
//
// Frames: A is the frame the hands are given in (on the operator's telemanip
// side the remote torso base, where the live voxmap is), gravity in A; O the
// object's frame (its mesh's), G a grasp frame, T_O_G per hand.
//
// Integration (per tick, dt): the object's twist nu = (v at the centre of mass,
// omega), both in A, with M = diag(m I, I_A) and per holding hand h (grip
// weight w_h, attachment point p_h = T_A_O t_O_Gh, r_h = p_h - c, point
// Jacobian J_h = [I, -[r_h]x]):
//
//   (M + dt D + dt^2 K) nu+ = M nu + dt (F_spring + F_hand_damping + m g + F_contact - omega x I_A omega)
//   D = sum w_h (J_h^T B J_h + diag(0, B_r I)) + diag(c I, c_r I),  K = sum w_h (J_h^T K J_h + diag(0, K_r I))
//   (c, c_r: the optional damping to A, HeldCouplingGains::linear_damping / angular_damping)
//
// i.e. linearized backward Euler on the coupling springs and dampers, explicit
// gravity, contact and gyroscopic terms; then c += dt v+, R <- exp(dt omega+) R.
// The coupling (linear and rotational springs and dampers) is thereby stable
// for every K, B, K_r, B_r >= 0 at any dt (backward Euler's amplification
// factor of a spring-damper-mass is below 1 in modulus), so no stiffness bound
// comes from the integration: not omega dt < 2 as for an explicit spring,
// nor the virtual coupling's omega dt <= 0.5 rule. What stays explicit is
// small at the coupling's stretches: the gyroscopic term, the log map's
// curvature and the offset's geometric stiffness (|f| |r|, a pendulum's: a few
// Hz). Tests run a thin bar whose K_r / I_min puts omega dt at 3.2, where an
// explicit spring diverges. The price is a numerical damping of about K dt
// (2 N s/m at K 2000 N/m, 1 kHz): passive, felt as a little more viscosity.
// The bound that remains for the hand is the device's passivity,
// K T/2 + B <= b_device, which vps::design_coupling sizes for the device;
// gains_from_coupling() reuses those gains.
//
// The hand receives the reaction of its coupling: (-f_h, -tau_h) at its G, in
// A. The object's stored energy (kinetic + springs + gravity) never grows by
// more than the work the hands put in (tests: held_object_test.cpp).
//
// Grasp and release never step the force: a hand's coupling weight w_h ramps
// between 0 and 1 over grip_ramp_s (release, a second hand's grasp); the
// first hand's grasp places the object on the hand (no stretch) and ramps the
// object's weight in over the same time (what supported it hands it over), the
// last hand's release ramps it out again. Per tick a hand's force changes by
// at most about |f_h| dt / grip_ramp_s plus the object's own motion.
//
// Pure, allocation-free, no I/O: called on the servo thread (docs/telemanipulation_model.md).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/coupling.h"
#include "common/mesh/triangle_mesh.h"

namespace hemm::haptics {

inline constexpr int kHeldHands = 2;  // hand i is device hand / remote arm i (0 right, 1 left)

// One hand's spring-damper to the object (at its grasp frame).
struct HeldCouplingGains {
  double k_lin = 2000.0;  // N/m
  double b_lin = 20.0;    // N s/m
  double k_rot = 20.0;    // N m/rad
  double b_rot = 0.2;     // N m s/rad
  // Damping of the object to A (the virtual coupling's c: keeps a weakly
  // damped coupling from ringing; felt as drag c v through the springs).
  double linear_damping = 0.0;   // N s/m
  double angular_damping = 0.0;  // N m s/rad
};

// The virtual coupling's gains (designed for the device by vps::design_coupling).
HeldCouplingGains gains_from_coupling(const vps::CouplingParams& p);

struct HeldObjectModel {
  // Mass, centre of mass and inertia about it, in O (mesh::compute_mass_properties
  // of the object's mesh, or a grasp estimate: grasp_estimate.h).
  mesh::MassProperties body;
  HeldCouplingGains gains;
  double dt = 1e-3;                                      // servo period [s]
  Eigen::Vector3d gravity_A = Eigen::Vector3d(0, 0, -9.81);
  double grip_ramp_s = 0.1;                              // a coupling's fade in / out [s]
};

enum class HeldStatus : std::uint8_t {
  kOk = 0,
  kNotHeld,      // no hand holds the object: nothing simulated, zero wrenches
  kBadHand,      // hand index outside 0..kHeldHands-1
  kNonFinite,    // a pose, twist or contact wrench with NaN/inf (nothing changed)
  kNotRotation,  // a pose whose rotation is not orthonormal (nothing changed)
  kAlreadyHeld,  // grasp by a hand that already holds
};
const char* to_string(HeldStatus s);

// Empty when usable: positive finite mass, finite centre of mass, symmetric
// positive definite inertia, gains >= 0 and finite, finite gravity, dt > 0,
// ramp > 0. Not for the servo thread (allocates the message).
std::optional<std::string> validate(const HeldObjectModel& model);

struct HeldHandState {
  bool attached = false;   // the hand grasps (its coupling exists)
  bool releasing = false;  // its weight ramps to 0, then it detaches
  double weight = 0.0;     // grip weight w_h in [0, 1]
  Eigen::Isometry3d T_O_G = Eigen::Isometry3d::Identity();
};

struct HeldObjectData {
  Eigen::Isometry3d T_A_O = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_A = Eigen::Vector3d::Zero();      // centre-of-mass velocity
  Eigen::Vector3d omega_A = Eigen::Vector3d::Zero();
  double gravity_scale = 0.0;  // share of the weight the hands carry (ramps 0 <-> 1)
  std::array<HeldHandState, kHeldHands> hand{};
  std::uint64_t ticks = 0;
};

// A hand as the servo tick sees it: its grasp frame and twist, in A.
struct HeldHandInput {
  Eigen::Isometry3d T_A_G = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_A = Eigen::Vector3d::Zero();
};

struct HeldObjectOutput {
  // The wrench each hand feels at its G, in A (zero for a hand not holding).
  std::array<vps::Wrench, kHeldHands> on_hand{};
  // The coupling wrench on the object from each hand (force at the grasp
  // point, couple), in A: the reactions of on_hand.
  std::array<vps::Wrench, kHeldHands> on_object{};
  // Internal force along the grasp line (p_1 - p_0), N, positive when the
  // hands squeeze the object: (f_0 . u - f_1 . u) / 2 of the forces on the
  // object; 0 unless both hands hold.
  double squeeze_n = 0.0;
  Eigen::Vector3d grasp_line_A = Eigen::Vector3d::Zero();  // unit, hand 0 -> hand 1
};

bool held(const HeldObjectData& data);

// Hand `hand` grasps the object with grasp frame T_O_G. If no hand holds it
// yet, the object is placed on the hand (T_A_O = T_A_G T_O_G^-1, moving with
// the hand) and its weight ramps in; otherwise the hand's coupling ramps in
// from whatever stretch T_O_G leaves (grasp_frame_here() for none).
HeldStatus grasp(const HeldObjectModel& model, HeldObjectData* data, int hand, const HeldHandInput& input,
                 const Eigen::Isometry3d& T_O_G);
// The grasp frame that puts hand pose T_A_G on the object as it is now (no stretch).
Eigen::Isometry3d grasp_frame_here(const HeldObjectData& data, const Eigen::Isometry3d& T_A_G);
// Hand `hand` opens: its coupling ramps out (and, if it was the last, the weight too).
HeldStatus release(HeldObjectData* data, int hand);

// One servo tick. `contact` (may be null) acts on the object: force in A,
// torque about O's origin (vps::PairResult::on_shell with the pointshell's
// reference point at O's origin). Hands not attached are ignored.
HeldStatus step_held_object(const HeldObjectModel& model, HeldObjectData* data,
                            const std::array<HeldHandInput, kHeldHands>& hands, const vps::Wrench* contact,
                            HeldObjectOutput* out);

// Energy stored in the object and its couplings: kinetic + springs + the
// carried share of gravity's potential (zero at z_A = 0) [J].
double held_stored_energy(const HeldObjectModel& model, const HeldObjectData& data,
                          const std::array<HeldHandInput, kHeldHands>& hands);

// A solid box's inertia about its centre (edges `size` along the axes).
Eigen::Matrix3d solid_box_inertia(double mass, const Eigen::Vector3d& size);

}  // namespace hemm::haptics
