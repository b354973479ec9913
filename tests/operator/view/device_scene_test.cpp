// What the live view of a device-only run draws (operator/view/device_scene.h),
// checked against what it stands for: the SIMULATED bimanual arms against
// the plant's own MuJoCo bodies (the hands where MuJoCo has them, the arms'
// capsules joined from mount to flange), a VPS object's box and points on the
// box mesh it was built from, at the pose the tick gives, the static scene's
// cubes on its mesh within the budget, the wrench arrows along the wrench;
// and the per-tick record the tasks publish (allocation-free, one per tick).
#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "common/mesh/primitives.h"
#include "operator/bimanual/bimanual_scripts.h"
#include "operator/bimanual/bimanual_task.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/device/replay_device.h"
#include "operator/view/device_scene.h"
#include "operator/vps/vps_session.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::op {
namespace {

namespace hb = hemm::device::bimanual;
namespace hv = hemm::view;
constexpr double mm = 1e-3;

bool same(hv::Rgba a, hv::Rgba b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

std::vector<const hv::Primitive*> of_colour(const hv::PrimitiveList& l, hv::Rgba c, hv::Shape shape) {
  std::vector<const hv::Primitive*> out;
  for (const hv::Primitive& p : l.items())
    if (same(p.rgba, c) && p.shape == shape) out.push_back(&p);
  return out;
}

double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (a + t * d - p).norm();
}

TEST(DeviceScene, BothArmsAndHandlesStandWhereTheSimulatedPlantHasThem) {
  hb::SimulationConfig cfg;
  hb::BimanualSimulation sim(cfg);
  DeviceSceneSetup s;
  s.device = "simulated-bimanual-lwr";
  s.arms = DeviceViewArms{cfg.plant.rig, {hb::handle_spec(cfg.plant.handles[0]), hb::handle_spec(cfg.plant.handles[1])}};
  DeviceViewRecord t;
  t.end_effectors = 2;
  t.has_arms = true;
  for (int a = 0; a < 2; ++a) {
    const auto k = static_cast<std::size_t>(a);
    t.q[k] = sim.reading(static_cast<hb::ArmSide>(a)).q;
    t.position_H[k] = sim.end_effector(static_cast<hb::ArmSide>(a)).T_D_E.translation();
  }
  hv::PrimitiveList out;
  build_device_scene(s, &t, DeviceSceneStyle{}, out);
  // Table and column, 7 link capsules and a handle per arm, nothing else
  // (no force, no objects).
  ASSERT_EQ(out.size(), 2u + 2u * 8u);
  const auto links = of_colour(out, device_view_colours::kArm, hv::Shape::kCapsule);
  const auto handles = of_colour(out, device_view_colours::kHandle, hv::Shape::kCapsule);
  ASSERT_EQ(links.size(), 14u);
  ASSERT_EQ(handles.size(), 2u);
  for (int a = 0; a < 2; ++a) {
    SCOPED_TRACE(a);
    const auto k = static_cast<std::size_t>(a);
    // A chain from the mount: each capsule starts where the last ended.
    EXPECT_LT((links[7 * k]->pos - cfg.plant.rig.T_D_A[k].translation()).norm(), 1e-12);
    for (std::size_t i = 1; i < 7; ++i) EXPECT_LT((links[7 * k + i]->pos - links[7 * k + i - 1]->to).norm(), 1e-12);
    EXPECT_DOUBLE_EQ(links[7 * k + 6]->width, cfg.plant.rig.link_radius[6]);
    // The handle starts at the flange, the chain's end.
    EXPECT_LT((handles[k]->pos - links[7 * k + 6]->to).norm(), 1e-12);
    // MuJoCo's own bodies: the SIMULATED hand holds the handle on its axis.
    const Eigen::Vector3d hand = sim.truth().hands[k].position_D;
    const double d = point_segment_distance(hand, handles[k]->pos, handles[k]->to);
    std::printf("arm %d: hand (MuJoCo) %.4f %.4f %.4f, %.2f mm from the drawn handle's axis\n", a, hand.x(),
                hand.y(), hand.z(), d / mm);
    EXPECT_LT(d, 1 * mm);
    // Right hand at y < 0, left at y > 0, both in front of the column.
    EXPECT_LT(hand.x(), cfg.plant.rig.column.min_D.x());
    EXPECT_EQ(hand.y() < 0, a == 0);
  }
}

TEST(DeviceScene, ObjectsAndStaticSceneAreDrawnWhereTheTickAndThePlacementPutThem) {
  // A 40 x 20 x 10 mm box held by end-effector 0, a 0.2 m plate as the scene.
  const Eigen::Vector3d half(0.02, 0.01, 0.005);
  VpsMeshSpec scene_spec, obj_spec;
  scene_spec.voxel_size = 2 * mm;
  obj_spec.voxel_size = 1 * mm;
  const auto model = make_vps_model(mesh::make_box(Eigen::Vector3d(0.1, 0.1, 0.01), 4), scene_spec,
                                    {{mesh::make_box(half, 2), obj_spec}}, vps::ContactParams{});
  VpsTaskParams tp;
  tp.ee[0].T_W_H.translation() = Eigen::Vector3d(0.1, 0.0, 0.0);
  tp.ee[1].T_W_H.translation() = Eigen::Vector3d(0.3, 0.0, 0.0);  // one object: only end-effector 0's counts
  DeviceSceneBudget budget;
  budget.scene_cubes = 300;
  budget.object_points = 50;
  const DeviceSceneSetup s = vps_view_setup(*model, tp, 2, nullptr, "test", budget);
  EXPECT_FALSE(s.arms);
  // W drawn through the one mapping that has an object.
  EXPECT_LT((s.T_H_W.translation() - Eigen::Vector3d(-0.1, 0, 0)).norm(), 1e-12);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_LE(s.objects[0].points_M.size(), 50u);
  EXPECT_GE(s.objects[0].points_M.size(), 25u);
  EXPECT_GT(s.scene.surface_voxels, 300u);
  EXPECT_LE(s.scene.centres.size(), 300u);
  EXPECT_GT(s.scene.centres.size(), 30u);
  // Every cube touches the plate's surface (within the cube's half diagonal).
  for (const Eigen::Vector3d& c : s.scene.centres) {
    const Eigen::Vector3d out = (c.cwiseAbs() - Eigen::Vector3d(0.1, 0.1, 0.01)).cwiseMax(0.0);
    const Eigen::Vector3d in = (Eigen::Vector3d(0.1, 0.1, 0.01) - c.cwiseAbs());
    const double to_surface = out.norm() > 0 ? out.norm() : in.minCoeff();
    EXPECT_LE(to_surface, std::sqrt(3.0) * s.scene.half + 1e-9) << c.transpose();
  }

  DeviceViewRecord t;
  t.end_effectors = 1;
  t.position_H[0] = Eigen::Vector3d(-0.05, 0.02, 0.1);
  t.force_H[0] = Eigen::Vector3d(0, 0, 10);
  t.torque_H[0] = Eigen::Vector3d(0.5, 0, 0);
  t.objects = 1;
  t.object_W[0] = Eigen::Translation3d(0.04, 0.0, 0.05) * Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ());
  hv::PrimitiveList out;
  const DeviceSceneStyle st;
  build_device_scene(s, &t, st, out);
  const Eigen::Isometry3d T_H_M = s.T_H_W * t.object_W[0];
  hv::Rgba box_colour = device_view_colours::kObject[0];
  const auto boxes = of_colour(out, box_colour, hv::Shape::kBox);
  ASSERT_EQ(boxes.size(), 1u);
  // The box mesh's own box, at the object's pose (the pointshell lies within
  // a voxel of the surface).
  EXPECT_LT((boxes[0]->pos - T_H_M.translation()).norm(), 1 * mm);
  EXPECT_LT((boxes[0]->R - T_H_M.linear()).norm(), 1e-12);
  EXPECT_LT((boxes[0]->size - half).cwiseAbs().maxCoeff(), 1 * mm);
  const auto points = of_colour(out, device_view_colours::kObject[0], hv::Shape::kSphere);
  ASSERT_EQ(points.size(), s.objects[0].points_M.size());
  for (const hv::Primitive* p : points) {
    const Eigen::Vector3d m = T_H_M.inverse() * p->pos;
    const double to_surface = (half - m.cwiseAbs()).minCoeff();
    EXPECT_LT(std::abs(to_surface), 1 * mm) << m.transpose();
  }
  // The grasp line from the hand to the object, the wrench as arrows.
  const auto grasp = of_colour(out, device_view_colours::kGrasp, hv::Shape::kLine);
  ASSERT_EQ(grasp.size(), 1u);
  EXPECT_EQ(grasp[0]->pos, t.position_H[0]);
  EXPECT_LT((grasp[0]->to - T_H_M.translation()).norm(), 1e-12);
  const auto force = of_colour(out, device_view_colours::kForce, hv::Shape::kArrow);
  const auto torque = of_colour(out, device_view_colours::kTorque, hv::Shape::kArrow);
  ASSERT_EQ(force.size(), 1u);
  ASSERT_EQ(torque.size(), 1u);
  EXPECT_LT((force[0]->to - (t.position_H[0] + st.force_scale * t.force_H[0])).norm(), 1e-12);
  // 0.5 N m at 1 m per N m: cut to the longest arrow, along the torque.
  EXPECT_LT((torque[0]->to - (t.position_H[0] + st.max_arrow * Eigen::Vector3d::UnitX())).norm(), 1e-12);
  // Without a tick: the scene only.
  build_device_scene(s, nullptr, st, out);
  EXPECT_EQ(out.size(), s.scene.centres.size());
}

