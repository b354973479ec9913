// deploy/scenes/workbench.xml in MuJoCo: both arms are lwr_arm_model()
// (forward kinematics, Jacobian, mass matrix and bias torques of
// common/kinematics equal MuJoCo's, the gripper as link 7's payload), the
// wrist force-torque sensor carries the gripper's weight at rest (closed
// form), the task objects are where a gripper reaches them, and the gripper
// holds the 2 kg box against gravity (MuJoCo truth).
#include "robot_side/twoarm/workbench_sim.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "robot_side/twoarm/twoarm_model.h"
#include "tests/robot_side/twoarm/workbench_scene.h"

namespace hk = hemm::kinematics;
namespace ht = hemm::twoarm;

namespace {

using hemm::test::kWorkbenchScene;
hk::Arm7Vector random_q(const hk::Arm7Model& arm, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  hk::Arm7Vector q;
  for (int i = 0; i < hk::kArm7Dof; ++i) q(i) = arm.q_min(i) + (0.1 + 0.8 * u(rng)) * (arm.q_max(i) - arm.q_min(i));
  return q;
}

struct ArmDofs {
  int dof[hk::kArm7Dof];
  int qpos[hk::kArm7Dof];
};

// True when a contact involves an arm's or gripper's geom.
bool arm_in_contact(const mjModel* m, const mjData* d) {
  const int r1 = mj_name2id(m, mjOBJ_BODY, "r_link1"), l1 = mj_name2id(m, mjOBJ_BODY, "l_link1");
  auto on_arm = [&](int geom) {
    for (int b = m->geom_bodyid[geom]; b > 0; b = m->body_parentid[b]) {
      if (b == r1 || b == l1) return true;
    }
    return false;
  };
  for (int i = 0; i < d->ncon; ++i) {
    if (on_arm(d->contact[i].geom1) || on_arm(d->contact[i].geom2)) return true;
  }
  return false;
}

ArmDofs dofs(const mjModel* m, ht::Side s) {
  ArmDofs a{};
  for (int i = 0; i < hk::kArm7Dof; ++i) {
    const int j = mj_name2id(m, mjOBJ_JOINT, (std::string(ht::prefix(s)) + "j" + std::to_string(i + 1)).c_str());
    a.dof[i] = m->jnt_dofadr[j];
    a.qpos[i] = m->jnt_qposadr[j];
  }
  return a;
}


}  // namespace

