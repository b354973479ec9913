// The arms' controllers: Eq. 1-4 and the dynamically consistent projector
// (identities, the singular configuration), and closed loop on the
// SIMULATED plant: the elbow pushed by F_d = 20 N while the hand holds still
// (both projectors in one table), the inertia the hand feels without and
// with feed-forward (identified from the hand's wrench on the handle and the
// handle's motion under a known sinusoidal push), stability over hand
// stiffness and damping, and the limits the device enforces.
#include "operator/device/bimanual/arm_control.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "operator/device/bimanual/simulation.h"
#include "tests/sanitizer_build.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;
using Eigen::Vector3d;
using M6 = Eigen::Matrix<double, 6, 6>;
using V6 = Eigen::Matrix<double, 6, 1>;

namespace {

hk::Arm7Vector random_q(const hk::Arm7Model& m, std::mt19937_64& rng) {
  hk::Arm7Vector q;
  for (int i = 0; i < 7; ++i) q(i) = std::uniform_real_distribution<double>(m.q_min(i), m.q_max(i))(rng);
  return q;
}

hb::SimulationConfig ideal_config() {
  hb::SimulationConfig c;
  c.plant.actuators = hb::ideal_actuators(c.plant.rig.arm);
  c.plant.model_error = hb::ModelError{0, 0, 0, 1};
  return c;
}

}  // namespace

// ------------------------------------------------------------ Eq. 1-4

TEST(NullSpace, Eq1To4IsTheKinematicProjectionAndLeavesNoStaticEndEffectorForce) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  std::mt19937_64 rng(41);
  for (int k = 0; k < 200; ++k) {
    const hk::Arm7Vector q = random_q(m, rng);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, q, f);
    const hk::Arm7Jacobian J4 = hk::elbow_jacobian(m, f), J7 = hk::flange_jacobian(m, f);
    hk::Wrench6 F_d = hk::Wrench6::Zero();
    F_d.head<3>() = 20.0 * Vector3d(std::uniform_real_distribution<double>(-1, 1)(rng), 1.0, 0.3).normalized();
    const hb::NullSpaceTorques ns = hb::null_space_eq1_4(J4, J7, F_d);
    EXPECT_TRUE(ns.T_d.tail<3>().isZero(0.0));  // [T_d; 0]
    EXPECT_LT((ns.T - hb::kinematic_null_projector(J7) * ns.T_d).norm(), 1e-9);
    // F_E of Eq. 2 is the least-squares flange wrench of T_d...
    EXPECT_LT((J7.transpose() * ns.F_E + ns.T_comp).norm(), 1e-12);
    // ...so what is left has no static effect at the flange: J7 T = 0 is
    // not required, but (J7^T)^+ T = 0 is.
    const Eigen::Matrix<double, 6, 7> pinv = J7.transpose().completeOrthogonalDecomposition().pseudoInverse();
    EXPECT_LT((pinv * ns.T).norm(), 1e-9 * std::max(1.0, ns.T_d.norm()));
    // The dynamically consistent projector: no flange acceleration.
    const hk::Arm7Matrix M = hk::mass_matrix(m, f);
    const hk::Arm7Vector Td = hb::dynamic_null_projector(J7, M) * ns.T_d;
    EXPECT_LT((J7 * M.ldlt().solve(Td)).norm(), 1e-9 * std::max(1.0, ns.T_d.norm()));
  }
}

