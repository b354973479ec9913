// VPS contact: culling, frame invariance, the bimanual cycle (allocation-
// free), thin walls against an exact plate reference, and the time-critical
// mode against its own full-resolution answer and the exact reference.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/sanitizer_build.h"

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

TEST(VpsContact, AStateOfAnotherPointShellIsIgnoredNotZeroed) {
  // A state sized for another pointshell (e.g. a model swapped under a task)
  // must neither index out of its arrays nor silence the contact: the call
  // is the stateless one, and the foreign state is left as it was.
  const auto scene = mesh::make_icosphere(0.1, 4);
  VoxmapParams vp;
  vp.voxel_size = 0.004;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap(scene, vp, &vm, nullptr));
  PointShellParams pp;
  pp.voxel_size = 0.004;
  PointShell box, ball;
  ASSERT_FALSE(build_pointshell(mesh::make_box({0.03, 0.02, 0.01}, 4), pp, Eigen::Vector3d::Zero(), &box));
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.02, 3), pp, Eigen::Vector3d::Zero(), &ball));
  ASSERT_NE(box.size(), ball.size());
  PairState foreign;
  init_pair_state(ball, &foreign);
  const PairState before = foreign;
  ContactParams cp;
  int touching = 0;
  for (int i = 0; i < 10; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.003 * i, -0.002 * i, 0.104 - 0.0005 * i);
    PairResult with_foreign, stateless;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), box, T, cp, &foreign, &with_foreign);
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), box, T, cp, nullptr, &stateless);
    EXPECT_EQ(with_foreign.contacts, stateless.contacts);
    EXPECT_EQ(with_foreign.on_shell.force, stateless.on_shell.force);
    EXPECT_EQ(with_foreign.on_shell.torque, stateless.on_shell.torque);
    touching += stateless.contacts > 0 ? 1 : 0;
  }
  EXPECT_GT(touching, 5);  // the poses do touch the sphere
  EXPECT_EQ(foreign.tick, before.tick);
  EXPECT_EQ(foreign.seen, before.seen);
  EXPECT_EQ(foreign.has_prev, before.has_prev);
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


// ---- thin walls -----------------------------------------------------------
// Reference (pressure model, the side the tool came from): a sphere whose
// lowest point is delta past the face it came through feels the force of the
// sphere against the half-space behind that face (sphere_halfspace_force),
// whatever the wall's thickness, along the face's outward normal. Zero
// before contact, no sideways force.

Eigen::Isometry3d at(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  return T;
}

// A plate of thickness t (in its frame faces z = 0 and z = -t, half-width
// `half`, n box cells a side), or an open sheet (z = 0, n_sheet cells a side)
// when t is 0, placed by T_V_wall.
mesh::TriangleMesh wall_mesh(const Eigen::Isometry3d& T_V_wall, double t, double half, int n, int n_sheet) {
  mesh::TriangleMesh wall;
  if (t > 0) {
    mesh::append_mesh(&wall, mesh::make_box({half, half, t / 2}, n), T_V_wall * at({0, 0, -t / 2}));
  } else {
    mesh::append_mesh(&wall, mesh::make_open_sheet(half, n_sheet), T_V_wall);
  }
  return wall;
}

struct SweepStats {
  double max_rel_err_shallow = 0;  // |F - F_ref| / F_ref for delta >= 0.3 mm
  double max_rel_err = 0;          // the same for delta >= 1 mm
  double max_side = 0;          // |F_xy| / |F|
  double early = 0;             // largest |F| before contact (N)
  double min_fz_in_contact = 1e300;  // along the approach normal, in contact (must stay > 0)
  int contacts = 0;
};

