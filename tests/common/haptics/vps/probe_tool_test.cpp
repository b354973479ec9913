// The robot's probe tool as a 6-DoF VPS tool (probe_tool.h) against closed
// forms: its pointshell's area and mass properties; at rest on an exact plane
// voxmap the displayed force is the coupling's static spring force and the
// contact force of the tip sphere pressed into a half-space
// (closed_forms.h); tilted, the displayed torque is the tip's force about the
// centre of mass (every tip point's force passes through the tip's centre);
// no voxmap gives nothing; a new voxmap resets the pair's state; the budget
// bounds the work; the replay reproduces the live ticks; no allocation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/probe_tool.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"

namespace vps = hemm::vps;

namespace {

// A box with its top face at z = 0.
vps::Voxmap plane_voxmap(double s) {
  const Eigen::Vector3d h(0.2, 0.2, 0.05);
  hemm::mesh::TriangleMesh m = hemm::mesh::make_box(h, 4);
  for (auto& v : m.vertices) v -= Eigen::Vector3d(0, 0, h.z());
  vps::VoxmapParams p;
  p.voxel_size = s;
  p.layers_in = p.layers_out = 6;
  vps::Voxmap vm;
  EXPECT_FALSE(vps::build_voxmap(m, p, &vm, nullptr));
  return vm;
}

vps::ProbeTool tool() {
  vps::ProbeTool t;
  EXPECT_FALSE(vps::make_probe_tool(vps::ProbeToolGeometry{}, &t));
  return t;
}

// An LWR-class end-effector (scripted_hands_limits in operator/vps/vps_task.h).
vps::ToolParams params(const vps::ProbeTool& t) {
  const vps::CouplingDeviceLimits d{
      .peak_force = 150, .max_stiffness = 5000, .renders_torque = true, .peak_torque = 25, .max_rot_stiffness = 300};
  vps::ToolParams p;
  p.coupling = vps::design_coupling(t.mass, t.inertia_com, d).params;
  p.contact.stiffness = 3e7;
  return p;
}

Eigen::Isometry3d goal_at(const Eigen::Vector3d& tip, double tilt_x = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T.translation() = tip;
  return T;
}

}  // namespace

TEST(ProbeTool, ShellAreaAndMassMatchTheClosedForms) {
  const vps::ProbeToolGeometry g;
  const vps::ProbeTool t = tool();
  const double a = g.tip_radius, r = g.rod_radius, L = g.rod_length, pi = std::numbers::pi;
  const double zj = std::sqrt(a * a - r * r);
  const double area = 2 * pi * a * (zj + a) + 2 * pi * r * (L - zj) + pi * r * r;
  EXPECT_NEAR(t.shell.total_weight, area, 1e-6 * area);  // float weights
  EXPECT_DOUBLE_EQ(t.mass, 0.21);
  // Centre of mass on the axis: rod (a cylinder from the junction to the end) against the tip sphere.
  EXPECT_NEAR(t.shell.reference_point.z(), g.rod_mass * 0.5 * (zj + L) / t.mass, 1e-12);
  EXPECT_EQ(t.shell.reference_point.head<2>().norm(), 0.0);
  // Every normal points into the tool: a point moved along it by a little stays inside.
  for (std::size_t i = 0; i < t.shell.size(); ++i) {
    const Eigen::Vector3d q = t.shell.point(i) + 1e-4 * t.shell.normal(i);
    const bool in_tip = q.norm() < a, in_rod = q.head<2>().norm() < r && q.z() > 0 && q.z() < L;
    EXPECT_TRUE(in_tip || in_rod) << i;
  }
  vps::ProbeToolGeometry bad;
  bad.rod_radius = 0.03;
  vps::ProbeTool u;
  const auto e = vps::make_probe_tool(bad, &u);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(e->message.find("thinner"), std::string::npos);
}