TEST(NullSpace, TVanishesAtTheStretchedElbowSingularity) {
  // With the elbow straight (q4 = 0) the elbow lies on the shoulder-wrist
  // line: the self-motion cannot move it. A force along the arm plane's
  // normal (joint 4's axis, the direction the elbow swivels in) gives a
  // non-zero T_d but T = 0; T grows again as the elbow bends.
  const hk::Arm7Model m = hk::lwr_arm_model();
  std::mt19937_64 rng(42);
  for (int k = 0; k < 50; ++k) {
    hk::Arm7Vector q = random_q(m, rng);
    q(1) = std::copysign(std::max(0.3, std::abs(q(1))), q(1));  // away from the shoulder singularity
    q(5) = std::copysign(std::max(0.3, std::abs(q(5))), q(5));  // and the wrist's
    double prev = 0.0;
    for (double q4 : {0.0, 0.01, 0.1, 0.3}) {
      q(3) = q4;
      hk::Arm7Frames f;
      hk::forward_kinematics(m, q, f);
      hk::Wrench6 F_d = hk::Wrench6::Zero();
      F_d.head<3>() = 20.0 * f.axis_A(m, 4);
      const hb::NullSpaceTorques ns = hb::null_space_eq1_4(hk::elbow_jacobian(m, f), hk::flange_jacobian(m, f), F_d);
      EXPECT_GT(ns.T_d.norm(), 1.0);
      if (q4 == 0.0) {
        EXPECT_LT(ns.T.norm(), 1e-9 * ns.T_d.norm()) << "T must vanish at the singularity";
      } else {
        EXPECT_GT(ns.T.norm(), prev) << "q4 " << q4;
      }
      prev = ns.T.norm();
    }
  }
}

// ------------------------------------------------------------ closed loop: null space

namespace {

struct NullSpaceRun {
  double static_max = 0.0;   // |(J_E^T)^+ tau_null| [N]: on a static end-effector
  double moving_rms = 0.0;   // measured at the hand [N]
  double moving_max = 0.0;
  double elbow_along = 0.0;  // elbow displacement along F_d [m]
  double elbow_speed_max = 0.0;
};

NullSpaceRun run_null_space(hb::SimulationConfig c, hb::NullSpaceProjector proj) {
  for (auto& p : c.control) {
    p.projector = proj;
    p.elbow_force = 0.0;
  }
  hb::BimanualSimulation s(c);
  const auto hold = s.resting_targets();
  for (int k = 0; k < 300; ++k) s.step(hold);
  const Vector3d F0 = s.truth().hands[0].grasp_force_D, e0 = s.output(hb::ArmSide::kRight).elbow_D;
  const hb::RigGeometry& rig = c.plant.rig;
  NullSpaceRun r;
  double sum2 = 0.0;
  const int n = 2500;
  Vector3d e_prev = e0;
  for (int k = 0; k < n; ++k) {
    const double fd = 20.0 * std::min(1.0, k / 300.0);  // ramped over 0.3 s
    s.controller().params(hb::ArmSide::kRight).elbow_force = fd;
    s.controller().params(hb::ArmSide::kLeft).elbow_force = fd;
    const hk::Arm7Vector q_ctl = s.reading(hb::ArmSide::kRight).q;  // what the controller sees this tick
    s.step(hold);
    const hb::ArmOutput& o = s.output(hb::ArmSide::kRight);
    // The static end-effector wrench of the null torques (nominal model).
    hk::Arm7Frames f;
    hk::forward_kinematics(s.controller().nominal(hb::ArmSide::kRight), q_ctl, f);
    const Vector3d p_E_A = rig.T_D_A[0].inverse() * o.T_D_E.translation();
    const hk::Arm7Jacobian J = hk::partial_jacobian(s.controller().nominal(hb::ArmSide::kRight), f, 7, p_E_A);
    const V6 F_static = J.transpose().completeOrthogonalDecomposition().pseudoInverse() * o.tau_null;
    r.static_max = std::max(r.static_max, F_static.head<3>().norm());
    const double dF = (s.truth().hands[0].grasp_force_D - F0).norm();
    sum2 += dF * dF;
    r.moving_max = std::max(r.moving_max, dF);
    r.elbow_speed_max = std::max(r.elbow_speed_max, (o.elbow_D - e_prev).norm() / 0.001);
    e_prev = o.elbow_D;
  }
  r.moving_rms = std::sqrt(sum2 / n);
  r.elbow_along = (s.output(hb::ArmSide::kRight).elbow_D - e0).dot(Vector3d(0, -1, 0));  // right elbow: -y
  return r;
}

}  // namespace