// A sphere swept (kinematically, 0.05 mm a tick) straight through the wall
// (its frame: faces z = 0 and z = -thickness, placed in the voxmap frame by
// T_V_wall) from one side to `beyond` past the other face, one pair state
// carried along; forces compared in the wall's frame.
SweepStats sweep(const Voxmap& vm, const Eigen::Isometry3d& T_V_wall, const PointShell& ps, double R, double K,
                 double thickness, bool from_above, const Eigen::Vector2d& xy, double beyond) {
  ContactParams cp;
  cp.stiffness = K;
  PairState state;
  init_pair_state(ps, &state);
  SweepStats st;
  const double start = 0.002, end = thickness + beyond;  // delta from -2 mm to past the far face
  for (double delta = -start; delta <= end; delta += 5e-5) {
    // Face z = 0 from above; face z = -thickness from below.
    const double zc = from_above ? R - delta : -thickness - R + delta;
    PairResult r;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T_V_wall * at({xy.x(), xy.y(), zc}),
                  cp, &state, &r);
    const Eigen::Vector3d F = T_V_wall.linear().transpose() * r.on_shell.force;
    const double fz = from_above ? F.z() : -F.z();
    const double ref = sphere_halfspace_force(K, R, delta);
    if (delta < -5e-5) {
      st.early = std::max(st.early, F.norm());
      continue;
    }
    if (delta > 1e-4) st.min_fz_in_contact = std::min(st.min_fz_in_contact, fz);
    if (r.contacts > 0) ++st.contacts;
    const double err = (F - Eigen::Vector3d(0, 0, from_above ? ref : -ref)).norm() / std::max(ref, 1e-300);
    if (delta >= 3e-4) {
      st.max_rel_err_shallow = std::max(st.max_rel_err_shallow, err);
      st.max_side = std::max(st.max_side, F.head<2>().norm() / F.norm());
    }
    if (delta >= 1e-3) st.max_rel_err = std::max(st.max_rel_err, err);
  }
  return st;
}

TEST(VpsThinWall, PlatesThinnerThanAVoxelAreNotTunnelledAndMatchTheExactPlateForce) {
  // Plates of 0.35 to 0.9 voxels (closed, signed field) and an open sheet
  // (unsigned), tilted off the grid axes, at three voxel sizes; a sphere
  // (R 20 mm) swept through from
  // above and from below, at off-grid lateral positions, until its lowest
  // point is 2 mm past the far face. None of these sizes was used to develop
  // the sheet model (that used the 0.8 mm wall at 2 mm voxels in the
  // peg-in-hole test). A 20 mm plate (no sheet: the ordinary field) is the
  // control: the bounds are those of the pointshell's 1 mm quadrature of the
  // contact cap, the same for both.
  // Bound: |F - F_ref| <= 6 % of F_ref from 0.3 mm deep (cap 7 mm across,
  // about 40 points), <= 2 % from 1 mm deep (cap 12.6 mm across).
  const double R = 0.02, K = 1e8;
  const auto sphere = mesh::make_icosphere(R, 5);
  PointShellParams pp;
  pp.voxel_size = 0.001;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(sphere, pp, Eigen::Vector3d::Zero(), &ps));
  std::printf("\n  voxel  | wall           | from  | |F| error >= 0.3 mm | >= 1 mm | max sideways | early |F| | min F_n\n");
  // The sanitizer pass: the middle size alone (tests/sanitizer_build.h; 31 s there with all three).
  const std::vector<double> voxels = hemm::test::sanitizer_cases<double>({0.0015, 0.0025, 0.004}, {1});
  for (const double s : voxels) {
    for (const double frac : {0.35, 0.6, 0.9, 0.0, -1.0}) {
      const double t = frac >= 0 ? frac * s : 0.02;
      Eigen::Isometry3d T_V_wall = at({0.0003, -0.0007, 0.0});
      T_V_wall.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 0).normalized()).toRotationMatrix();
      const mesh::TriangleMesh wall = wall_mesh(T_V_wall, t, 0.06, 3, 12);
      VoxmapParams vp;
      vp.voxel_size = s;
      // The sweep goes 2 mm past the far face of the thin walls: layers for that depth.
      vp.layers_out = vp.layers_in = layers_for_depth(frac >= 0 ? t + 0.002 : 0.004, s);
      Voxmap vm;
      ASSERT_FALSE(build_voxmap(wall, vp, &vm, nullptr));
      EXPECT_EQ(vm.sheet_voxels > 0, frac >= 0);
      for (const bool above : {true, false}) {
        const Eigen::Vector2d xy = above ? Eigen::Vector2d(0.0011, -0.0004) : Eigen::Vector2d(-0.0017, 0.0009);
        const SweepStats st = sweep(vm, T_V_wall, ps, R, K, t, above, xy, frac >= 0 ? 0.002 : -t + 0.004);
        std::printf("  %.1f mm | %-7s %.2f mm | %s | %18.2f%% | %6.2f%% | %11.2f%% | %7.4f N | %7.3f N\n", s * 1e3,
                    frac > 0 ? "plate" : (frac == 0 ? "sheet" : "control"), t * 1e3, above ? "above" : "below",
                    100 * st.max_rel_err_shallow, 100 * st.max_rel_err, 100 * st.max_side, st.early,
                    st.min_fz_in_contact);
        // No tunnelling, and never the wrong way: the force along the approach
        // normal stays positive all the way to 2 mm past the far face.
        EXPECT_GT(st.min_fz_in_contact, 0.0) << s << " " << t << " " << above;
        EXPECT_LT(st.max_rel_err_shallow, 0.06) << s << " " << t << " " << above;
        EXPECT_LT(st.max_rel_err, 0.02) << s << " " << t << " " << above;
        // No sideways force where symmetry gives none, no early contact.
        EXPECT_LT(st.max_side, 0.01) << s << " " << t << " " << above;
        EXPECT_EQ(st.early, 0.0) << s << " " << t << " " << above;
      }
    }
  }
}

