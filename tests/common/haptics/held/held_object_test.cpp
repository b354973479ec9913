// The held object against closed forms: a hand's static load (weight, the
// torque of an offset centre of mass on a torsional spring), two hands'
// statics (symmetric and by the lever rule with the rotational springs), the
// squeeze of two springs in series, the inertia an accelerating hand feels,
// passivity (stored energy never above the work the hands put in; a free
// swing never gains energy, also where an explicit spring would diverge),
// hand-over without force steps, bad input, no allocation.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>

#include "common/haptics/held_object.h"
#include "common/math/frames.h"
#include "tests/common/haptics/vps/test_devices.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::haptics {
namespace {

constexpr double kG = 9.81;

Eigen::Isometry3d held_pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  return math::make_transform(R, p);
}

HeldHandInput held_hand(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  HeldHandInput h;
  h.T_A_G = held_pose(p, R);
  return h;
}

// A solid box of `mass` and `size`, centre of mass at `com_O`.
HeldObjectModel held_box(double mass, const Eigen::Vector3d& size, const Eigen::Vector3d& com_O,
                         const HeldCouplingGains& gains) {
  HeldObjectModel m;
  m.body.mass = mass;
  m.body.centre_of_mass = com_O;
  m.body.inertia_com = solid_box_inertia(mass, size);
  m.gains = gains;
  EXPECT_FALSE(validate(m).has_value());
  return m;
}

HeldCouplingGains held_gains(double k, double b, double kr, double br) {
  HeldCouplingGains g;
  g.k_lin = k;
  g.b_lin = b;
  g.k_rot = kr;
  g.b_rot = br;
  return g;
}

// Runs `ticks` with fixed hands.
HeldObjectOutput held_run(const HeldObjectModel& m, HeldObjectData* d, const std::array<HeldHandInput, 2>& hands,
                          int ticks) {
  HeldObjectOutput out;
  for (int i = 0; i < ticks; ++i) EXPECT_EQ(step_held_object(m, d, hands, nullptr, &out), HeldStatus::kOk);
  return out;
}

// The tilt theta of a body on a torsional spring K_r about a pivot whose
// centre of mass sits h horizontally and z0 vertically from the pivot:
// K_r theta = m g (h cos theta + z0 sin theta), by bisection.
double held_pendulum_tilt(double kr, double m, double h, double z0) {
  double lo = 0.0, hi = std::numbers::pi / 2;
  for (int i = 0; i < 200; ++i) {
    const double t = 0.5 * (lo + hi);
    (kr * t - m * kG * (h * std::cos(t) + z0 * std::sin(t)) < 0 ? lo : hi) = t;
  }
  return 0.5 * (lo + hi);
}