TEST(NullSpace, ElbowMovesAlongFdWhileTheHandHoldsStillBothProjectors) {
  // The right hand holds the handle still (its target fixed); F_d = 20 N
  // pushes the right elbow to the right (-y of D).
  struct Row {
    const char* name;
    hb::SimulationConfig cfg;
  };
  hb::SimulationConfig friction = ideal_config();
  friction.plant.actuators = hb::lwr_actuators(friction.plant.rig.arm);
  hb::SimulationConfig all;  // friction, ripple and the nominal model off by a few per cent
  // The sanitizer pass: the ideal plant with both projectors (tests/sanitizer_build.h).
  const std::vector<Row> rows = hemm::test::sanitizer_cases<Row>(
      {{"ideal actuators", ideal_config()}, {"friction + ripple", friction}, {"+ model error", all}}, {0});
  std::printf("\nnull space, F_d = 20 N at the right elbow, the hand holding still (|F| at the hand, N):\n");
  std::printf("%-10s %-18s %14s %12s %12s %14s %12s\n", "projector", "plant", "static |F_E|", "moving rms", "moving max",
              "elbow along F_d", "elbow speed");
  for (hb::NullSpaceProjector proj : {hb::NullSpaceProjector::kKinematic, hb::NullSpaceProjector::kDynamic}) {
    for (const Row& row : rows) {
      const NullSpaceRun r = run_null_space(row.cfg, proj);
      std::printf("%-10s %-18s %14.2e %12.3f %12.3f %12.3f m %9.3f m/s\n", hb::to_string(proj), row.name, r.static_max,
                  r.moving_rms, r.moving_max, r.elbow_along, r.elbow_speed_max);
      EXPECT_GT(r.elbow_along, 0.01) << row.name;  // the elbow goes the way F_d pushes
      if (proj == hb::NullSpaceProjector::kKinematic) {
        EXPECT_LT(r.static_max, 1e-6);  // Eq. 2-4
      }
      if (&row == &rows[0]) {
        EXPECT_GT(r.elbow_along, 0.03);
        EXPECT_LT(r.moving_max, proj == hb::NullSpaceProjector::kDynamic ? 0.1 : 2.0);
      } else {
        EXPECT_LT(r.moving_max, 5.0);  // "slightly perceivable"
      }
    }
  }
}

// ------------------------------------------------------------ closed loop: inertia

namespace {

// One run: the hand pushes along/about axis `ax` of D with a sinusoid of
// `hz` (1000 / hz an integer); the in-phase parts of the hand's wrench on
// the handle (at E) and of E's acceleration (from the joint sensors) over
// two whole periods, each channel detrended first (the arm drifts).
void sine_push(const hb::SimulationConfig& c, int ax, double amp, double hz, V6& W, V6& A) {
  hb::BimanualSimulation s(c);
  auto h = s.resting_targets();
  for (int k = 0; k < 100; ++k) s.step(h);
  const double om = 2 * std::numbers::pi * hz;
  const int n_ramp = static_cast<int>(std::lround(1000 / hz)), n_meas = 2 * n_ramp;
  const Eigen::Isometry3d E0 = s.output(hb::ArmSide::kRight).T_D_E;
  const Vector3d u = Vector3d::Unit(ax % 3);
  Eigen::Matrix<double, Eigen::Dynamic, 13> rows(n_meas, 13);  // x (6), w (6), cos
  for (int k = 0; k < n_ramp + n_meas; ++k) {
    const double t = (k + 1) * 0.001;
    const double env = k < n_ramp ? 0.5 * (1 - std::cos(std::numbers::pi * k / n_ramp)) : 1.0;
    const double f = env * amp * std::cos(om * t);
    (ax >= 3 ? h[0].push_torque_D : h[0].push_force_D) = f * u;
    s.step(h);
    if (k < n_ramp) continue;
    const hb::HandTruth& th = s.truth().hands[0];
    const Eigen::Isometry3d& E = s.output(hb::ArmSide::kRight).T_D_E;
    const Eigen::AngleAxisd aa(E.linear() * E0.linear().transpose());
    rows.row(k - n_ramp) << (E.translation() - E0.translation()).transpose(), (aa.angle() * aa.axis()).transpose(),
        -th.grasp_force_D.transpose(), -th.grasp_torque_D.transpose(), std::cos(om * t);  // hand on handle, at E
  }
  // Detrend (least-squares line), then correlate with the cosine.
  Eigen::MatrixXd B(n_meas, 2);
  for (int i = 0; i < n_meas; ++i) B.row(i) << 1.0, i;
  const Eigen::MatrixXd data = rows.leftCols<12>();
  const Eigen::MatrixXd detrended = data - B * B.colPivHouseholderQr().solve(data);
  const Eigen::Matrix<double, 12, 1> inphase = detrended.transpose() * rows.col(12) * (2.0 / n_meas);
  A = -om * om * inphase.head<6>();
  W = inphase.tail<6>();
}

// The 6x6 inertia the hand feels at E: wrench = Lambda acceleration, from six pushes.
M6 felt_inertia(const hb::SimulationConfig& c, double hz, double scale = 1.0) {
  M6 W, A;
  for (int ax = 0; ax < 6; ++ax) {
    V6 w, a;
    sine_push(c, ax, scale * (ax >= 3 ? 0.3 : 8.0), hz, w, a);
    W.col(ax) = w;
    A.col(ax) = a;
  }
  return W * A.inverse();
}

}  // namespace

