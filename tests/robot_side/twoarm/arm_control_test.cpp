// The two-arm robot's 1 kHz controllers on the SIMULATED workbench, against
// MuJoCo truth and closed forms: the stiffness G shows to an external force
// is the stiffness set (displacement F / K), the wrist force limit holds when
// the arm is told to push 10 cm into the bench, no joint reaches its limit
// whatever the target, the gripper presses with the force it is told, and
// the arm-arm repulsion keeps the arms apart where without it they collide.
#include "robot_side/twoarm/twoarm_control.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "robot_side/twoarm/task_truth.h"
#include "robot_side/twoarm/workbench_sim.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace hk = hemm::kinematics;
namespace ht = hemm::twoarm;

namespace {

using hemm::test::kWorkbenchScene;

struct Loop {
  ht::WorkbenchSim sim{kWorkbenchScene};
  ht::TwoArmParams params;
  ht::TwoArmTargets targets;
  ht::TwoArmOutput out;
  std::function<void()> each_tick;  // after the controller, before the step (external loads)

  std::array<ht::ArmReading, ht::kArms> readings() const {
    return {sim.reading(ht::Side::kRight), sim.reading(ht::Side::kLeft)};
  }
  void hold_here(double grip_N = 10.0) { targets = ht::hold_targets(sim.model(), readings(), {grip_N, grip_N}); }
  void run(double seconds, const std::function<void()>& check = {}) {
    const int n = static_cast<int>(std::lround(seconds / sim.timestep_s()));
    for (int k = 0; k < n; ++k) {
      ht::twoarm_control(sim.model(), params, readings(), targets, out);
      sim.set_command(ht::Side::kRight, out.command[0]);
      sim.set_command(ht::Side::kLeft, out.command[1]);
      for (int i = 0; i < 6 * sim.m()->nbody; ++i) sim.d()->xfrc_applied[i] = 0.0;
      if (each_tick) each_tick();
      sim.step();
      if (check) check();
    }
  }
};

// Applies force f_A and torque t_A at the grasp site of side s: a body
// wrench on the gripper (MuJoCo's xfrc_applied acts at the body's centre of
// mass), which the wrist sensor feels as a real push would be.
void push_at_grasp(ht::WorkbenchSim& sim, ht::Side s, const Eigen::Vector3d& f_A, const Eigen::Vector3d& t_A) {
  mjModel* m = sim.m();
  mjData* d = sim.d();
  const int body = mj_name2id(m, mjOBJ_BODY, (std::string(ht::prefix(s)) + "gripper").c_str());
  const Eigen::Vector3d p = sim.grasp_site_A(s).translation();  // A = W in this scene
  const Eigen::Vector3d c(d->xipos[3 * body], d->xipos[3 * body + 1], d->xipos[3 * body + 2]);
  const Eigen::Vector3d t = t_A + (p - c).cross(f_A);
  for (int k = 0; k < 3; ++k) {
    d->xfrc_applied[6 * body + k] = f_A(k);
    d->xfrc_applied[6 * body + 3 + k] = t(k);
  }
}

}  // namespace