TEST(HeldObject, OneHandFeelsTheWeightAndTheTorqueOfAnOffsetCentreOfMass) {
  struct Case {
    double mass;
    Eigen::Vector3d com_G;  // centre of mass from the grasp frame (object at rest: O = G axes)
    HeldCouplingGains gains;
  };
  const Case cases[] = {
      {1.5, {0.10, 0.0, 0.0}, held_gains(2000, 30, 40, 0.6)},
      {0.4, {0.05, 0.03, -0.02}, held_gains(3500, 15, 15, 0.15)},
      {2.0, {0.0, -0.08, 0.04}, held_gains(1200, 40, 60, 0.8)},
  };
  for (const Case& c : cases) {
    const HeldObjectModel m = held_box(c.mass, {0.2, 0.15, 0.1}, c.com_G, c.gains);
    HeldObjectData d;
    const Eigen::Vector3d P(0.6, -0.2, 0.9);
    const std::array<HeldHandInput, 2> hands{held_hand(P), HeldHandInput{}};
    ASSERT_EQ(grasp(m, &d, 0, hands[0], Eigen::Isometry3d::Identity()), HeldStatus::kOk);
    const HeldObjectOutput out = held_run(m, &d, hands, 6000);
    // Statics: the hand carries the weight ...
    EXPECT_NEAR((out.on_hand[0].force - c.mass * m.gravity_A).norm(), 0.0, 1e-4 * c.mass * kG);
    // ... and the torque of the centre of mass, tilted by the torsional spring.
    const double h = std::hypot(c.com_G.x(), c.com_G.y());
    const double theta = held_pendulum_tilt(c.gains.k_rot, c.mass, h, c.com_G.z());
    const double torque = c.mass * kG * (h * std::cos(theta) + c.com_G.z() * std::sin(theta));
    const Eigen::Vector3d axis = Eigen::Vector3d(c.com_G.x(), c.com_G.y(), 0).cross(-Eigen::Vector3d::UnitZ()).normalized();
    EXPECT_NEAR((out.on_hand[0].torque - torque * axis).norm(), 0.0, 2e-3 * torque + 1e-6);
    EXPECT_NEAR(Eigen::AngleAxisd(d.T_A_O.linear()).angle(), theta, 1e-4);
    // The linear spring at G sags by m g / K.
    const Eigen::Vector3d sag = d.T_A_O.translation() - P;  // T_O_G = identity: G's point is O's origin
    EXPECT_NEAR(sag.z(), -c.mass * kG / c.gains.k_lin, 1e-7);
    std::printf("m %.2f kg: force %.4f N (m g %.4f), torque %.5f N m (closed form %.5f, tilt %.4f rad)\n", c.mass,
                out.on_hand[0].force.norm(), c.mass * kG, out.on_hand[0].torque.norm(), torque, theta);
  }
}

// Two hands at x = -a and +b from the centre of mass (grasp line through it,
// horizontal), springs K and K_r: the small-displacement statics (sag delta,
// tilt theta about y) of the two springs and the two torsional springs give
// each hand's share; with K_r = 0 it is the lever rule m g b / (a + b).
void held_two_hand_shares(double m, double a, double b, double k, double kr, double* f0, double* f1) {
  // -K(delta + theta a) - K(delta - theta b) = m g
  // -a K (delta + theta a) + b K (delta - theta b) - 2 K_r theta = 0
  Eigen::Matrix2d A;
  A << -2 * k, -k * (a - b), -k * (a - b), -k * (a * a + b * b) - 2 * kr;
  const Eigen::Vector2d x = A.lu().solve(Eigen::Vector2d(m * kG, 0));
  *f0 = -k * (x(0) + x(1) * a);
  *f1 = -k * (x(0) - x(1) * b);
}

TEST(HeldObject, TwoHandsShareTheWeightByStatics) {
  struct Case {
    double mass, a, b, k, kr;
  };
  const Case cases[] = {
      {2.0, 0.15, 0.15, 2000, 20},  // the box, symmetric: m g / 2 each
      {2.0, 0.10, 0.20, 2000, 20},  // centre of mass nearer hand 0
      {0.7, 0.25, 0.05, 3000, 5},   // a bar held near one end
      {1.2, 0.12, 0.18, 2500, 0},   // no torsional springs: the lever rule
  };
  for (const Case& c : cases) {
    const HeldObjectModel m = held_box(c.mass, {c.a + c.b, 0.1, 0.1}, Eigen::Vector3d::Zero(),
                                       held_gains(c.k, 40, c.kr, 0.5));
    HeldObjectData d;
    const Eigen::Vector3d centre(0.6, 0.0, 1.0);
    std::array<HeldHandInput, 2> hands{held_hand(centre - Eigen::Vector3d(c.a, 0, 0)),
                                       held_hand(centre + Eigen::Vector3d(c.b, 0, 0))};
    ASSERT_EQ(grasp(m, &d, 0, hands[0], held_pose({-c.a, 0, 0})), HeldStatus::kOk);
    ASSERT_EQ(grasp(m, &d, 1, hands[1], grasp_frame_here(d, hands[1].T_A_G)), HeldStatus::kOk);
    const HeldObjectOutput out = held_run(m, &d, hands, 8000);
    double f0 = 0, f1 = 0;
    held_two_hand_shares(c.mass, c.a, c.b, c.k, c.kr, &f0, &f1);
    std::printf("m %.2f a %.2f b %.2f K_r %.0f: hand 0 %.4f N (closed form %.4f, lever %.4f), hand 1 %.4f N (%.4f), "
                "squeeze %.2e N\n",
                c.mass, c.a, c.b, c.kr, -out.on_hand[0].force.z(), f0, c.mass * kG * c.b / (c.a + c.b),
                -out.on_hand[1].force.z(), f1, out.squeeze_n);
    EXPECT_NEAR(-(out.on_hand[0].force + out.on_hand[1].force).z(), c.mass * kG, 1e-6 * c.mass * kG);
    // Small-displacement statics: exact to first order in the tilt.
    EXPECT_NEAR(-out.on_hand[0].force.z(), f0, 2e-3 * c.mass * kG);
    EXPECT_NEAR(-out.on_hand[1].force.z(), f1, 2e-3 * c.mass * kG);
    if (c.a == c.b) {
      EXPECT_NEAR(-out.on_hand[0].force.z(), c.mass * kG / 2, 1e-6 * c.mass * kG);
    }
    EXPECT_NEAR(out.squeeze_n, 0.0, 1e-3 * c.mass * kG);
  }
}