TEST(ProbeTool, RestingOnAnExactPlaneGivesTheCouplingsStaticForce) {
  const vps::Voxmap vm = plane_voxmap(0.0025);
  const vps::ProbeTool t = tool();
  const vps::ToolParams p = params(t);
  const double a = t.shell.point(0).norm();  // tip radius
  vps::ToolState s;
  vps::init_tool_state(t, &s);
  const double press = 0.006;  // the hand holds the tip 6 mm below the plane
  const Eigen::Isometry3d goal = goal_at(Eigen::Vector3d(0.01, -0.02, a - press));
  for (int i = 0; i < 4000; ++i) vps::probe_tool_tick(p, t, &vm, goal, &s);
  ASSERT_LT(s.body.linear_velocity.norm(), 1e-6);
  const double tip_z = vps::tool_pose_W(t, s).translation().z();
  const double depth = a - tip_z;
  // The coupling's static force: its spring over the hand's lead, exactly,
  // pushing the hand up; and the contact's.
  const double spring = p.coupling.k_lin * (goal.translation().z() - tip_z);
  EXPECT_NEAR(s.device.force.z(), -spring, 1e-6 * std::abs(spring));
  EXPECT_NEAR(s.device.force.z(), s.contact.on_shell.force.z(), 1e-6 * std::abs(spring));
  // Sideways and torque: only the quadrature's asymmetry (Fibonacci points).
  EXPECT_LT(s.device.force.head<2>().norm(), 2e-3 * std::abs(spring));
  EXPECT_LT(s.device.torque.norm(), 2e-3 * std::abs(spring) * t.shell.reference_point.z());
  // ...equal to the tip sphere pressed into a half-space at that depth (the
  // pointshell's quadrature and the 2.5 mm field: within 3 %).
  const double exact = vps::sphere_halfspace_force(p.contact.stiffness, a, depth);
  std::printf("rest: depth %.3f mm, displayed %.3f N, closed form %.3f N, coupling K %.0f N/m\n", depth * 1e3,
              s.device.force.z(), exact, p.coupling.k_lin);
  EXPECT_GT(depth, 0.5e-3);
  EXPECT_LT(depth, press);
  EXPECT_NEAR(s.device.force.z(), exact, 0.03 * exact);
}

TEST(ProbeTool, TiltedOnThePlaneTheTorqueIsTheTipForceAboutTheCentreOfMass) {
  const vps::Voxmap vm = plane_voxmap(0.0025);
  const vps::ProbeTool t = tool();
  const vps::ToolParams p = params(t);
  const double a = t.shell.point(0).norm();
  vps::ToolState s;
  vps::init_tool_state(t, &s);
  const Eigen::Isometry3d goal = goal_at(Eigen::Vector3d(0, 0, a - 0.005), 0.4);
  for (int i = 0; i < 6000; ++i) vps::probe_tool_tick(p, t, &vm, goal, &s);
  ASSERT_LT(s.body.angular_velocity.norm(), 1e-5);
  const Eigen::Isometry3d T = vps::tool_pose_W(t, s);
  const Eigen::Vector3d r = T.translation() - T * t.shell.reference_point;  // centre of mass -> tip centre
  const Eigen::Vector3d F = s.contact.on_shell.force;
  const Eigen::Vector3d expect = r.cross(F);
  std::printf("tilted: F %.3f N, torque %.4f N m (r x F %.4f)\n", F.norm(), s.device.torque.norm(), expect.norm());
  ASSERT_GT(expect.norm(), 0.01);
  EXPECT_NEAR((s.device.torque - expect).norm(), 0.0, 1e-3 * expect.norm());
  EXPECT_NEAR((s.contact.on_shell.torque - expect).norm(), 0.0, 1e-9 + 1e-6 * expect.norm());
}