// ---- pushed through and out ----------------------------------------------------
// A sphere pushed at constant speed (0.05 mm a tick, 50 mm/s at 1 kHz)
// straight through a wall (wall frame: faces z = 0 and z = -thickness) and out
// the other side, one pair state carried all the way, then pulled back into
// the wall from the side it now is on.

struct PassStats {
  int apart_ticks = 0;          // ticks with no overlap after the sphere went through
  double apart_force = 0;       // largest |F| on those ticks (N)
  int apart_contacts = 0;       // largest contact count on those ticks
  int back_ticks = 0;           // ticks pulled back with the far face 0.3-2 mm into the sphere
  double back_err = 0;          // largest |F - F_ref| / F_ref there (F_ref: from the face it now comes through)
  double back_min_resist = 1e300;  // smallest force against the pull-back there (N; must stay > 0)
};

// `out_by`: how far past the far face the sphere's nearest point goes before
// it is pulled back.
PassStats pass_through(const Voxmap& vm, const Eigen::Isometry3d& T_V_wall, const PointShell& ps, double R, double K,
                       double thickness, bool from_above, const Eigen::Vector2d& xy, double out_by) {
  ContactParams cp;
  cp.stiffness = K;
  PairState state;
  init_pair_state(ps, &state);
  PassStats st;
  // u: the sphere centre's distance travelled along the push, from 1 mm
  // before contact; the push direction is -z from above, +z from below.
  const double step = 5e-5, through = 2 * R + thickness + 0.001 + out_by;
  const double sign = from_above ? 1.0 : -1.0;
  auto centre_z = [&](double u) { return from_above ? R + 0.001 - u : -thickness - R - 0.001 + u; };
  auto evaluate = [&](double zc, PairResult* r) {
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps,
                  T_V_wall * at({xy.x(), xy.y(), zc}), cp, &state, r);
    return Eigen::Vector3d(T_V_wall.linear().transpose() * r->on_shell.force);
  };
  // Push through and out; more than 2 mm out, five times as fast (the
  // layers reach up to 46 mm here).
  double gap = 0;
  for (double u = 0; u <= through; u += gap > 0.002 ? 5 * step : step) {
    const double zc = centre_z(u);
    PairResult r;
    const Eigen::Vector3d F = evaluate(zc, &r);
    // Out the far side by more than 10 um: a sheet's normal is stored to
    // 1/32767, which tilts its plane by up to ~3e-5 across the sphere.
    gap = from_above ? -thickness - (zc + R) : zc - R;
    if (gap > 1e-5) {
      ++st.apart_ticks;
      st.apart_force = std::max(st.apart_force, F.norm());
      st.apart_contacts = std::max(st.apart_contacts, r.contacts);
    }
  }
  // Pulled back: the far face is now the face it comes through (again five
  // times as fast until 2 mm from it).
  double delta = -out_by;
  for (double u = through; u >= through - out_by - 0.003; u -= delta < -0.002 ? 5 * step : step) {
    const double zc = centre_z(u);
    PairResult r;
    const Eigen::Vector3d F = evaluate(zc, &r);
    delta = from_above ? zc + R + thickness : R - zc;  // past the face it now comes through
    const double ref = sphere_halfspace_force(K, R, delta);
    const double resist = -sign * F.z();  // the pull-back is along +z from above: resisted along -z
    if (delta >= 3e-4 && delta <= 0.002) {
      ++st.back_ticks;
      st.back_err = std::max(st.back_err, (F - Eigen::Vector3d(0, 0, -sign * ref)).norm() / ref);
      st.back_min_resist = std::min(st.back_min_resist, resist);
    }
    if (delta < -1e-5) {
      ++st.apart_ticks;
      st.apart_force = std::max(st.apart_force, F.norm());
      st.apart_contacts = std::max(st.apart_contacts, r.contacts);
    }
  }
  return st;
}