TEST(DeviceScene, TheMeanMappingPutsTheSceneBetweenTwoHands) {
  std::array<Eigen::Isometry3d, 2> T{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  T[0].translation() = Eigen::Vector3d(0.7, 0.25, -0.25);
  T[1].translation() = Eigen::Vector3d(0.7, -0.25, -0.30);
  const Eigen::Isometry3d T_H_W = view_placement_of_W(T, 2);
  EXPECT_LT((T_H_W * Eigen::Vector3d::Zero() - Eigen::Vector3d(-0.7, 0.0, 0.275)).norm(), 1e-12);
  EXPECT_LT((view_placement_of_W(T, 1).translation() - Eigen::Vector3d(-0.7, -0.25, 0.25)).norm(), 1e-12);
}

// The bimanual task with the view attached, on the SIMULATED device, on this
// thread: one record per tick, the device's joint angles in it, no allocation.
TEST(DeviceViewRecord, TheBimanualTaskPublishesOneRecordPerTickWithoutAllocating) {
  hb::SimulationConfig cfg;
  const BimanualHands hands = make_bimanual_hands("idle", cfg);
  hb::SimulatedBimanualDevice dev(cfg, hands.hands);
  BimanualTask task(std::array<HandEnvironment, device::kMaxEndEffectors>{});
  DeviceViewMailbox box;
  task.set_view(&box, &dev);
  servo::ModelSnapshot none;
  device::DeviceSample in;
  servo::TickOutput out;
  dev.read(in);
  task.tick(in, none, out);  // warm-up
  dev.write(out.command);
  test::count_allocations_on_this_thread(true);
  const std::uint64_t before = test::counted_allocations();
  for (int i = 0; i < 200; ++i) {
    dev.read(in);
    in.end_effectors = 2;
    out = servo::TickOutput{};
    task.tick(in, none, out);
    dev.write(out.command);
  }
  const std::uint64_t allocs = test::counted_allocations() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(box.published(), 201u);
  const DeviceViewRecord* r = box.take();
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->tick, 201u);
  EXPECT_TRUE(r->has_arms);
  EXPECT_EQ(r->end_effectors, 2);
  for (int a = 0; a < 2; ++a) {
    const auto k = static_cast<std::size_t>(a);
    // The joint angles the tick's sample was read at: the hand the device
    // reported is at their forward kinematics.
    EXPECT_EQ(r->position_H[k], in.ee[k].position_H);
    const Eigen::Isometry3d T_D_J7 =
        cfg.plant.rig.T_D_A[k] * kinematics::flange_pose(cfg.plant.rig.arm, r->q[k]);
    const Eigen::Vector3d e = T_D_J7 * hb::handle_spec(cfg.plant.handles[k]).T_J7_E.translation();
    EXPECT_LT((e - r->position_H[k]).norm(), 1e-9);
  }
}

}  // namespace
}  // namespace hemm::op