TEST(Workbench, ArmsAreTheLwrArmInMujoco) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  mjModel* m = sim.m();
  mjData* d = sim.d();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<mjtNum> M(static_cast<std::size_t>(m->nv) * static_cast<std::size_t>(m->nv));
  std::vector<mjtNum> jacp(3 * static_cast<std::size_t>(m->nv)), jacr(3 * static_cast<std::size_t>(m->nv));
  for (int trial = 0; trial < 6; ++trial) {
    std::array<hk::Arm7Vector, ht::kArms> q, qd;
    for (std::size_t a = 0; a < ht::kArms; ++a) {
      q[a] = random_q(sim.model().arms[a].arm, rng);
      qd[a] = hk::Arm7Vector::NullaryExpr([&] { return u(rng); });
    }
    sim.reset(q);
    for (ht::Side s : {ht::Side::kRight, ht::Side::kLeft}) {
      const ArmDofs ad = dofs(m, s);
      for (int i = 0; i < hk::kArm7Dof; ++i) d->qvel[ad.dof[i]] = qd[ht::idx(s)](i);
    }
    mj_forward(m, d);
    mj_fullM(m, M.data(), d->qM);
    for (ht::Side s : {ht::Side::kRight, ht::Side::kLeft}) {
      SCOPED_TRACE(ht::to_string(s));
      const ht::ArmMount& mount = sim.model().arm(s);
      const ArmDofs ad = dofs(m, s);
      hk::Arm7Frames f;
      hk::forward_kinematics(mount.arm, q[ht::idx(s)], f);
      // Forward kinematics: the flange site and the grasp site.
      const int flange = mj_name2id(m, mjOBJ_SITE, (std::string(ht::prefix(s)) + "flange").c_str());
      const Eigen::Vector3d p_fl(d->site_xpos[3 * flange], d->site_xpos[3 * flange + 1], d->site_xpos[3 * flange + 2]);
      EXPECT_LT((p_fl - mount.T_A_Ar * f.origin(7)).norm(), 1e-9);
      const Eigen::Isometry3d T_G = ht::grasp_pose_A(mount, f);
      const Eigen::Isometry3d T_G_mj = sim.grasp_site_A(s);
      EXPECT_LT((T_G.translation() - T_G_mj.translation()).norm(), 1e-9);
      EXPECT_LT((T_G.linear() - T_G_mj.linear()).norm(), 1e-9);
      // The grasp frame's Jacobian.
      const int grasp = mj_name2id(m, mjOBJ_SITE, (std::string(ht::prefix(s)) + "grasp").c_str());
      mj_jacSite(m, d, jacp.data(), jacr.data(), grasp);
      const hk::Arm7Jacobian J = ht::grasp_jacobian_A(mount, f);
      for (int r = 0; r < 3; ++r) {
        for (int i = 0; i < hk::kArm7Dof; ++i) {
          EXPECT_NEAR(J(r, i), jacp[static_cast<std::size_t>(r * m->nv + ad.dof[i])], 1e-9);
          EXPECT_NEAR(J(3 + r, i), jacr[static_cast<std::size_t>(r * m->nv + ad.dof[i])], 1e-9);
        }
      }
      // Dynamics with the gripper (fingers closed) as the payload.
      const hk::Arm7Matrix Mk = hk::mass_matrix(mount.arm, f);
      const hk::Arm7Vector bias = hk::bias_torque(mount.arm, f, qd[ht::idx(s)], sim.model().gravity_Ar(s));
      for (int i = 0; i < hk::kArm7Dof; ++i) {
        EXPECT_NEAR(bias(i), d->qfrc_bias[ad.dof[i]], 1e-8 * (1.0 + std::abs(bias(i))));
        for (int k = 0; k < hk::kArm7Dof; ++k) {
          EXPECT_NEAR(Mk(i, k), M[static_cast<std::size_t>(ad.dof[i] * m->nv + ad.dof[k])], 1e-9);
        }
      }
    }
  }
}

TEST(Workbench, WristSensorCarriesTheGripperWeightAtRest) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  mjModel* m = sim.m();
  mjData* d = sim.d();
  std::mt19937_64 rng(11);
  // The gripper's mass and centre of mass in J7, from the scene's bodies.
  double mass = 0.0;
  for (const char* b : {"gripper", "finger_a", "finger_b"}) mass += m->body_mass[mj_name2id(m, mjOBJ_BODY, (std::string("r_") + b).c_str())];
  EXPECT_NEAR(mass, 0.8, 1e-12);  // the scene's palm 0.6 kg and two 0.1 kg fingers
  int checked = 0;
  for (int trial = 0; trial < 40 && checked < 5; ++trial) {
    std::array<hk::Arm7Vector, ht::kArms> q{random_q(sim.model().arms[0].arm, rng), random_q(sim.model().arms[1].arm, rng)};
    const double fingers = 0.02 * (trial % 5);
    sim.reset(q, {fingers, fingers});
    if (arm_in_contact(m, d)) continue;  // statics of a free arm only
    ++checked;
    // Motors hold everything still (ctrl = the bias forces): qacc = 0, so the
    // sensor reads statics only.
    mj_forward(m, d);
    for (int i = 0; i < m->nu; ++i) d->ctrl[i] = d->qfrc_bias[m->jnt_dofadr[m->actuator_trnid[2 * i]]];
    mj_forward(m, d);
    for (ht::Side s : {ht::Side::kRight, ht::Side::kLeft}) {
      SCOPED_TRACE(ht::to_string(s));
      const ht::ArmReading r = sim.reading(s);
      const Eigen::Isometry3d T_A_J7 = sim.model().arm(s).T_A_Ar * hk::flange_pose(sim.model().arm(s).arm, q[ht::idx(s)]);
      const Eigen::Vector3d f_J7 = -mass * (T_A_J7.linear().transpose() * sim.model().gravity_A);
      EXPECT_LT((r.ft_J7.head<3>() - f_J7).norm(), 1e-6 * (1.0 + f_J7.norm()));
      // Torque about the flange: c x f with c the gripper's centre of mass.
      hk::RigidBodyInertia g;
      for (const char* b : {"gripper", "finger_a", "finger_b"}) {
        const int id = mj_name2id(m, mjOBJ_BODY, (std::string(ht::prefix(s)) + b).c_str());
        g = hk::combine(g, hk::RigidBodyInertia{m->body_mass[id],
                                                T_A_J7.inverse() * Eigen::Vector3d(d->xipos[3 * id], d->xipos[3 * id + 1], d->xipos[3 * id + 2]),
                                                Eigen::Matrix3d::Zero()});
      }
      EXPECT_LT((r.ft_J7.tail<3>() - g.com.cross(f_J7)).norm(), 1e-6);
    }
  }
  EXPECT_EQ(checked, 5);
}