TEST(VpsThinWall, NoForceOnceTheSpherePushedThroughNoLongerOverlapsTheWall) {
  // Plates of 0.6 and 0.9 mm and an open sheet, tilted off the grid axes, at
  // 1, 2 and 4 mm voxels; a 14 mm sphere with the default 3 distance layers
  // and a 9 mm sphere with layers deeper than the sphere (so its whole near
  // side is still in the layers when it comes out); pushed from above and
  // from below. (The case the model was fixed on was a 20 mm sphere through a
  // 1 mm plate: none of these.) Once no part of the sphere overlaps the wall
  // the force and the contact count are exactly zero on every tick, both
  // right after it comes out and while the layers still hold its points;
  // pulled back, it is felt from the face it now comes through: against the
  // pull, within 10 % of the sphere/half-space force behind that face from
  // 0.3 mm deep (the 1 mm pointshell's quadrature of caps from 4.6 mm
  // across; 6.6-7.6 % measured), whether it comes back right after coming
  // out (1 mm) or after leaving the layers (deeper than them). Before the
  // change: up to 1,105 N and 2,365 contacts once apart, and pulled back
  // right after coming out, up to 305 N through the wall.
  const double K = 1e8;
  PointShellParams pp;
  pp.voxel_size = 0.001;
  PointShell small, large;  // R 9 and 14 mm
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.009, 5), pp, Eigen::Vector3d::Zero(), &small));
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(0.014, 5), pp, Eigen::Vector3d::Zero(), &large));
  std::printf("\n  voxel  | wall           | layers | R     | from  | out by  | apart: ticks  max |F|  contacts | "
              "back: |F| error  min F against\n");
  // Under the sanitizers one voxel size (2 mm) of the three: the same code (tests/sanitizer_build.h).
  const std::vector<double> voxels = hemm::test::sanitizer_cases<double>({0.001, 0.002, 0.004}, {1});
  for (const double s : voxels) {
    for (const double t : {0.0006, 0.0009, 0.0}) {
      for (const bool deep : {false, true}) {
        Eigen::Isometry3d T_V_wall = at({-0.0004, 0.0009, 0.0002});
        T_V_wall.linear() = Eigen::AngleAxisd(0.25, Eigen::Vector3d(2, -1, 0).normalized()).toRotationMatrix();
        const mesh::TriangleMesh wall = wall_mesh(T_V_wall, t, 0.03, 2, 6);
        VoxmapParams vp;
        vp.voxel_size = s;
        vp.layers_out = vp.layers_in = deep ? layers_for_depth(0.03, s) : 3;
        Voxmap vm;
        ASSERT_FALSE(build_voxmap(wall, vp, &vm, nullptr));
        ASSERT_GT(vm.sheet_voxels, 0u);  // thin: the sheet model, not the field
        const double R = deep ? 0.009 : 0.014;
        const PointShell& ps = deep ? small : large;
        for (const bool above : {true, false}) {
          const Eigen::Vector2d xy = above ? Eigen::Vector2d(0.0013, -0.0006) : Eigen::Vector2d(-0.0008, 0.0017);
          // Pulled back 1 mm out, or once out of the layers (the sheet's
          // layers count from its surface voxels, up to two voxels thick).
          for (const double out_by : {0.001, (vp.layers_out + 2) * s + 0.002}) {
            const PassStats st = pass_through(vm, T_V_wall, ps, R, K, t, above, xy, out_by);
            std::printf("  %.0f mm   | %-7s %.2f mm | %6d | %.0f mm | %s | %4.1f mm | %12d %9.4f N %9d | %14.2f%% "
                        "%11.3f N\n",
                        s * 1e3, t > 0 ? "plate" : "sheet", t * 1e3, vp.layers_out, R * 1e3,
                        above ? "above" : "below", out_by * 1e3, st.apart_ticks, st.apart_force,
                        st.apart_contacts, 100 * st.back_err, st.back_min_resist);
            const std::string where = std::to_string(s) + " " + std::to_string(t) + " " + std::to_string(R) +
                                      (above ? " above" : " below") + " out by " + std::to_string(out_by) +
                                      " layers " + std::to_string(vp.layers_out);
            EXPECT_GT(st.apart_ticks, 20) << where;
            EXPECT_EQ(st.apart_force, 0.0) << where;
            EXPECT_EQ(st.apart_contacts, 0) << where;
            EXPECT_GT(st.back_ticks, 20) << where;
            EXPECT_GT(st.back_min_resist, 0.0) << where;
            EXPECT_LT(st.back_err, 0.10) << where;
          }
        }
      }
    }
  }
}