TEST(HeldObject, SqueezeIsTheSeriesStiffnessTimesTheSeparationChange) {
  struct Case {
    double mass, k, delta;  // delta > 0: hands 'delta' closer together
  };
  const Case cases[] = {{2.0, 2000, 0.01}, {2.0, 2000, -0.006}, {0.5, 4500, 0.004}, {1.3, 1200, 0.02}};
  for (const Case& c : cases) {
    const HeldObjectModel m = held_box(c.mass, {0.3, 0.2, 0.15}, Eigen::Vector3d::Zero(),
                                       held_gains(c.k, 40, 20, 0.5));
    HeldObjectData d;
    const Eigen::Vector3d centre(0.5, 0.1, 1.1);
    const Eigen::Vector3d u = Eigen::Vector3d(1, 1, 0.2).normalized();  // a grasp line not along an axis
    std::array<HeldHandInput, 2> hands{held_hand(centre - 0.15 * u), held_hand(centre + 0.15 * u)};
    // O at the centre, axes along A's: the grasp frames at -+0.15 u.
    ASSERT_EQ(grasp(m, &d, 0, hands[0], held_pose(-0.15 * u)), HeldStatus::kOk);
    ASSERT_EQ(grasp(m, &d, 1, hands[1], held_pose(0.15 * u)), HeldStatus::kOk);
    // Move the hands together by delta over 0.5 s (each delta/2), then settle.
    HeldObjectOutput out;
    for (int i = 0; i < 6000; ++i) {
      const double s = std::min(1.0, i / 500.0) * 0.5 * c.delta;
      hands[0].T_A_G.translation() = centre - (0.15 - s) * u;
      hands[1].T_A_G.translation() = centre + (0.15 - s) * u;
      ASSERT_EQ(step_held_object(m, &d, hands, nullptr, &out), HeldStatus::kOk);
    }
    const double expected = 0.5 * c.k * c.delta;  // two springs K in series: K / 2
    std::printf("K %.0f, closer by %+.1f mm: squeeze %.4f N (K/2 delta = %.4f N)\n", c.k, 1e3 * c.delta,
                out.squeeze_n, expected);
    EXPECT_NEAR(out.squeeze_n, expected, 2e-3 * std::abs(expected) + 1e-3);
    EXPECT_NEAR(out.grasp_line_A.dot(u), 1.0, 1e-6);
  }
}