// At rest (both arms in their rest postures, grippers closed) the robot
// touches nothing: the scene's objects are out of the arms' way.
TEST(Workbench, RestPostureTouchesNothing) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  sim.reset({sim.model().arms[0].rest_q, sim.model().arms[1].rest_q});
  EXPECT_FALSE(arm_in_contact(sim.m(), sim.d()));
}

TEST(Workbench, TaskObjectsAreWithinReach) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  const ht::ArmMount& right = sim.model().arm(ht::Side::kRight);
  const ht::ArmMount& left = sim.model().arm(ht::Side::kLeft);
  const Eigen::Vector3d box = sim.body_pose_A("box").translation();
  const Eigen::Vector3d peg = sim.body_pose_A("peg").translation();
  const Eigen::Vector3d hole = sim.body_pose_A("fixture").translation() + Eigen::Vector3d(0, 0, 0.05);
  const Eigen::Vector3d bar = sim.body_pose_A("bar").translation();
  // Top grasps: the box 4 cm below its top, the peg 2 cm below its top and
  // over the hole with its tip 1 cm in, the bar from each side of its middle.
  EXPECT_TRUE(ht::grasp_inverse_kinematics(right, ht::downward_grasp(box + Eigen::Vector3d(0, 0, 0.035)), right.rest_q));
  EXPECT_TRUE(ht::grasp_inverse_kinematics(right, ht::downward_grasp(box + Eigen::Vector3d(0, 0, 0.135)), right.rest_q));
  EXPECT_TRUE(ht::grasp_inverse_kinematics(left, ht::downward_grasp(peg + Eigen::Vector3d(0, 0, 0.03)), left.rest_q));
  EXPECT_TRUE(ht::grasp_inverse_kinematics(left, ht::downward_grasp(hole + Eigen::Vector3d(0, 0, 0.08)), left.rest_q));
  EXPECT_TRUE(ht::grasp_inverse_kinematics(right, ht::downward_grasp(bar + Eigen::Vector3d(0, -0.12, 0)), right.rest_q));
  EXPECT_TRUE(ht::grasp_inverse_kinematics(left, ht::downward_grasp(bar + Eigen::Vector3d(0, 0.12, 0)), left.rest_q));
  // The shelf: the box set down on it (its top at z = 0.95).
  const Eigen::Vector3d shelf = sim.body_pose_A("shelf").translation();
  EXPECT_TRUE(ht::grasp_inverse_kinematics(right, ht::downward_grasp(Eigen::Vector3d(shelf.x(), shelf.y(), 0.95 + 0.11)), right.rest_q));
  // Far beyond the arm: refused.
  EXPECT_FALSE(ht::grasp_inverse_kinematics(right, ht::downward_grasp(Eigen::Vector3d(1.8, -0.4, 0.9)), right.rest_q));
}