// ---- time-critical mode -------------------------------------------------------

TEST(VpsTimeCritical, BudgetBoundsTheWorkAndTheForceDegradesGracefully) {
  // Both tools are spheres (R 30 mm and 25 mm, 1.5 mm pointshells, four
  // levels) pressed into a slab (top z = 0) 2.5 and 1.5 mm deep, and into
  // each other 1 mm: exact references for the two scene pairs.
  const double K = 1e8;
  mesh::TriangleMesh slab;
  mesh::append_mesh(&slab, mesh::make_box({0.15, 0.15, 0.02}, 4), at({0, 0, -0.02}));
  VoxmapParams vp;
  vp.voxel_size = 0.003;
  Voxmap scene;
  ASSERT_FALSE(build_voxmap(slab, vp, &scene, nullptr));
  const double Rr = 0.03, Rl = 0.025;
  PointShellParams pp;
  pp.voxel_size = 0.0015;
  PointShell ps_r, ps_l;
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(Rr, 5), pp, Eigen::Vector3d::Zero(), &ps_r));
  ASSERT_FALSE(build_pointshell(mesh::make_icosphere(Rl, 5), pp, Eigen::Vector3d::Zero(), &ps_l));
  EXPECT_EQ(ps_r.levels, 4);
  Voxmap vm_l;
  VoxmapParams lp;
  lp.voxel_size = 0.0015;
  ASSERT_FALSE(build_voxmap(mesh::make_icosphere(Rl, 5), lp, &vm_l, nullptr));
  BimanualModel model;
  model.scene = &scene;
  model.right = {nullptr, &ps_r};
  model.left = {&vm_l, &ps_l};
  model.params.stiffness = K;
  const double dr = 0.0025, dl = 0.0015;
  const Eigen::Isometry3d T_W_R = at({0.0013, -0.0004, Rr - dr});
  const Eigen::Isometry3d T_W_L = at({Rr + Rl - 0.001 + 0.0013, -0.0004, Rl - dl});
  const double ref_r = sphere_halfspace_force(K, Rr, dr), ref_l = sphere_halfspace_force(K, Rl, dl);
  BimanualState state;
  init_bimanual_state(model, &state);
  BimanualData full, tc;
  evaluate_bimanual(model, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, &state, &full);
  // Unlimited budget: the full cycle's wrench (float sums in another order).
  evaluate_bimanual_budgeted(model, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, kUnlimitedWork, &state, &tc);
  EXPECT_EQ(tc.levels_completed, 4);
  for (const auto* w : {&full.right_total, &full.left_total}) {
    const Wrench& t = w == &full.right_total ? tc.right_total : tc.left_total;
    EXPECT_NEAR((t.force - w->force).norm(), 0.0, 1e-6 * w->force.norm());
    EXPECT_NEAR((t.torque - w->torque).norm(), 0.0, 1e-6 * (w->torque.norm() + w->force.norm() * 0.03));
  }
  const double err_full = std::max(std::abs(full.right_scene.on_shell.force.z() - ref_r) / ref_r,
                                   std::abs(full.left_scene.on_shell.force.z() - ref_l) / ref_l);
  const std::int64_t all = tc.work;  // the unlimited time-critical cycle's work (its own level trees)
  std::printf("\n  budget            | work  | levels | scene pairs' |F| error (worse) | right-left |F|\n");
  std::printf("  full cycle        | %5lld |      4 | %31.2f%% | %.3f N\n", static_cast<long long>(full.work),
              100 * err_full, full.right_left.on_shell.force.norm());
  // No budget at all: the coarsest round still completes (its work is the
  // least a call does).
  evaluate_bimanual_budgeted(model, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, 0, &state, &tc);
  EXPECT_EQ(tc.levels_completed, 1);
  EXPECT_EQ(tc.right_scene.levels_completed, 1);
  EXPECT_EQ(tc.right_left.levels_completed, 1);
  const std::int64_t coarsest = tc.work;
  EXPECT_GT(coarsest, 0);
  EXPECT_LT(coarsest, all / 4);
  int prev_levels = 1;
  for (const double frac : {0.01, 0.03, 0.06, 0.12, 0.25, 0.5, 0.75, 1.0}) {
    const auto budget = static_cast<std::int64_t>(frac * static_cast<double>(all));
    evaluate_bimanual_budgeted(model, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, budget, &state, &tc);
    const double err = std::max(std::abs(tc.right_scene.on_shell.force.z() - ref_r) / ref_r,
                                std::abs(tc.left_scene.on_shell.force.z() - ref_l) / ref_l);
    std::printf("  %5.0f%% (%5lld) | %5lld | %6d | %31.2f%% | %.3f N\n", 100 * frac, static_cast<long long>(budget),
                static_cast<long long>(tc.work), tc.levels_completed, 100 * err, tc.right_left.on_shell.force.norm());
    // Never more work than the budget (or the coarsest round, which always
    // runs); more budget, never fewer levels.
    EXPECT_LE(tc.work, std::max(budget, coarsest));
    EXPECT_GE(tc.levels_completed, prev_levels);
    prev_levels = tc.levels_completed;
    // Graceful: once a level is complete the force is a coarser quadrature
    // of the same integral (contact caps of 8.7 and 12 mm radius here, level
    // spacings 12, 6, 3, 1.5 mm), not nothing and not garbage.
    if (tc.levels_completed >= 2) {
      EXPECT_LT(err, 0.5) << budget;
    }
  }
  EXPECT_EQ(prev_levels, 4);
  EXPECT_LT(err_full, 0.02);
}