TEST(FeedForward, FeltInertiaDropsTo33And25PerCent) {
  // The human's arm is relaxed (no stiffness or damping: only the known
  // push acts), the device renders no damping; the hand's push is a 4 Hz
  // sinusoid (8 N, 0.3 N m) so the arm stays at its posture. Apparent mass
  // along an axis = the force per unit acceleration when E accelerates
  // along that axis only (the diagonal of the identified 6x6 inertia).
  hb::SimulationConfig c = ideal_config();
  for (auto& h : c.plant.humans) h.arm_stiffness = h.arm_damping = h.arm_rot_stiffness = h.arm_rot_damping = 0.0;
  for (auto& p : c.control) {
    p.elbow_force = 0.0;
    p.cartesian_damping = p.cartesian_rot_damping = 0.0;
    p.projector = hb::NullSpaceProjector::kDynamic;  // its damping stays in the null space
    p.feedforward = false;
  }
  const M6 L0 = felt_inertia(c, 4.0);
  for (auto& p : c.control) p.feedforward = true;
  const M6 L1 = felt_inertia(c, 4.0);
  // The same without feed-forward from the plant's true model: the operational-
  // space inertia of arm + handle at E (checks the identification itself).
  hb::BimanualPlant plant(c.plant);
  const hk::Arm7Model truth =
      hk::with_payload(plant.true_arm(hb::ArmSide::kRight), plant.true_handle(hb::ArmSide::kRight).inertia_J7);
  hk::Arm7Frames f;
  hk::forward_kinematics(truth, c.plant.rig.home(hb::ArmSide::kRight), f);
  const Eigen::Isometry3d& T_D_A = c.plant.rig.T_D_A[0];
  const Eigen::Isometry3d T_D_E = T_D_A * f.joint(7) * plant.true_handle(hb::ArmSide::kRight).T_J7_E;
  hk::Arm7Jacobian J = hk::partial_jacobian(truth, f, 7, T_D_A.inverse() * T_D_E.translation());
  J.topRows<3>() = T_D_A.linear() * J.topRows<3>().eval();
  J.bottomRows<3>() = T_D_A.linear() * J.bottomRows<3>().eval();
  const M6 Lm = hb::operational_space_inertia(J, hk::mass_matrix(truth, f));
  const char* names[6] = {"x (kg)", "y (kg)", "z (kg)", "about x (kg m^2)", "about y (kg m^2)", "about z (kg m^2)"};
  std::printf("\ninertia felt at the right hand (ideal actuators), without -> with feed-forward:\n");
  for (int i = 0; i < 6; ++i) {
    const double ratio = L1(i, i) / L0(i, i);
    std::printf("  %-17s %8.4f -> %8.4f   ratio %.3f   (model, no feed-forward: %.4f)\n", names[i], L0(i, i), L1(i, i),
                ratio, Lm(i, i));
    EXPECT_NEAR(ratio, i < 3 ? 0.33 : 0.25, 0.03) << names[i];
    EXPECT_NEAR(L0(i, i), Lm(i, i), 0.1 * Lm(i, i)) << names[i];
  }
  // With the LWR-like friction and ripple the same identification (pushes
  // three times larger, so motion dominates stiction): reported only, as
  // friction is not inertia.
  hb::SimulationConfig r = c;
  r.plant.actuators = hb::lwr_actuators(r.plant.rig.arm);
  for (auto& p : r.control) p.feedforward = false;
  const M6 R0 = felt_inertia(r, 4.0, 3.0);
  for (auto& p : r.control) p.feedforward = true;
  const M6 R1 = felt_inertia(r, 4.0, 3.0);
  std::printf("with friction and ripple:\n");
  for (int i = 0; i < 6; ++i)
    std::printf("  %-17s %8.4f -> %8.4f   ratio %.3f\n", names[i], R0(i, i), R1(i, i), R1(i, i) / R0(i, i));
}

