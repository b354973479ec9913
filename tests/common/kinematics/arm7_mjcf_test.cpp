// The MJCF text of an Arm7Model: MuJoCo reads back exactly the model's
// numbers (masses, centres of mass, principal inertias, joint axes, ranges,
// friction), names, sites and collision geoms.
#include "common/kinematics/arm7_mjcf.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "tests/common/kinematics/mujoco_arm7.h"

namespace hk = hemm::kinematics;

TEST(Arm7Mjcf, MujocoReadsBackTheModel) {
  const hk::Arm7Model m = hk::lwr_arm_model();
  hk::Arm7MjcfOptions o;
  o.prefix = "r_";
  o.damping = hk::Arm7Vector::Constant(0.5);
  o.frictionloss = hk::Arm7Vector::LinSpaced(0.1, 0.7);
  o.link_radius = hk::Arm7Vector::Constant(0.06);
  o.contype = 2;
  o.conaffinity = 5;
  auto mj = hemm::test::make_mj_arm7(m, "0 0 0", "1 0 0 0", "", o);
  const mjModel* mm = mj.m.get();
  ASSERT_EQ(mm->njnt, 7);
  ASSERT_EQ(mm->nv, 7);
  for (int i = 0; i < 7; ++i) {
    const auto k = static_cast<size_t>(i);
    const int b = mj.link[i];
    EXPECT_DOUBLE_EQ(mm->body_mass[b], m.link[k].mass);
    // Principal moments: MuJoCo diagonalises the full inertia.
    Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m.link[k].inertia).eigenvalues();
    Eigen::Vector3d mv(mm->body_inertia[3 * b], mm->body_inertia[3 * b + 1], mm->body_inertia[3 * b + 2]);
    std::sort(mv.data(), mv.data() + 3);
    EXPECT_LT((ev - mv).norm(), 1e-12);
    for (int c = 0; c < 3; ++c) {
      EXPECT_DOUBLE_EQ(mm->body_ipos[3 * b + c], m.link[k].com(c));
      EXPECT_DOUBLE_EQ(mm->jnt_axis[3 * i + c], m.axis[k](c));
      EXPECT_DOUBLE_EQ(mm->body_pos[3 * b + c], m.offset[k](c));
    }
    EXPECT_DOUBLE_EQ(mm->jnt_range[2 * i], m.q_min(i));
    EXPECT_DOUBLE_EQ(mm->jnt_range[2 * i + 1], m.q_max(i));
    EXPECT_DOUBLE_EQ(mm->dof_frictionloss[i], o.frictionloss(i));
    EXPECT_DOUBLE_EQ(mm->dof_damping[i], 0.5);
    EXPECT_DOUBLE_EQ(mm->dof_armature[i], m.armature(i));
    const int g = mj_name2id(mm, mjOBJ_GEOM, ("r_geom" + std::to_string(i + 1)).c_str());
    ASSERT_GE(g, 0);
    EXPECT_EQ(mm->geom_bodyid[g], b);
    EXPECT_EQ(mm->geom_contype[g], 2);
    EXPECT_EQ(mm->geom_conaffinity[g], 5);
    EXPECT_DOUBLE_EQ(mm->geom_size[3 * g], 0.06);
  }
  const int elbow = mj_name2id(mm, mjOBJ_SITE, "r_elbow");
  const int flange = mj_name2id(mm, mjOBJ_SITE, "r_flange");
  ASSERT_GE(elbow, 0);
  ASSERT_GE(flange, 0);
  EXPECT_EQ(mm->site_bodyid[elbow], mj.link[3]);
  EXPECT_EQ(mm->site_bodyid[flange], mj.link[6]);
}

TEST(Arm7Mjcf, NumbersReadBackExactly) {
  const double v[] = {0.1, -2.5e-17, 1.0 / 3.0, 0.2085, 176.0};
  const std::string text = hk::mjcf_numbers({v[0], v[1], v[2], v[3], v[4]});
  const char* p = text.c_str();
  for (double x : v) {
    char* end = nullptr;
    EXPECT_EQ(std::strtod(p, &end), x);
    p = end;
  }
  EXPECT_EQ(*p, '\0');
}