// The stiffness felt at G equals the stiffness set: an external force F
// moves G by F / K, a torque T turns it by T / K_r (closed forms), for two
// stiffnesses on two arms in two postures.
TEST(TwoArmControl, StiffnessFeltIsTheSetStiffness) {
  struct Case {
    ht::Side side;
    double K, K_r;
    Eigen::Vector3d F, T;
    Eigen::Vector3d offset;  // of the grasp frame from its rest pose
  };
  const Case cases[] = {
      {ht::Side::kRight, 1000.0, 60.0, {8.0, -5.0, 6.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}},
      {ht::Side::kLeft, 600.0, 40.0, {-4.0, 3.0, -7.0}, {0.0, 0.0, 0.0}, {0.06, 0.05, -0.08}},
      {ht::Side::kRight, 1000.0, 60.0, {0.0, 0.0, 0.0}, {0.6, -0.4, 0.5}, {-0.05, 0.04, 0.05}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(ht::to_string(c.side)) + " K " + std::to_string(c.K));
    Loop L;
    const ht::ArmMount& mount = L.sim.model().arm(c.side);
    const Eigen::Isometry3d rest = ht::grasp_pose_A(mount, mount.rest_q);
    Eigen::Isometry3d at = rest;
    at.translation() += c.offset;
    const auto q = ht::grasp_inverse_kinematics(mount, at, mount.rest_q);
    ASSERT_TRUE(q);
    std::array<hk::Arm7Vector, 2> q0{L.sim.model().arms[0].rest_q, L.sim.model().arms[1].rest_q};
    q0[ht::idx(c.side)] = *q;
    L.sim.reset(q0, {0.03, 0.03});
    for (auto& a : L.params.arm) {
      a.stiffness_N_per_m = c.K;
      a.rot_stiffness_Nm_per_rad = c.K_r;
    }
    L.params.avoid = false;
    L.hold_here();
    L.run(2.0);  // settle
    ASSERT_EQ(L.out.arm[ht::idx(c.side)].tau_limits.norm(), 0.0);  // no joint near its limit
    const Eigen::Isometry3d before = L.sim.grasp_site_A(c.side);
    L.each_tick = [&] { push_at_grasp(L.sim, c.side, c.F, c.T); };
    L.run(2.0);
    const Eigen::Isometry3d after = L.sim.grasp_site_A(c.side);
    const Eigen::Vector3d dx = after.translation() - before.translation();
    const Eigen::Vector3d dr = ht::rotation_vector(after.linear() * before.linear().transpose());
    if (c.F.norm() > 0.0) {
      const Eigen::Vector3d expect = c.F / c.K;
      EXPECT_LT((dx - expect).norm(), 0.03 * expect.norm()) << dx.transpose() << " vs " << expect.transpose();
      std::printf("%s K %.0f: moved %.3f mm for %.3f mm (F / K)\n", ht::to_string(c.side), c.K, 1e3 * dx.norm(), 1e3 * expect.norm());
    } else {
      const Eigen::Vector3d expect = c.T / c.K_r;
      EXPECT_LT((dr - expect).norm(), 0.03 * expect.norm()) << dr.transpose() << " vs " << expect.transpose();
      std::printf("%s K_r %.0f: turned %.4f rad for %.4f rad (T / K_r)\n", ht::to_string(c.side), c.K_r, dr.norm(), expect.norm());
    }
    // The wrist sensor sees the pushed wrench (at rest: statics).
    const hk::Wrench6 w = L.out.wrench_ext_A[ht::idx(c.side)];
    EXPECT_LT((w.head<3>() - c.F).norm(), 0.05 + 0.02 * c.F.norm()) << w.head<3>().transpose();
    EXPECT_LT((w.tail<3>() - c.T).norm(), 0.01 + 0.02 * c.T.norm()) << w.tail<3>().transpose();
  }
}