TEST(VpsTimeCritical, LevelsAreNestedAndEachCarriesTheWholeArea) {
  const auto tool = mesh::make_box({0.04, 0.025, 0.015}, 6);
  PointShellParams pp;
  pp.voxel_size = 0.002;
  PointShell ps;
  ASSERT_FALSE(build_pointshell(tool, pp, Eigen::Vector3d::Zero(), &ps));
  ASSERT_GE(ps.levels, 3);
  const double area = mesh::mesh_area(tool);
  std::size_t members = 0;
  for (int l = 0; l < ps.levels; ++l) {
    double sum = 0;
    std::size_t count = 0;
    for (std::size_t i = 0; i < ps.size(); ++i) {
      const float w = ps.level_weight[i * kMaxShellLevels + static_cast<std::size_t>(l)];
      // A point has a weight from its own level on (nested levels), none before.
      EXPECT_EQ(w > 0, ps.point_level[i] <= l) << i << " level " << l;
      sum += w;
      count += ps.point_level[i] <= l ? 1 : 0;
    }
    EXPECT_NEAR(sum, area, 1e-5 * area) << "level " << l;
    EXPECT_GT(count, members);  // each level adds points
    members = count;
    // Level l's spacing is twice level l+1's.
    EXPECT_NEAR(ps.level[static_cast<std::size_t>(l)].spacing, pp.voxel_size * std::ldexp(1.0, ps.levels - 1 - l), 1e-12);
  }
  EXPECT_EQ(members, ps.size());
}

}  // namespace
}  // namespace hemm::vps

