// The paper's peg-in-hole: a pins object (right hand) inserted into a holes
// object (left hand) with 1 mm clearance, both moving through 6-DoF virtual
// coupling, above a static table; the three-pair cycle every 1 ms tick. Also:
// thin walls (thinner than a voxel) and open meshes are not tunnelled.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "common/haptics/vps/coupling.h"
#include "common/haptics/vps/scenes.h"
#include "common/mesh/primitives.h"
#include "tests/common/haptics/vps/test_devices.h"

namespace hemm::vps {
namespace {

constexpr double mm = 1e-3;

Eigen::Isometry3d at(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

struct Tool {
  Voxmap voxmap;
  PointShell shell;
  mesh::MassProperties mass;
  CouplingParams coupling;
  RigidBodyState state;
  Eigen::Isometry3d T_C_M = Eigen::Isometry3d::Identity();  // mesh frame in the centre-of-mass frame
  Eigen::Isometry3d mesh_pose() const { return state.pose() * T_C_M; }
};

void make_tool(const mesh::TriangleMesh& m, double s, double shell_s, int layers, double density, Tool* t) {
  mesh::TriangleMesh valid;
  mesh::MeshReport rep;
  ASSERT_FALSE(mesh::validate_mesh(m, {}, &valid, &rep));
  ASSERT_TRUE(rep.watertight());
  t->mass = mesh::compute_mass_properties(valid, density);
  VoxmapParams vp;
  vp.voxel_size = s;
  vp.layers_in = vp.layers_out = layers;
  ASSERT_FALSE(build_voxmap(m, vp, &t->voxmap, nullptr));
  PointShellParams pp;
  pp.voxel_size = shell_s;
  ASSERT_FALSE(build_pointshell(m, pp, t->mass.centre_of_mass, &t->shell));
  t->coupling = design_coupling(t->mass.mass, t->mass.inertia_com, test::lwr_like()).params;
  t->T_C_M.translation() = -t->mass.centre_of_mass;
}

TEST(VpsPegInHole, BimanualInsertionCompletesStablyWithoutTunnelling) {
  // The paper's peg-in-hole with its scripted hands: voxmaps at 1 mm (the
  // clearance), pointshells at 1.5 mm, LWR-class couplings.
  const BimanualScene scene = make_peg_in_hole_scene();
  const double s = 1.0 * mm;
  ContactParams cp;
  cp.stiffness = 1e7;
  // Distance layers from the coupling's maximum expected penetration: the
  // hands lead the objects by at most the 2 mm press plus 3 mm of lag; the
  // smallest patch that must hold that force is the plate on the block
  // (2,800 mm^2).
  const double lead = 5 * mm, patch = 2.8e-3;
  const CouplingParams probe = design_coupling(0.3, Eigen::Matrix3d::Identity() * 1e-4, test::lwr_like()).params;
  const double p_max = max_expected_penetration(probe, lead, test::lwr_like().peak_force, cp.stiffness * patch);
  const int layers = layers_for_depth(p_max, s);
  std::printf("max expected penetration %.2f mm -> %d distance layers at %.1f mm voxels\n", p_max / mm, layers, s / mm);
  Tool pins, holes;
  make_tool(scene.right, s, 1.5 * mm, layers, 7800, &pins);
  make_tool(scene.left, s, 1.5 * mm, layers, 7800, &holes);
  Voxmap table;
  {
    VoxmapParams vp;
    vp.voxel_size = 2 * mm;
    vp.layers_in = vp.layers_out = layers_for_depth(p_max, vp.voxel_size);
    ASSERT_FALSE(build_voxmap(scene.scene, vp, &table, nullptr));
  }
  // The contact stiffness the tools see stays within the integration's limit
  // for the largest contact patch (the plate on the block).
  ASSERT_LT(cp.stiffness * patch, max_contact_stiffness(pins.coupling));
  BimanualModel model;
  model.scene = &table;
  model.right = {&pins.voxmap, &pins.shell};
  model.left = {&holes.voxmap, &holes.shell};
  model.params = cp;
  // Hands (mesh-frame poses) to device poses of the centre-of-mass frames,
  // velocities by differences of the scripted path.
  const double dt = 1e-3;
  auto device = [&](double t, const Tool& tool, bool right, Eigen::Vector3d* v) {
    auto at_t = [&](double tt) {
      const BimanualPoses h = peg_in_hole_hands(tt);
      return (right ? h.right : h.left) * tool.T_C_M.inverse();
    };
    const Eigen::Isometry3d T = at_t(t);
    *v = (at_t(t + dt).translation() - T.translation()) / dt;
    return T;
  };
  Eigen::Vector3d v0;
  pins.state.position = device(0, pins, true, &v0).translation();
  pins.state.orientation = Eigen::Quaterniond(device(0, pins, true, &v0).linear());
  holes.state.position = device(0, holes, false, &v0).translation();
  const int total = static_cast<int>(kPegInHoleDuration / dt);
  const int insert_ticks = total - 500;  // the path has reached its end by then
  BimanualData data;
  BimanualState state;
  init_bimanual_state(model, &state);
  double max_pen = 0, max_lateral = 0, max_speed = 0;
  double energy_hold_start = 0, energy_end = 0, max_ke_late = 0;
  const double speed = 0.03;
  for (int tick = 0; tick < total; ++tick) {
    Eigen::Vector3d v_r, v_l;
    const Eigen::Isometry3d dev_r = device(tick * dt, pins, true, &v_r);
    const Eigen::Isometry3d dev_l = device(tick * dt, holes, false, &v_l);
    evaluate_bimanual(model, Eigen::Isometry3d::Identity(), pins.mesh_pose(), holes.mesh_pose(), &state, &data);
    Wrench dr, dl;
    step_virtual_coupling(pins.coupling, dev_r, v_r, Eigen::Vector3d::Zero(), data.right_total, &pins.state, &dr);
    step_virtual_coupling(holes.coupling, dev_l, v_l, Eigen::Vector3d::Zero(), data.left_total, &holes.state, &dl);
    max_pen = std::max({max_pen, data.right_left.max_penetration, data.right_scene.max_penetration,
                        data.left_scene.max_penetration});
    // Pins axis relative to the holes: lateral offset in the holes' frame.
    const Eigen::Vector3d rel = holes.mesh_pose().inverse() * pins.mesh_pose().translation();
    if (rel.z() < 15 * mm + 25 * mm) max_lateral = std::max(max_lateral, std::hypot(rel.x(), rel.y()));
    max_speed = std::max(max_speed, pins.state.linear_velocity.norm());
    const double energy = kinetic_energy(pins.coupling, pins.state) + kinetic_energy(holes.coupling, holes.state) +
                          coupling_potential(pins.coupling, pins.state, dev_r) +
                          coupling_potential(holes.coupling, holes.state, dev_l);
    if (tick == insert_ticks + 150) energy_hold_start = energy;
    if (tick > insert_ticks + 300)
      max_ke_late = std::max(max_ke_late, kinetic_energy(pins.coupling, pins.state) +
                                              kinetic_energy(holes.coupling, holes.state));
    energy_end = energy;
  }
  const Eigen::Vector3d rel = holes.mesh_pose().inverse() * pins.mesh_pose().translation();
  std::printf("peg-in-hole: %d ticks, final pins frame %.3f %.3f %.3f mm in holes frame, max penetration %.3f mm,\n"
              "  max lateral offset %.3f mm, max pins speed %.3f m/s, energy hold start %.3g J end %.3g J, "
              "late KE %.3g J, contacts right-left %d\n",
              total, rel.x() / mm, rel.y() / mm, rel.z() / mm, max_pen / mm, max_lateral / mm, max_speed,
              energy_hold_start, energy_end, max_ke_late, data.right_left.contacts);
  // Completed: the plate rests on the block (frame z = 15 mm minus a small penetration).
  EXPECT_NEAR(rel.z(), 15 * mm, 0.8 * mm);
  EXPECT_LT(std::hypot(rel.x(), rel.y()), 1.0 * mm + max_pen);
  EXPECT_GT(data.right_left.contacts, 0);
  // No tunnelling: penetrations stay well below the clearance and the wall,
  // and within the distance layers chosen for them.
  EXPECT_LT(max_pen, 0.8 * mm);
  EXPECT_LT(max_pen, p_max + 0.1 * mm);
  EXPECT_LT(max_lateral, 1.5 * mm);
  // No jamming or numerical shaking: speeds stay near the scripted speed.
  EXPECT_LT(max_speed, 3 * speed);
  // No energy growth while holding still.
  EXPECT_LE(energy_end, energy_hold_start * 1.01 + 1e-6);
  EXPECT_LT(max_ke_late, 1e-5);
}

// A tool box pushed by its coupled device through a wall (closed but thinner
// than a voxel, or an open sheet): the wall holds it.
void thin_wall_holds(const mesh::TriangleMesh& wall, const char* name) {
  const double s = 2 * mm;
  Voxmap vm;
  VoxmapParams vp;
  vp.voxel_size = s;
  ASSERT_FALSE(build_voxmap(wall, vp, &vm, nullptr));
  PointShell ps;
  PointShellParams pp;
  pp.voxel_size = s;
  ASSERT_FALSE(build_pointshell(mesh::make_box({0.01, 0.01, 0.01}, 4), pp, Eigen::Vector3d::Zero(), &ps));
  CouplingParams cpl = design_coupling(0.5, Eigen::Matrix3d::Identity() * 1e-4, test::lwr_like()).params;
  ContactParams cp;
  cp.stiffness = 2e8;  // 8e4 N/m over the 20 x 20 mm face
  ASSERT_LT(cp.stiffness * 4e-4, max_contact_stiffness(cpl));
  RigidBodyState st;
  st.position = Eigen::Vector3d(0.001, 0.0007, 0.03);
  const double speed = 0.1;
  double min_bottom = 1;
  PairState pair;
  init_pair_state(ps, &pair);
  for (int tick = 0; tick < 1200; ++tick) {
    const double z = std::max(-0.03, 0.03 - speed * tick * 1e-3);  // ends 30 mm past the wall
    const Eigen::Vector3d v(0, 0, z > -0.03 ? -speed : 0.0);
    PairResult r;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, st.pose(), cp, &pair, &r);
    step_virtual_coupling(cpl, at({0.001, 0.0007, z}), v, Eigen::Vector3d::Zero(), r.on_shell, &st, nullptr);
    min_bottom = std::min(min_bottom, st.position.z() - 0.01);
  }
  std::printf("%s: lowest tool bottom %.3f mm (wall top at 0), device 30 mm below\n", name, min_bottom / mm);
  EXPECT_GT(min_bottom, -s) << name;
}

TEST(VpsPegInHole, WallsThinnerThanAVoxelAndOpenSheetsAreNotTunnelled) {
  mesh::TriangleMesh wall;  // 0.8 mm thick: 0.4 voxel
  mesh::append_mesh(&wall, mesh::make_box({0.05, 0.05, 0.0004}, 4), at({0, 0, -0.0004}));
  thin_wall_holds(wall, "closed wall 0.8 mm (0.4 voxel)");
  thin_wall_holds(mesh::make_open_sheet(0.05, 10), "open sheet (unsigned fallback)");
}

}  // namespace
}  // namespace hemm::vps