// Told to push 10 cm into the bench (100 N of spring at K = 1000 N/m), the
// arm presses with the force limit and no more: the bench's total contact
// force on the fingers (normal and friction, MuJoCo truth) settles at the
// limit, and the peak stays within 10 % of it.
TEST(TwoArmControl, WristForceLimitHeldAgainstTheBench) {
  struct Case {
    ht::Side side;
    double limit;
    Eigen::Vector3d at;
  };
  for (const Case& c : {Case{ht::Side::kRight, 30.0, {0.50, -0.12, 0.0}}, Case{ht::Side::kLeft, 20.0, {0.48, 0.05, 0.0}}}) {
    SCOPED_TRACE(std::string(ht::to_string(c.side)) + " limit " + std::to_string(c.limit));
    Loop L;
    mjModel* m = L.sim.m();
    mjData* d = L.sim.d();
    const ht::ArmMount& mount = L.sim.model().arm(c.side);
    const double bench = L.sim.model().bench.top_z;
    // G 2.5 cm above the finger tips: tips 3 cm above the bench to start.
    const Eigen::Vector3d start(c.at.x(), c.at.y(), bench + 0.055);
    const auto q = ht::grasp_inverse_kinematics(mount, ht::downward_grasp(start), mount.rest_q);
    ASSERT_TRUE(q);
    std::array<hk::Arm7Vector, 2> q0{L.sim.model().arms[0].rest_q, L.sim.model().arms[1].rest_q};
    q0[ht::idx(c.side)] = *q;
    L.sim.reset(q0, {0.02, 0.02});
    for (auto& a : L.params.arm) a.force_limit_N = c.limit;
    L.hold_here();
    L.targets.T_A_G[ht::idx(c.side)] = ht::downward_grasp(Eigen::Vector3d(c.at.x(), c.at.y(), bench + 0.025 - 0.10));
    const int top = mj_name2id(m, mjOBJ_GEOM, "bench_top");
    const std::string p = ht::prefix(c.side);
    const int fa = mj_name2id(m, mjOBJ_GEOM, (p + "finger_a_geom").c_str());
    const int fb = mj_name2id(m, mjOBJ_GEOM, (p + "finger_b_geom").c_str());
    // The bench's total force on the fingers (normal and friction), in A.
    auto bench_force = [&] {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int i = 0; i < d->ncon; ++i) {
        const mjContact& con = d->contact[i];
        const bool ours = (con.geom1 == top && (con.geom2 == fa || con.geom2 == fb)) ||
                          (con.geom2 == top && (con.geom1 == fa || con.geom1 == fb));
        if (!ours) continue;
        mjtNum cf[6];
        mj_contactForce(m, d, i, cf);  // in the contact frame: rows of con.frame, normal first
        Eigen::Vector3d fw = Eigen::Vector3d::Zero();
        for (int r = 0; r < 3; ++r) fw += cf[r] * Eigen::Vector3d(con.frame[3 * r], con.frame[3 * r + 1], con.frame[3 * r + 2]);
        sum += con.geom1 == top ? fw : -fw;  // on the fingers (the contact frame's force acts on geom2)
      }
      return sum.norm();
    };
    double peak = 0.0;
    L.run(1.0);
    L.run(2.0, [&] { peak = std::max(peak, bench_force()); });
    const double settled = bench_force();
    EXPECT_NEAR(settled, c.limit, 0.05 * c.limit);
    EXPECT_LT(peak, 1.10 * c.limit);
    EXPECT_TRUE(L.out.arm[ht::idx(c.side)].force_limited);
    // The wrist sensor reads it too (the bench pushes G up).
    EXPECT_NEAR(L.out.wrench_ext_A[ht::idx(c.side)].head<3>().norm(), c.limit, 0.05 * c.limit);
    std::printf("pushing 10 cm into the bench with a %.0f N limit: %.2f N on the bench (peak %.2f N)\n", c.limit, settled, peak);
  }
}