TEST(ProbeTool, NoVoxmapGivesNothingAndANewVoxmapResetsThePairState) {
  const vps::Voxmap vm = plane_voxmap(0.005);
  const vps::Voxmap copy = vm;
  const vps::ProbeTool t = tool();
  const vps::ToolParams p = params(t);
  const double a = t.shell.point(0).norm();
  vps::ToolState s;
  vps::init_tool_state(t, &s);
  const Eigen::Isometry3d deep = goal_at(Eigen::Vector3d(0, 0, a - 0.004));
  for (int i = 0; i < 100; ++i) vps::probe_tool_tick(p, t, nullptr, deep, &s);
  EXPECT_EQ(s.device.force.norm(), 0.0);
  EXPECT_EQ(s.device.torque.norm(), 0.0);
  EXPECT_TRUE(vps::tool_pose_W(t, s).translation().isApprox(deep.translation(), 1e-12));
  for (int i = 0; i < 3000; ++i) vps::probe_tool_tick(p, t, &vm, deep, &s);
  EXPECT_EQ(s.voxmap_changes, 1u);
  const Eigen::Vector3d F = s.device.force;
  EXPECT_GT(F.z(), 1.0);  // pushes the hand up
  s.pair.seen[0] = 12345;  // something remembered from the old voxmap
  vps::probe_tool_tick(p, t, &copy, deep, &s);
  EXPECT_EQ(s.voxmap_changes, 2u);
  EXPECT_NE(s.pair.seen[0], 12345u);
  EXPECT_NEAR((s.device.force - F).norm(), 0.0, 1e-3);  // the same geometry: the same force
  // A non-finite goal: nothing displayed, the tool stays.
  const Eigen::Vector3d before = s.body.position;
  Eigen::Isometry3d bad = deep;
  bad.translation().x() = NAN;
  vps::probe_tool_tick(p, t, &vm, bad, &s);
  EXPECT_EQ(s.device.force.norm(), 0.0);
  EXPECT_EQ(s.body.position, before);
}

TEST(ProbeTool, BudgetBoundsTheWorkReplayReproducesTheTicksAndNothingAllocates) {
  const vps::Voxmap vm = plane_voxmap(0.0025);
  const vps::ProbeTool t = tool();
  vps::ToolParams p = params(t);
  const double a = t.shell.point(0).norm();
  // A hand path: down onto the plane, slide with a tilt, lift.
  std::vector<Eigen::Isometry3d> goals;
  for (int i = 0; i < 3000; ++i) {
    const double u = i / 3000.0;
    const double z = a + 0.01 - 0.016 * std::min(1.0, 3 * u) + (u > 0.8 ? 0.1 * (u - 0.8) : 0.0);
    goals.push_back(goal_at(Eigen::Vector3d(0.05 * u, 0.0, z), 0.3 * u));
  }
  vps::ToolState s;
  vps::init_tool_state(t, &s);
  std::vector<vps::Wrench> live;
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (const auto& g : goals) {
    vps::probe_tool_tick(p, t, &vm, g, &s);
    if (live.capacity() > live.size()) live.push_back(s.device);
  }
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  (void)live;
  // The replay is the same ticks.
  vps::ToolState s2;
  vps::init_tool_state(t, &s2);
  std::vector<vps::Wrench> ticks;
  double peak = 0;
  for (const auto& g : goals) {
    vps::probe_tool_tick(p, t, &vm, g, &s2);
    ticks.push_back(s2.device);
    peak = std::max(peak, s2.device.force.norm());
  }
  vps::ToolReplay rep;
  vps::replay_tool_path(p, t, vm, goals, {}, {}, &rep);
  ASSERT_EQ(rep.wrench.size(), goals.size());
  for (std::size_t i = 0; i < goals.size(); ++i) {
    ASSERT_EQ(rep.wrench[i].force, ticks[i].force) << i;
    ASSERT_EQ(rep.wrench[i].torque, ticks[i].torque) << i;
  }
  EXPECT_GT(peak, 2.0);
  // Time-critical: the work never exceeds the budget, and a coarser level stands in.
  p.budget = 60;
  vps::ToolState s3;
  vps::init_tool_state(t, &s3);
  int fewer = 0;
  for (const auto& g : goals) {
    vps::probe_tool_tick(p, t, &vm, g, &s3);
    // ... or the coarsest level's, which always completes.
    EXPECT_LE(s3.contact.nodes_visited + s3.contact.points_tested, std::max<std::int64_t>(60, vps::coarsest_level_work(t.shell)));
    EXPECT_GE(s3.contact.levels_completed, 1);
    if (s3.contact.levels_completed < t.shell.levels) ++fewer;
  }
  EXPECT_GT(fewer, 0);
}