namespace hemm::vps {
namespace {

// Two unit-weight points pressed into the flat top of a box (z = 0.1), one
// above its x < 0 half, whose voxels are flagged inferred: the inferred
// force is exactly the first point's K p n, the share p1 / (p1 + p2), and a
// stiffness scale scales that point's force alone. The field of a box face
// is exact (the voxmap's distances are exact and the interpolant is exact
// for planes), so p is the point's depth below z = 0.1.
TEST(VpsInferred, ShareAndStiffnessScaleAreExactOnTwoPoints) {
  VoxmapParams vp;
  vp.voxel_size = 0.005;
  Voxmap vm;
  ASSERT_FALSE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), vp, &vm, nullptr));
  int flagged = 0;
  for (int z = 0; z < vm.dims().z(); ++z)
    for (int y = 0; y < vm.dims().y(); ++y)
      for (int x = 0; x < vm.dims().x(); ++x) {
        const Eigen::Vector3i v(x, y, z);
        const std::int32_t bi = vm.top[block_linear(vm, Eigen::Vector3i(x >> kBlockShift, y >> kBlockShift, z >> kBlockShift))];
        if (bi < 0 || voxel_centre(vm, v).x() >= 0.0) continue;
        vm.blocks[static_cast<std::size_t>(bi)].v[static_cast<std::size_t>(voxel_in_block(v))].flags |= kFlagInferred;
        ++flagged;
      }
  ASSERT_GT(flagged, 0);
  // Not at voxel centres, not symmetric: depths 1.3 mm and 3.1 mm.
  const double d1 = 0.0013, d2 = 0.0031;
  const std::vector<Eigen::Vector3d> pts = {{-0.0312, 0.0117, 0.1 - d1}, {0.0277, -0.0191, 0.1 - d2}};
  const std::vector<Eigen::Vector3d> nrm = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
  const std::vector<double> w = {1.0, 1.0};
  PointShell ps;
  ASSERT_FALSE(build_pointshell_from_points(pts, nrm, w, 0.005, 1, 1 << 30, Eigen::Vector3d::Zero(), &ps));
  for (const double scale : {1.0, 0.4}) {
    ContactParams cp;
    cp.stiffness = 1000.0;
    cp.inferred_stiffness_scale = scale;
    PairResult r;
    evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, Eigen::Isometry3d::Identity(), cp,
                  nullptr, &r);
    ASSERT_EQ(r.contacts, 2);
    EXPECT_EQ(r.inferred_contacts, 1);
    EXPECT_NEAR(r.inferred_force.z(), scale * cp.stiffness * d1, 1e-5);
    EXPECT_NEAR(r.on_shell.force.z(), scale * cp.stiffness * d1 + cp.stiffness * d2, 1e-5);
    EXPECT_NEAR(inferred_share(r), scale * d1 / (scale * d1 + d2), 1e-6);
    std::printf("scale %.1f: F %.6f N, inferred %.6f N, share %.6f (exact %.6f)\n", scale, r.on_shell.force.z(),
                r.inferred_force.z(), inferred_share(r), scale * d1 / (scale * d1 + d2));
  }
  // Nothing flagged: no inferred force; the same total at scale 1.
  Voxmap plain;
  ASSERT_FALSE(build_voxmap(mesh::make_box({0.1, 0.1, 0.1}), vp, &plain, nullptr));
  ContactParams cp;
  cp.stiffness = 1000.0;
  cp.inferred_stiffness_scale = 0.4;
  PairResult r;
  evaluate_pair(plain, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, Eigen::Isometry3d::Identity(), cp,
                nullptr, &r);
  EXPECT_EQ(r.inferred_contacts, 0);
  EXPECT_EQ(inferred_share(r), 0.0);
  EXPECT_NEAR(r.on_shell.force.z(), cp.stiffness * (d1 + d2), 1e-5);
  // The budgeted (time-critical) path reports the same, without allocating.
  cp.inferred_stiffness_scale = 1.0;
  PairResult b;
  test::count_allocations_on_this_thread(true);
  const auto before = test::counted_allocations();
  evaluate_pair_budgeted(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, Eigen::Isometry3d::Identity(),
                         cp, 1000, nullptr, &b);
  const auto after = test::counted_allocations();
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after, before);
  EXPECT_NEAR(b.inferred_force.z(), cp.stiffness * d1, 1e-5);  // level weights are floats
}

}  // namespace
}  // namespace hemm::vps