TEST(HeldObject, AnAcceleratingHandFeelsMassTimesAcceleration) {
  struct Case {
    double mass;
    Eigen::Vector3d a;
    HeldCouplingGains gains;
  };
  const Case cases[] = {
      {2.0, {2.0, 0, 0}, held_gains(2000, 40, 20, 0.5)},
      {0.3, {0, -4.0, 1.0}, held_gains(4000, 15, 10, 0.1)},
      {1.1, {-1.0, 1.5, 0}, held_gains(1500, 25, 30, 0.4)},
  };
  for (const Case& c : cases) {
    const HeldObjectModel m = held_box(c.mass, {0.1, 0.1, 0.1}, Eigen::Vector3d::Zero(), c.gains);
    HeldObjectData d;
    const Eigen::Vector3d P0(0.5, 0, 1.0);
    std::array<HeldHandInput, 2> hands{held_hand(P0), HeldHandInput{}};
    ASSERT_EQ(grasp(m, &d, 0, hands[0], Eigen::Isometry3d::Identity()), HeldStatus::kOk);
    held_run(m, &d, hands, 1500);
    HeldObjectOutput out;
    for (int i = 1; i <= 800; ++i) {
      const double t = i * m.dt;
      hands[0].T_A_G.translation() = P0 + 0.5 * c.a * t * t;
      hands[0].v_A = c.a * t;
      ASSERT_EQ(step_held_object(m, &d, hands, nullptr, &out), HeldStatus::kOk);
    }
    const Eigen::Vector3d expected = c.mass * (m.gravity_A - c.a);  // the hand feels -m (a - g)
    std::printf("m %.2f kg, a %.2f m/s^2: felt %.4f N (m a = %.4f N)\n", c.mass, c.a.norm(),
                (out.on_hand[0].force - c.mass * m.gravity_A).norm(), c.mass * c.a.norm());
    EXPECT_NEAR((out.on_hand[0].force - expected).norm(), 0.0, 0.02 * c.mass * c.a.norm());
  }
}

// Rotation vector of R1 R0^T.
Eigen::Vector3d held_rotvec(const Eigen::Matrix3d& R1, const Eigen::Matrix3d& R0) {
  const Eigen::AngleAxisd aa(R1 * R0.transpose());
  return aa.angle() * aa.axis();
}

struct HeldEnergyRun {
  double worst_excess = -1e9;  // max over ticks of E - E0 - W (J)
  double through = 0.0;        // sum |dW| (J)
};