TEST(FeedForward, HandArmSystemStaysStableOverHandStiffnessAndDamping) {
  // A push (15 N for 0.1 s, with 0.3 N m) and release, feed-forward on,
  // LWR-like actuators: the end-effector's speed must die out, never grow.
  struct Hand {
    double k, b, grasp;
  };
  // The sanitizer pass (tests/sanitizer_build.h): the free hand, the stiffest
  // arm and the stiffest grasp, the same code as the rest of the sweep.
  const std::vector<Hand> hands = hemm::test::sanitizer_cases<Hand>(
      {{0, 0, 4000}, {0, 25, 4000}, {300, 5, 4000}, {300, 25, 4000}, {300, 100, 4000}, {1000, 25, 4000},
       {1000, 100, 4000}, {3000, 50, 4000}, {3000, 150, 4000}, {300, 25, 1500}, {300, 25, 10000}, {1000, 50, 10000}},
      {0, 8, 11});
  std::printf("\nstability with feed-forward (push 15 N + 0.3 N m for 0.1 s, then release):\n");
  std::printf("%10s %10s %10s %14s %14s\n", "k [N/m]", "b [N s/m]", "grasp [N/m]", "|v| 0.1-0.4 s", "|v| 1.2-1.5 s");
  for (const Hand& hd : hands) {
    hb::SimulationConfig c;
    for (auto& h : c.plant.humans) {
      h.arm_stiffness = hd.k;
      h.arm_damping = hd.b;
      h.grasp_stiffness = hd.grasp;
    }
    hb::BimanualSimulation s(c);
    auto h = s.resting_targets();
      double early = 0.0, late = 0.0;
    for (int k = 0; k < 1500; ++k) {
      const bool push = k >= 100 && k < 200;
      h[0].push_force_D = push ? Vector3d(10.0, 10.0, 5.0) : Vector3d::Zero();
      h[0].push_torque_D = push ? Vector3d(0.0, 0.0, 0.3) : Vector3d::Zero();
      s.step(h);
      const double v = s.output(hb::ArmSide::kRight).twist_E_D.head<3>().norm();
      ASSERT_TRUE(std::isfinite(v));
      if (k >= 200 && k < 500) early = std::max(early, v);
      if (k >= 1200) late = std::max(late, v);
    }
    std::printf("%10.0f %10.0f %10.0f %11.4f m/s %11.4f m/s\n", hd.k, hd.b, hd.grasp, early, late);
    EXPECT_TRUE(s.enabled(hb::ArmSide::kRight));
    EXPECT_GT(early, 0.01);        // the push moved it
    EXPECT_LT(late, 0.5 * early);  // and the motion dies out
  }
}

// ------------------------------------------------------------ limits