TEST(Workbench, GripperHoldsTheBoxAgainstGravity) {
  ht::WorkbenchSim sim(kWorkbenchScene);
  mjModel* m = sim.m();
  mjData* d = sim.d();
  const ht::ArmMount& right = sim.model().arm(ht::Side::kRight);
  const Eigen::Vector3d box0 = sim.body_pose_A("box").translation();
  const Eigen::Isometry3d grasp = ht::downward_grasp(box0 + Eigen::Vector3d(0, 0, 0.035));
  Eigen::Isometry3d lifted = grasp;
  lifted.translation().z() += 0.10;
  const auto q_grasp = ht::grasp_inverse_kinematics(right, grasp, right.rest_q);
  ASSERT_TRUE(q_grasp);
  const auto q_lift = ht::grasp_inverse_kinematics(right, lifted, *q_grasp);
  ASSERT_TRUE(q_lift);
  sim.reset({*q_grasp, sim.model().arm(ht::Side::kLeft).rest_q}, {0.108, 0.0});
  // A stiff joint PD on top of MuJoCo's own bias forces holds the arms (this
  // tests the scene, not the robot's controllers); the fingers close with a
  // force of 30 N each.
  hk::Arm7Vector kp, kd;
  kp << 3000, 3000, 1500, 1500, 600, 300, 300;
  kd << 80, 80, 40, 40, 15, 6, 6;
  const ArmDofs ad[2] = {dofs(m, ht::Side::kRight), dofs(m, ht::Side::kLeft)};
  const hk::Arm7Vector q_left = sim.model().arm(ht::Side::kLeft).rest_q;
  const double grip = 30.0;
  auto run = [&](double seconds, auto q_of_t) {
    const double t0 = sim.time_s();
    while (sim.time_s() - t0 < seconds) {
      const hk::Arm7Vector qr = q_of_t((sim.time_s() - t0) / seconds);
      for (int a = 0; a < 2; ++a) {
        ht::ArmCommand c;
        const hk::Arm7Vector& target = a == 0 ? qr : q_left;
        for (int i = 0; i < hk::kArm7Dof; ++i) {
          c.tau(i) = d->qfrc_bias[ad[a].dof[i]] + kp(i) * (target(i) - d->qpos[ad[a].qpos[i]]) - kd(i) * d->qvel[ad[a].dof[i]];
        }
        const double f = a == 0 ? -grip : 0.0;
        c.finger_force_N = {f, f};
        sim.set_command(a == 0 ? ht::Side::kRight : ht::Side::kLeft, c);
      }
      sim.step();
    }
  };
  run(0.6, [&](double) { return *q_grasp; });
  const ht::ArmReading closed = sim.reading(ht::Side::kRight);
  // Both pads press on the box with the motors' force (MuJoCo's touch sensors).
  EXPECT_NEAR(closed.gripper.pad_force_N[0], grip, 0.1 * grip);
  EXPECT_NEAR(closed.gripper.pad_force_N[1], grip, 0.1 * grip);
  EXPECT_NEAR(closed.gripper.finger_m[0] + closed.gripper.finger_m[1], 0.20, 0.004);  // the box's 0.20 m side
  const Eigen::Isometry3d T_G_box0 = sim.grasp_site_A(ht::Side::kRight).inverse() * sim.body_pose_A("box");
  run(1.0, [&](double s) { return ((1.0 - s) * *q_grasp + s * *q_lift).eval(); });
  run(1.0, [&](double) { return *q_lift; });
  const Eigen::Isometry3d box = sim.body_pose_A("box");
  // Lifted 10 cm with the gripper, off the bench, not slipping.
  EXPECT_NEAR(box.translation().z() - box0.z(), 0.10, 0.01);
  const Eigen::Isometry3d T_G_box = sim.grasp_site_A(ht::Side::kRight).inverse() * box;
  EXPECT_LT((T_G_box.translation() - T_G_box0.translation()).norm(), 0.004) << (T_G_box.translation() - T_G_box0.translation()).transpose() << " rot " << Eigen::AngleAxisd(T_G_box.linear() * T_G_box0.linear().transpose()).angle();
  EXPECT_GT(sim.reading(ht::Side::kRight).gripper.pad_force_N[0], 0.5 * grip);
}