// Two hands move the box for 5 s (sinusoids in position and z-y-x angles);
// W is the work the hands put into the couplings (trapezoid rule: exact for a
// spring). Backward Euler dissipates, so E - E0 - W stays at or below zero up
// to the work rule's discretization, which shrinks with dt; an active coupling
// (an explicit spring beyond its bound, a damper of the wrong sign) would gain
// energy in proportion to time instead.
HeldEnergyRun held_energy_run(const HeldCouplingGains& g, double dt) {
  HeldObjectModel m = held_box(2.0, {0.3, 0.2, 0.15}, Eigen::Vector3d(0.02, -0.01, 0.03), g);
  m.dt = dt;
  HeldObjectData d;
  const Eigen::Vector3d c0(0.5, 0, 1.0);
  std::array<HeldHandInput, 2> hands{held_hand(c0 - Eigen::Vector3d(0.15, 0, 0)),
                                     held_hand(c0 + Eigen::Vector3d(0.15, 0, 0))};
  EXPECT_EQ(grasp(m, &d, 0, hands[0], held_pose({-0.15, 0, 0})), HeldStatus::kOk);
  EXPECT_EQ(grasp(m, &d, 1, hands[1], held_pose({0.15, 0, 0})), HeldStatus::kOk);
  held_run(m, &d, hands, static_cast<int>(0.3 / dt));  // weights ramped in
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  Eigen::Matrix<double, 12, 3> wave;  // per hand: 3 translation + 3 rotation axes x (amplitude, freq, phase)
  for (int r = 0; r < 12; ++r) wave.row(r) << 0.03 * (1 + U(rng)), 1.5 + 2 * (1 + U(rng)), 3 * U(rng);
  const std::array<HeldHandInput, 2> start = hands;
  auto hand_at = [&](int h, double t) {
    HeldHandInput in = start[static_cast<std::size_t>(h)];
    // Translation: three sinusoids; rotation: z-y-x angles (a, b, c), whose
    // angular velocity is exactly a' z + b' Rz y + c' Rz Ry x.
    Eigen::Vector3d dp, vp, ang, rate;
    for (int k = 0; k < 3; ++k) {
      const auto row = wave.row(6 * h + k), rrow = wave.row(6 * h + 3 + k);
      const double w = 2 * std::numbers::pi * row(1), wr = 2 * std::numbers::pi * rrow(1);
      // From where the hand is at t = 0 (no jump at the start).
      dp[k] = row(0) * (std::sin(w * t + row(2)) - std::sin(row(2)));
      vp[k] = row(0) * w * std::cos(w * t + row(2));
      ang[k] = 5 * rrow(0) * (std::sin(wr * t + rrow(2)) - std::sin(rrow(2)));
      rate[k] = 5 * rrow(0) * wr * std::cos(wr * t + rrow(2));
    }
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(ang[0], Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d Ry = Eigen::AngleAxisd(ang[1], Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d Rx = Eigen::AngleAxisd(ang[2], Eigen::Vector3d::UnitX()).toRotationMatrix();
    in.T_A_G.translation() += dp;
    in.T_A_G.linear() = Rz * Ry * Rx * in.T_A_G.linear();
    in.v_A = vp;
    in.omega_A = rate[0] * Eigen::Vector3d::UnitZ() + rate[1] * (Rz * Eigen::Vector3d::UnitY()) +
                 rate[2] * (Rz * Ry * Eigen::Vector3d::UnitX());
    return in;
  };
  HeldEnergyRun run;
  HeldObjectOutput prev = held_run(m, &d, hands, 1), out;
  const double e0 = held_stored_energy(m, d, hands);
  std::array<HeldHandInput, 2> last = hands;
  double work = 0.0;
  const int ticks = static_cast<int>(5.0 / dt);
  for (int i = 1; i <= ticks; ++i) {
    for (int h = 0; h < 2; ++h) hands[static_cast<std::size_t>(h)] = hand_at(h, i * dt);
    EXPECT_EQ(step_held_object(m, &d, hands, nullptr, &out), HeldStatus::kOk);
    for (std::size_t k = 0; k < 2; ++k) {
      const Eigen::Vector3d dP = hands[k].T_A_G.translation() - last[k].T_A_G.translation();
      const Eigen::Vector3d dth = held_rotvec(hands[k].T_A_G.linear(), last[k].T_A_G.linear());
      const double dw = 0.5 * (prev.on_object[k].force + out.on_object[k].force).dot(dP) +
                        0.5 * (prev.on_object[k].torque + out.on_object[k].torque).dot(dth);
      work += dw;
      run.through += std::abs(dw);
    }
    last = hands;
    prev = out;
    run.worst_excess = std::max(run.worst_excess, held_stored_energy(m, d, hands) - e0 - work);
  }
  return run;
}

TEST(HeldObject, StoredEnergyNeverExceedsTheWorkTheHandsPutIn) {
  // Gains as the virtual coupling's design gives them for an LWR-class arm
  // (weak coupling damping, drag to A), and gains of our own.
  const vps::CouplingDesign dev =
      vps::design_coupling(2.0, solid_box_inertia(2.0, {0.3, 0.2, 0.15}), vps::test::lwr_like());
  const HeldCouplingGains sets[] = {gains_from_coupling(dev.params), held_gains(2000, 40, 20, 0.5),
                                    held_gains(5000, 2, 50, 0.05), held_gains(1500, 0, 10, 0)};
  for (const HeldCouplingGains& g : sets) {
    const HeldEnergyRun coarse = held_energy_run(g, 1e-3), fine = held_energy_run(g, 0.5e-3);
    std::printf("K %.0f B %.2f c %.1f K_r %.0f: worst (E - E0 - W) %.3e J at 1 kHz, %.3e J at 2 kHz; |W| %.1f J\n",
                g.k_lin, g.b_lin, g.linear_damping, g.k_rot, coarse.worst_excess, fine.worst_excess, coarse.through);
    EXPECT_LE(coarse.worst_excess, 1e-6 * coarse.through);
    EXPECT_LE(fine.worst_excess, 1e-6 * fine.through);
    // It is discretization: it shrinks with dt (an active coupling's would not).
    EXPECT_LE(fine.worst_excess, 0.7 * std::max(coarse.worst_excess, 1e-6) + 1e-6);
  }
}

TEST(HeldObject, AFreeSwingNeverGainsEnergy) {
  // No coupling damping: only backward Euler's own dissipation. The thin
  // bar's K_r / I_min puts omega dt at 3.2 (an explicit spring diverges above 2).
  struct Case {
    const char* name;
    double mass;
    Eigen::Vector3d size, com;
    HeldCouplingGains gains;
  };
  const Case cases[] = {
      {"box, offset centre of mass", 2.0, {0.3, 0.2, 0.15}, {0.05, 0.02, -0.03}, held_gains(3000, 0, 30, 0)},
      {"thin bar", 0.3, {0.4, 0.0063, 0.0063}, {0.1, 0, 0}, held_gains(5000, 0, 20, 0)},
  };
  for (const Case& c : cases) {
    const HeldObjectModel m = held_box(c.mass, c.size, c.com, c.gains);
    const double i_min = m.body.inertia_com.diagonal().minCoeff();
    HeldObjectData d;
    const std::array<HeldHandInput, 2> hands{held_hand({0.5, 0, 1.0}), HeldHandInput{}};
    ASSERT_EQ(grasp(m, &d, 0, hands[0], Eigen::Isometry3d::Identity()), HeldStatus::kOk);
    held_run(m, &d, hands, 200);  // weight ramped in
    d.v_A = Eigen::Vector3d(0.3, -0.2, 0.4);
    d.omega_A = Eigen::Vector3d(2.0, -1.0, 3.0);
    double e_prev = held_stored_energy(m, d, hands);
    const double e_start = e_prev;
    double worst = -1e9;
    HeldObjectOutput out;
    for (int i = 0; i < 5000; ++i) {
      ASSERT_EQ(step_held_object(m, &d, hands, nullptr, &out), HeldStatus::kOk);
      const double e = held_stored_energy(m, d, hands);
      worst = std::max(worst, e - e_prev);
      e_prev = e;
      ASSERT_TRUE(d.T_A_O.matrix().allFinite());
    }
    std::printf("%s: omega_rot dt %.2f, energy %.4f -> %.4f J, largest rise per tick %.2e J\n", c.name,
                std::sqrt(c.gains.k_rot / i_min) * m.dt, e_start, e_prev, worst);
    EXPECT_LE(e_prev, e_start);
    EXPECT_LE(worst, 1e-6 * e_start);
  }
}

// Hand 1 picks the object up (its weight ramps in), hand 0 joins, hand 1
// lets go, then hand 0 puts it down. Returns the largest change of either
// hand's force over one tick; checks the end states.
double held_handover_worst_step(const HeldObjectModel& m) {
  HeldObjectData d;
  const Eigen::Vector3d c0(0.5, 0, 1.0);
  const std::array<HeldHandInput, 2> hands{held_hand(c0 - Eigen::Vector3d(0.15, 0, 0)),
                                           held_hand(c0 + Eigen::Vector3d(0.15, 0, 0))};
  HeldObjectOutput out, prev;
  double worst_step = 0.0;
  auto track = [&](int ticks) {
    for (int i = 0; i < ticks; ++i) {
      const HeldStatus s = step_held_object(m, &d, hands, nullptr, &out);
      EXPECT_TRUE(s == HeldStatus::kOk || (s == HeldStatus::kNotHeld && !held(d)));
      for (std::size_t h = 0; h < 2; ++h) {
        worst_step = std::max(worst_step, (out.on_hand[h].force - prev.on_hand[h].force).norm());
      }
      prev = out;
    }
  };
  EXPECT_EQ(grasp(m, &d, 1, hands[1], held_pose({0.15, 0, 0})), HeldStatus::kOk);
  track(3000);
  EXPECT_EQ(grasp(m, &d, 0, hands[0], grasp_frame_here(d, hands[0].T_A_G)), HeldStatus::kOk);
  track(3000);
  EXPECT_EQ(release(&d, 1), HeldStatus::kOk);
  track(4000);
  EXPECT_FALSE(d.hand[1].attached);
  EXPECT_EQ(out.on_hand[1].force.norm(), 0.0);
  EXPECT_NEAR((out.on_hand[0].force - m.body.mass * m.gravity_A).norm(), 0.0, 1e-3 * m.body.mass * kG);
  EXPECT_EQ(release(&d, 0), HeldStatus::kOk);
  track(1000);
  EXPECT_FALSE(held(d));
  EXPECT_EQ(out.on_hand[0].force.norm(), 0.0);
  return worst_step;
}

TEST(HeldObject, ReleaseHandsTheObjectToTheOtherHandWithoutAForceStep) {
  const vps::CouplingDesign dev =
      vps::design_coupling(0.8, solid_box_inertia(0.8, {0.3, 0.2, 0.15}), vps::test::lwr_like());
  struct Case {
    double mass;
    HeldCouplingGains gains;
  };
  const Case cases[] = {{2.0, held_gains(2000, 40, 20, 0.5)}, {0.8, gains_from_coupling(dev.params)}};
  for (const Case& c : cases) {
    HeldObjectModel m = held_box(c.mass, {0.3, 0.2, 0.15}, Eigen::Vector3d(0.03, 0, 0), c.gains);
    const double ramped = held_handover_worst_step(m);
    m.grip_ramp_s = m.dt;  // no ramp: grasp and release in one tick
    const double instant = held_handover_worst_step(m);
    std::printf("m %.1f kg, K %.0f K_r %.0f: largest force change per tick %.4f N with a %.2f s ramp, %.3f N "
                "without (m g / 2 = %.2f N)\n",
                c.mass, c.gains.k_lin, c.gains.k_rot, ramped, HeldObjectModel{}.grip_ramp_s, instant,
                0.5 * c.mass * kG);
    // Without the ramp the hands feel the load step (about m g / 2 at the
    // first grasp, m g); with it, every tick's change stays within 5 % of that.
    EXPECT_GT(instant, 0.4 * c.mass * kG);
    EXPECT_LE(ramped, 0.05 * instant);
  }
}

TEST(HeldObject, BadInputIsRefusedAndChangesNothing) {
  const HeldObjectModel m = held_box(1.0, {0.1, 0.1, 0.1}, Eigen::Vector3d::Zero(), held_gains(2000, 40, 20, 0.5));
  HeldObjectData d;
  std::array<HeldHandInput, 2> hands{held_hand({0.5, 0, 1}), held_hand({0.6, 0, 1})};
  ASSERT_EQ(grasp(m, &d, 0, hands[0], Eigen::Isometry3d::Identity()), HeldStatus::kOk);
  held_run(m, &d, hands, 100);
  const HeldObjectData before = d;
  auto unchanged = [&] {
    EXPECT_TRUE(d.T_A_O.isApprox(before.T_A_O, 0.0));
    EXPECT_EQ(d.v_A, before.v_A);
    EXPECT_EQ(d.omega_A, before.omega_A);
    EXPECT_EQ(d.ticks, before.ticks);
    EXPECT_EQ(d.hand[0].weight, before.hand[0].weight);
    EXPECT_EQ(d.hand[1].attached, before.hand[1].attached);
  };
  HeldObjectOutput out;
  std::array<HeldHandInput, 2> bad = hands;
  bad[0].T_A_G.translation().x() = std::nan("");
  EXPECT_EQ(step_held_object(m, &d, bad, nullptr, &out), HeldStatus::kNonFinite);
  unchanged();
  bad = hands;
  bad[0].omega_A.z() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(step_held_object(m, &d, bad, nullptr, &out), HeldStatus::kNonFinite);
  unchanged();
  bad = hands;
  bad[0].T_A_G.linear() *= 1.5;
  EXPECT_EQ(step_held_object(m, &d, bad, nullptr, &out), HeldStatus::kNotRotation);
  unchanged();
  vps::Wrench nan_contact;
  nan_contact.torque.y() = std::nan("");
  EXPECT_EQ(step_held_object(m, &d, hands, &nan_contact, &out), HeldStatus::kNonFinite);
  unchanged();
  EXPECT_EQ(grasp(m, &d, 2, hands[1], Eigen::Isometry3d::Identity()), HeldStatus::kBadHand);
  EXPECT_EQ(grasp(m, &d, 0, hands[0], Eigen::Isometry3d::Identity()), HeldStatus::kAlreadyHeld);
  bad = hands;
  bad[1].v_A.x() = std::nan("");
  EXPECT_EQ(grasp(m, &d, 1, bad[1], Eigen::Isometry3d::Identity()), HeldStatus::kNonFinite);
  EXPECT_EQ(release(&d, 1), HeldStatus::kNotHeld);
  EXPECT_EQ(release(&d, -1), HeldStatus::kBadHand);
  unchanged();
  // A hand not attached may carry garbage: it is not read.
  bad = hands;
  bad[1].T_A_G.translation().x() = std::nan("");
  EXPECT_EQ(step_held_object(m, &d, bad, nullptr, &out), HeldStatus::kOk);

  // Models.
  auto refused = [&](auto edit, const char* what) {
    HeldObjectModel b = m;
    edit(b);
    const auto err = validate(b);
    ASSERT_TRUE(err.has_value()) << what;
    EXPECT_NE(err->find(what), std::string::npos) << *err;
  };
  refused([](HeldObjectModel& b) { b.body.mass = 0; }, "mass");
  refused([](HeldObjectModel& b) { b.body.mass = std::nan(""); }, "mass");
  refused([](HeldObjectModel& b) { b.body.centre_of_mass.x() = INFINITY; }, "centre of mass");
  refused([](HeldObjectModel& b) { b.body.inertia_com(0, 1) = 0.5; }, "symmetric");
  refused([](HeldObjectModel& b) { b.body.inertia_com(2, 2) = -1; }, "positive definite");
  refused([](HeldObjectModel& b) { b.gains.b_rot = -1; }, "gains");
  refused([](HeldObjectModel& b) { b.gains.k_lin = 0; }, "k_lin");
  refused([](HeldObjectModel& b) { b.dt = 0; }, "dt");
  refused([](HeldObjectModel& b) { b.grip_ramp_s = 0; }, "grip_ramp_s");
}

TEST(HeldObject, AServoTickAllocatesNothing) {
  const HeldObjectModel m = held_box(2.0, {0.3, 0.2, 0.15}, Eigen::Vector3d(0.01, 0, 0), held_gains(2000, 40, 20, 0.5));
  HeldObjectData d;
  std::array<HeldHandInput, 2> hands{held_hand({0.35, 0, 1}), held_hand({0.65, 0, 1})};
  ASSERT_EQ(grasp(m, &d, 0, hands[0], held_pose({-0.15, 0, 0})), HeldStatus::kOk);
  ASSERT_EQ(grasp(m, &d, 1, hands[1], held_pose({0.15, 0, 0})), HeldStatus::kOk);
  HeldObjectOutput out;
  vps::Wrench contact;
  contact.force = Eigen::Vector3d(0, 0, 3);
  test::count_allocations_on_this_thread(true);
  const auto before = test::counted_allocations();
  for (int i = 0; i < 2000; ++i) {
    hands[0].T_A_G.translation().z() = 1.0 + 0.01 * std::sin(i * 1e-2);
    step_held_object(m, &d, hands, i % 2 ? &contact : nullptr, &out);
    if (i == 1000) release(&d, 1);
  }
  const auto after = test::counted_allocations();
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
}

}  // namespace
}  // namespace hemm::haptics