TEST(Limits, RendererWrenchIsCheckedClampedAndTorquesStayWithinTheDrives) {
  hb::BimanualSimulation s(hb::SimulationConfig{});
  const auto h = s.resting_targets();
  const hb::ArmControlParams& P = s.config().control[0];
  hk::Wrench6 nan = hk::Wrench6::Zero();
  nan(1) = NAN;
  s.step({nan, hk::Wrench6::Constant(1e6)}, {0.0, 0.0}, h);
  EXPECT_TRUE(s.output(hb::ArmSide::kRight).nonfinite_wrench);
  EXPECT_TRUE(s.output(hb::ArmSide::kRight).w_env_applied_D.isZero(0.0));
  EXPECT_TRUE(s.output(hb::ArmSide::kLeft).wrench_limited);
  EXPECT_NEAR(s.output(hb::ArmSide::kLeft).w_env_applied_D.head<3>().norm(), P.peak_force, 1e-9);
  EXPECT_NEAR(s.output(hb::ArmSide::kLeft).w_env_applied_D.tail<3>().norm(), P.peak_torque, 1e-9);
  for (int k = 0; k < 300; ++k) {
    s.step({hk::Wrench6::Constant(1e6), hk::Wrench6::Constant(-1e6)}, {0.0, 0.0}, h);
    for (hb::ArmSide a : {hb::ArmSide::kRight, hb::ArmSide::kLeft}) {
      const hk::Arm7Vector& tau = s.output(a).tau;
      ASSERT_TRUE(((tau.array().abs() <= s.controller().nominal(a).tau_max.array() + 1e-12)).all());
    }
  }
}

TEST(Limits, WorkspaceWallAndSpeedLimitHoldAgainstTheRenderer) {
  // The renderer pushes the right end-effector towards the column (+x) with
  // 60 N; the device's wall at the workspace box stops it.
  hb::SimulationConfig c;
  hb::BimanualSimulation s(c);
  auto h = s.resting_targets();
  h[0].grasp = false;  // no hand: only the renderer and the device
  const hb::ArmControlParams& P = c.control[0];
  hk::Wrench6 w = hk::Wrench6::Zero();
  w(0) = 60.0;
  double max_x = -1e9, max_speed = 0.0;
  for (int k = 0; k < 2500; ++k) {
    s.step({w, hk::Wrench6::Zero()}, {0.0, 0.0}, h);
    max_x = std::max(max_x, s.output(hb::ArmSide::kRight).T_D_E.translation().x());
    max_speed = std::max(max_speed, s.output(hb::ArmSide::kRight).twist_E_D.head<3>().norm());
  }
  const double overshoot = max_x - P.workspace_D.max_D.x();
  std::printf("60 N towards the column: end-effector at most %.3f m beyond the workspace wall, speed at most %.2f m/s "
              "(limit %.2f)\n",
              overshoot, max_speed, P.max_linear_speed);
  EXPECT_GT(max_x, P.workspace_D.max_D.x() - 0.05);  // it got there
  EXPECT_LT(overshoot, 60.0 / P.workspace_stiffness + 0.02);
  EXPECT_LT(max_speed, P.max_linear_speed + 0.3);
}

TEST(Limits, ValidateRejectsOutOfRangeParameters) {
  auto bad = [](auto mutate) {
    hb::ArmControlParams p = hb::default_arm_control();
    mutate(p);
    return hb::validate(p).has_value();
  };
  EXPECT_FALSE(bad([](hb::ArmControlParams&) {}));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.inertia_ratio_translation = 0.05; }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.inertia_ratio_rotation = NAN; }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.elbow_force = -1; }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.peak_force = 1000; }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.cartesian_damping = -2; }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.workspace_D.max_D.x() = p.workspace_D.min_D.x(); }));
  EXPECT_TRUE(bad([](hb::ArmControlParams& p) { p.collision.activation_m = 0; }));
  EXPECT_THROW(hb::BimanualSimulation([] {
                 hb::SimulationConfig c;
                 c.control[1].max_linear_speed = 0;
                 return c;
               }()),
               std::invalid_argument);
}