// Targets that would drive joints past their limits (a wrist turned 2.5 rad
// beyond its range, a point 1.5 m out of reach, one behind the torso): no
// joint reaches its limit (MuJoCo's joint-limit constraint never engages) and
// no motor torque exceeds the arm's torque limits.
TEST(TwoArmControl, NoJointLimitCrossed) {
  Loop L;
  mjModel* m = L.sim.m();
  mjData* d = L.sim.d();
  L.hold_here();
  const Eigen::Isometry3d home_r = L.targets.T_A_G[0], home_l = L.targets.T_A_G[1];
  std::vector<std::array<Eigen::Isometry3d, 2>> goals;
  {
    Eigen::Isometry3d r = home_r, l = home_l;
    r.linear() = r.linear() * Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    l.linear() = l.linear() * Eigen::AngleAxisd(-2.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    goals.push_back({r, l});
    r = home_r;
    l = home_l;
    r.translation() += Eigen::Vector3d(1.5, -0.5, 0.2);
    l.translation() = Eigen::Vector3d(-0.6, 0.5, 1.2);
    goals.push_back({r, l});
  }
  int limit_rows = 0;
  double worst_margin = 1e9;
  for (const auto& g : goals) {
    L.targets.T_A_G = g;
    L.run(3.0, [&] {
      for (int i = 0; i < d->nefc; ++i) {
        if (d->efc_type[i] == mjCNSTR_LIMIT_JOINT) {
          const int j = d->efc_id[i];
          if (m->jnt_type[j] == mjJNT_HINGE) ++limit_rows;
        }
      }
      for (std::size_t a = 0; a < 2; ++a) {
        const ht::ArmReading r = L.sim.reading(static_cast<ht::Side>(a));
        const hk::Arm7Model& arm = L.sim.model().arms[a].arm;
        worst_margin = std::min(worst_margin, std::min((r.q - arm.q_min).minCoeff(), (arm.q_max - r.q).minCoeff()));
        EXPECT_TRUE(((L.out.command[a].tau.cwiseAbs() - arm.tau_max).array() <= 1e-12).all());
      }
    });
  }
  EXPECT_EQ(limit_rows, 0);
  EXPECT_GT(worst_margin, 0.0);
  std::printf("closest approach to a joint limit: %.3f rad\n", worst_margin);
}

// Position and force: in free space the fingers go to the opening; closed on
// the box they press with the commanded force (touch sensors, MuJoCo truth).
TEST(TwoArmControl, GripperPositionAndForce) {
  Loop L;
  L.hold_here();
  L.targets.gripper[1] = {0.137, 20.0};
  L.run(1.5);  // 68.5 mm per finger at the governed 80 mm/s
  EXPECT_NEAR(L.sim.reading(ht::Side::kLeft).gripper.finger_m[0] + L.sim.reading(ht::Side::kLeft).gripper.finger_m[1],
              0.137, 0.001);
  EXPECT_FALSE(L.out.gripper[1].holding);
  // The right gripper around the box, then closing with 15 N and with 35 N.
  const ht::ArmMount& right = L.sim.model().arm(ht::Side::kRight);
  const Eigen::Vector3d box = L.sim.body_pose_A("box").translation();
  const auto q = ht::grasp_inverse_kinematics(right, ht::downward_grasp(box + Eigen::Vector3d(0, 0, 0.035)), right.rest_q);
  ASSERT_TRUE(q);
  L.sim.reset({*q, L.sim.model().arms[1].rest_q}, {0.105, 0.0});
  L.hold_here();
  for (double force : {15.0, 35.0}) {
    L.targets.gripper[0] = {0.0, force};
    L.run(0.8);
    const ht::ArmReading r = L.sim.reading(ht::Side::kRight);
    // The coupled fingers share the squeeze: the mean is the grip force.
    EXPECT_NEAR(0.5 * (r.gripper.pad_force_N[0] + r.gripper.pad_force_N[1]), force, 0.03 * force);
    EXPECT_NEAR(r.gripper.pad_force_N[0], force, 0.2 * force);
    EXPECT_NEAR(r.gripper.pad_force_N[1], force, 0.2 * force);
    EXPECT_NEAR(L.out.gripper[0].grip_force_N, force, 0.03 * force);
    EXPECT_TRUE(L.out.gripper[0].holding);
    EXPECT_NEAR(L.out.gripper[0].opening_m, 0.20, 0.004);
  }
}

// The right grasp frame sent to the left arm's elbow: with the repulsion no
// link of one arm touches the other arm, nor a gripper the other's links (no
// MuJoCo contact; the grippers may meet, as in a hand-over), and the gap
// stays near the activation distance; without it the right arm comes
// closer (here it is stopped by its reach before it touches: the test
// compares the gaps, it does not show a collision).
TEST(TwoArmControl, ArmArmAvoidanceKeepsTheArmsApart) {
  auto contacts_between_arms = [](bool avoid) {
    Loop L;
    mjModel* m = L.sim.m();
    mjData* d = L.sim.d();
    L.params.avoid = avoid;
    for (auto& a : L.params.arm) a.force_limit_N = 80.0;  // push hard
    L.hold_here();
    // The right grasp frame sent to the left arm's elbow (beyond its reach:
    // the right arm sweeps across the left one).
    const ht::ArmMount& left = L.sim.model().arms[1];
    hk::Arm7Frames f;
    hk::forward_kinematics(left.arm, left.rest_q, f);
    L.targets.T_A_G[0].translation() = left.T_A_Ar * f.origin(4);
    int touching = 0;
    const int r1 = mj_name2id(m, mjOBJ_BODY, "r_link1"), l1 = mj_name2id(m, mjOBJ_BODY, "l_link1");
    const int r_grip = mj_name2id(m, mjOBJ_BODY, "r_gripper"), l_grip = mj_name2id(m, mjOBJ_BODY, "l_gripper");
    // 0 / 1: a geom of the right / left arm's links; 2 / 3: of its gripper.
    auto arm_of = [&](int geom) {
      int part = 0;
      for (int b = m->geom_bodyid[geom]; b > 0; b = m->body_parentid[b]) {
        if (b == r_grip || b == l_grip) part = 2;
        if (b == r1) return part + 0;
        if (b == l1) return part + 1;
      }
      return -1;
    };
    double min_gap = 1e9;
    L.run(3.0, [&] {
      min_gap = std::min(min_gap, L.out.avoidance.min_arm_arm_m);
      for (int i = 0; i < d->ncon; ++i) {
        // Arm against arm, but not gripper against gripper (a hand-over's).
        const int a1 = arm_of(d->contact[i].geom1), a2 = arm_of(d->contact[i].geom2);
        if (a1 >= 0 && a2 >= 0 && a1 % 2 != a2 % 2 && (a1 < 2 || a2 < 2)) ++touching;
      }
    });
    return std::make_pair(touching, min_gap);
  };
  const auto with = contacts_between_arms(true);
  const auto without = contacts_between_arms(false);
  EXPECT_EQ(with.first, 0);
  // The repulsion holds the arms near its activation gap (6 cm); without it
  // the right arm comes closer (its grasp frame stops at its reach).
  EXPECT_GT(with.second, 0.04);
  EXPECT_GT(with.second, without.second + 0.008);
  std::printf("smallest arm-arm gap with the repulsion: %.3f m, without %.3f m\n", with.second, without.second);
}

// The fingers' speed governor: a gripper 7 mm off the box's centre across
// its closing axis closes on it (open 0.218 m, box 0.20 m: one pad 2 mm
// from it, the other 16 mm). The first pad meets the box alone; the net
// contact force on the gripper (MuJoCo truth, the task judge's wrist
// measure) stays within the 40 N wrist limit with the governor, and is well
// beyond it without (the pads arrive at ~0.5 m/s). Both then hold.
TEST(TwoArmControl, GripperClosingOffCentreStaysWithinTheWristLimit) {
  const auto peak_closing = [](double max_speed) {
    Loop L;
    L.params.gripper.max_speed_mps = max_speed;
    const ht::ArmMount& right = L.sim.model().arm(ht::Side::kRight);
    const Eigen::Vector3d box = L.sim.body_pose_A("box").translation();
    const auto q = ht::grasp_inverse_kinematics(right, ht::downward_grasp(box + Eigen::Vector3d(0.007, 0, 0.035)), right.rest_q);
    EXPECT_TRUE(q);
    if (!q) return 0.0;
    L.sim.reset({*q, L.sim.model().arms[1].rest_q}, {0.109, 0.0});
    L.hold_here();
    L.run(0.3);  // settle open
    const ht::TaskTruthModel tm = ht::make_task_truth_model(L.sim, ht::Task::kBox);
    double peak = 0.0;
    L.targets.gripper[0] = {0.0, 30.0};
    L.run(1.0, [&] { peak = std::max(peak, ht::task_truth_sample(tm, L.sim).gripper_force_A[0].norm()); });
    EXPECT_TRUE(L.out.gripper[0].holding) << "max_speed " << max_speed;
    EXPECT_NEAR(L.out.gripper[0].grip_force_N, 30.0, 1.5) << "max_speed " << max_speed;
    return peak;
  };
  const double governed = peak_closing(0.08);
  const double ungoverned = peak_closing(0.0);
  std::printf("closing 7 mm off centre: wrist contact peak %.1f N governed, %.1f N not\n", governed, ungoverned);
  EXPECT_LT(governed, 40.0);
  EXPECT_GT(ungoverned, 1.5 * governed);
}

// Both grippers holding: the two arms' position errors are coupled - their
// mean at the full stiffness, what differs at relative_stiffness_ratio of
// it (closed form on the spring force at rest); one gripper not holding, or
// the ratio 1: independent arms.
TEST(TwoArmControl, BothGrippersHoldingCoupleThePositionErrors) {
  ht::WorkbenchSim sim{kWorkbenchScene};
  std::array<ht::ArmReading, ht::kArms> in{sim.reading(ht::Side::kRight), sim.reading(ht::Side::kLeft)};
  ht::TwoArmTargets targets = ht::hold_targets(sim.model(), in, {30.0, 30.0});
  const Eigen::Vector3d e0(0.012, 0.0, -0.004), e1(0.0, 0.002, 0.0);
  targets.T_A_G[0].translation() += e0;
  targets.T_A_G[1].translation() += e1;
  ht::TwoArmParams p;
  p.avoid = false;
  p.relative_stiffness_ratio = 0.25;
  const double k = p.arm[0].stiffness_N_per_m;
  ht::TwoArmOutput out;
  const auto spring = [&](std::size_t a) -> Eigen::Vector3d { return out.arm[a].wrench_A.head<3>(); };
  // Not holding: independent.
  ht::twoarm_control(sim.model(), p, in, targets, out);
  EXPECT_FALSE(out.coupled);
  EXPECT_LT((spring(0) - k * e0).norm(), 0.05);
  EXPECT_LT((spring(1) - k * e1).norm(), 0.05);
  // Both pads of both grippers pressing with the grip force: coupled.
  for (auto& r : in) r.gripper.pad_force_N = {30.0, 30.0};
  ht::twoarm_control(sim.model(), p, in, targets, out);
  EXPECT_TRUE(out.coupled);
  const Eigen::Vector3d ec = 0.5 * (e0 + e1);
  EXPECT_LT((spring(0) - k * (ec + 0.25 * (e0 - ec))).norm(), 0.05) << spring(0).transpose();
  EXPECT_LT((spring(1) - k * (ec + 0.25 * (e1 - ec))).norm(), 0.05) << spring(1).transpose();
  // The sum - what moves the object - is the independent arms' sum.
  EXPECT_LT((spring(0) + spring(1) - k * (e0 + e1)).norm(), 0.05);
  // One gripper holding only: independent again.
  in[1].gripper.pad_force_N = {30.0, 0.0};
  ht::twoarm_control(sim.model(), p, in, targets, out);
  EXPECT_FALSE(out.coupled);
  EXPECT_LT((spring(0) - k * e0).norm(), 0.05);
  // Ratio 1: never coupled.
  in[1].gripper.pad_force_N = {30.0, 30.0};
  p.relative_stiffness_ratio = 1.0;
  ht::twoarm_control(sim.model(), p, in, targets, out);
  EXPECT_FALSE(out.coupled);
  EXPECT_LT((spring(1) - k * e1).norm(), 0.05);
}
