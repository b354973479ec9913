// Accuracy of VPS forces against closed forms (pressure model: the force on
// the tool is K * integral over the tool's penetrating surface of p n dA, with
// p the depth of the surface point in the scene and n the tool's inward
// normal). Prints a table of magnitude error per voxel size and asserts the
// direction (within 2 degrees) and a falling error trend. The sanitizer pass
// takes one voxel size of each sweep (tests/sanitizer_build.h): the finest
// sizes were most of its 95 s here, and every size runs the same code; the
// trend is asserted in the release pass.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/contact.h"
#include "common/mesh/primitives.h"
#include "tests/sanitizer_build.h"

namespace hemm::vps {
namespace {

constexpr double kK = 1e7;

Eigen::Isometry3d at(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

struct Row {
  double voxel;
  double err_cont;
  double err_layered;
  double angle_cont;
};

void print_table(const char* name, const std::vector<Row>& rows) {
  std::printf("\n%s\n  voxel [mm] | |F| error continuous | |F| error layered (paper) | direction error [deg]\n",
              name);
  for (const Row& r : rows)
    std::printf("  %10.2f | %19.2f%% | %25.2f%% | %8.3f\n", r.voxel * 1e3, 100 * r.err_cont, 100 * r.err_layered,
                r.angle_cont);
}

void expect_falling(const std::vector<Row>& rows) {
  if (hemm::test::kSanitizerBuild) return;  // one size there: no trend to judge
  // Monotone within a margin, and clearly smaller at the finest than at the coarsest size.
  for (std::size_t i = 1; i < rows.size(); ++i) EXPECT_LE(rows[i].err_cont, rows[i - 1].err_cont * 1.15 + 0.005);
  EXPECT_LT(rows.back().err_cont, 0.5 * rows.front().err_cont + 0.005);
  EXPECT_LT(rows.back().err_cont, 0.05);
}

PairResult eval(const Voxmap& vm, const PointShell& ps, const Eigen::Isometry3d& T_W_P, PenetrationModel model) {
  ContactParams cp;
  cp.stiffness = kK;
  cp.model = model;
  PairResult r;
  evaluate_pair(vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), ps, T_W_P, cp, nullptr, &r);
  return r;
}

const std::vector<double> kVoxels = hemm::test::sanitizer_cases<double>({0.008, 0.004, 0.002, 0.0015}, {1});

TEST(VpsAccuracy, SphereAgainstPlane) {
  const double R = 0.05, delta = 0.006;
  const auto sphere = mesh::make_icosphere(R, 5);
  const auto slab = mesh::make_box({0.12, 0.12, 0.04}, 1);  // top face at z = 0 after the shift below
  mesh::TriangleMesh scene;
  mesh::append_mesh(&scene, slab, at({0, 0, -0.04}));
  const double ref = sphere_halfspace_force(kK, R, delta);  // the slab top is the plane
  std::vector<Row> rows;
  for (double s : kVoxels) {
    VoxmapParams vp;
    vp.voxel_size = s;
    // Enough distance layers to cover the penetration depth (10 mm).
    vp.layers_in = vp.layers_out = std::max(3, static_cast<int>(std::ceil(0.010 / s)));
    Voxmap vm;
    ASSERT_FALSE(build_voxmap(scene, vp, &vm, nullptr));
    PointShellParams pp;
    pp.voxel_size = s;
    PointShell ps;
    ASSERT_FALSE(build_pointshell(sphere, pp, Eigen::Vector3d::Zero(), &ps));
    // An off-grid pose and a rotation, so the result does not hinge on alignment.
    const Eigen::Matrix3d rot = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    const auto T = at({0.0013, -0.0021, R - delta}, rot);
    const PairResult c = eval(vm, ps, T, PenetrationModel::kContinuous);
    const PairResult l = eval(vm, ps, T, PenetrationModel::kLayered);
    const Eigen::Vector3d dir(0, 0, 1);
    rows.push_back({s, std::abs(c.on_shell.force.norm() - ref) / ref, std::abs(l.on_shell.force.norm() - ref) / ref,
                    angle_deg(c.on_shell.force, dir)});
    EXPECT_LT(angle_deg(c.on_shell.force, dir), 2.0) << "voxel " << s;
    EXPECT_LT(angle_deg(l.on_shell.force, dir), 2.0) << "voxel " << s;
    // Forces along normals through the centre: torque about the centre stays small.
    EXPECT_LT(c.on_shell.torque.norm(), 0.05 * R * c.on_shell.force.norm());
  }
  print_table("sphere (R 50 mm) against plane, depth 6 mm", rows);
  expect_falling(rows);
}

TEST(VpsAccuracy, SphereAgainstSphere) {
  const double R1 = 0.04, R2 = 0.06, pen = 0.006;
  const auto tool = mesh::make_icosphere(R1, 5);
  const auto scene = mesh::make_icosphere(R2, 5);
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized();
  const double D = R1 + R2 - pen;
  const double ref = sphere_sphere_force(kK, R1, R2, D);
  std::vector<Row> rows;
  for (double s : kVoxels) {
    VoxmapParams vp;
    vp.voxel_size = s;
    // Enough distance layers to cover the penetration depth (10 mm).
    vp.layers_in = vp.layers_out = std::max(3, static_cast<int>(std::ceil(0.010 / s)));
    Voxmap vm;
    ASSERT_FALSE(build_voxmap(scene, vp, &vm, nullptr));
    PointShellParams pp;
    pp.voxel_size = s;
    PointShell ps;
    ASSERT_FALSE(build_pointshell(tool, pp, Eigen::Vector3d::Zero(), &ps));
    const auto T = at(D * axis);
    const PairResult c = eval(vm, ps, T, PenetrationModel::kContinuous);
    const PairResult l = eval(vm, ps, T, PenetrationModel::kLayered);
    rows.push_back({s, std::abs(c.on_shell.force.norm() - ref) / ref, std::abs(l.on_shell.force.norm() - ref) / ref,
                    angle_deg(c.on_shell.force, axis)});
    EXPECT_LT(angle_deg(c.on_shell.force, axis), 2.0) << "voxel " << s;
    // Reaction on the scene sphere: equal and opposite, no torque about its centre.
    EXPECT_NEAR((c.on_voxmap.force + c.on_shell.force).norm(), 0.0, 1e-9 * ref);
    EXPECT_LT(c.on_voxmap.torque.norm(), 0.05 * R2 * ref);
  }
  print_table("sphere (R 40 mm) against sphere (R 60 mm), overlap 6 mm", rows);
  expect_falling(rows);
}

TEST(VpsAccuracy, BoxFaceContacts) {
  // Tool box 60 x 40 x 30 mm lying flat on the scene slab (top at z = 0, the
  // slab ends at x = 0), bottom face delta deep.
  //  A: the whole bottom face over the slab: F = K A delta along +z (the side
  //     strips below z = 0 cancel).
  //  B: the box centred at x = o over the slab's edge: the bottom face over the
  //     slab (length L = hx - o) has depth min(delta, -x), the -x side face
  //     pushes along +x; closed forms for F and the torque about the centre.
  const Eigen::Vector3d h(0.03, 0.02, 0.015);
  const double delta = 0.005;
  const auto tool = mesh::make_box(h, 8);
  mesh::TriangleMesh scene;
  mesh::append_mesh(&scene, mesh::make_box({0.1, 0.1, 0.04}, 1), at({-0.1, 0, -0.04}));
  const double W = 2 * h.y(), A = 4 * h.x() * h.y();
  // Case A pose: well inside the slab (x in [-0.09, -0.03]).
  const Eigen::Vector3d pA(-0.0603, 0.0011, h.z() - delta);
  const Eigen::Vector3d FA(0, 0, kK * A * delta);
  // Case B pose and closed form.
  const double o = 0.0007;
  const double L = h.x() - o;
  const Eigen::Vector3d pB(o, 0.0011, h.z() - delta);
  const Eigen::Vector3d FB(kK * W * delta * delta / 2, 0, kK * W * (delta * L - delta * delta / 2));
  const double tauB_y =
      kK * W * (delta * delta * delta / 3 + o * delta * delta / 2 + delta * ((L * L - delta * delta) / 2 + o * (L - delta))) +
      kK * W * ((delta - h.z()) * delta * delta / 2 - delta * delta * delta / 3);
  std::vector<Row> rows;
  const std::vector<double> voxels = hemm::test::sanitizer_cases<double>({0.004, 0.003, 0.002, 0.0015}, {1});
  for (double s : voxels) {
    VoxmapParams vp;
    vp.voxel_size = s;
    // Enough distance layers to cover the penetration depth (10 mm).
    vp.layers_in = vp.layers_out = std::max(3, static_cast<int>(std::ceil(0.010 / s)));
    Voxmap vm;
    ASSERT_FALSE(build_voxmap(scene, vp, &vm, nullptr));
    PointShellParams pp;
    pp.voxel_size = s;
    PointShell ps;
    ASSERT_FALSE(build_pointshell(tool, pp, Eigen::Vector3d::Zero(), &ps));
    const PairResult a = eval(vm, ps, at(pA), PenetrationModel::kContinuous);
    const PairResult al = eval(vm, ps, at(pA), PenetrationModel::kLayered);
    const PairResult b = eval(vm, ps, at(pB), PenetrationModel::kContinuous);
    const double errA = std::abs(a.on_shell.force.norm() - FA.norm()) / FA.norm();
    const double errB = (b.on_shell.force - FB).norm() / FB.norm();
    rows.push_back({s, std::max(errA, errB), std::abs(al.on_shell.force.norm() - FA.norm()) / FA.norm(),
                    std::max(angle_deg(a.on_shell.force, FA), angle_deg(b.on_shell.force, FB))});
    EXPECT_LT(angle_deg(a.on_shell.force, FA), 2.0) << "voxel " << s;
    EXPECT_LT(angle_deg(b.on_shell.force, FB), 2.0) << "voxel " << s;
    EXPECT_NEAR(b.on_shell.torque.y(), tauB_y, 0.1 * std::abs(tauB_y)) << "voxel " << s;
    std::printf("  voxel %.1f mm: case B torque_y %.4f N m (closed form %.4f)\n", s * 1e3, b.on_shell.torque.y(),
                tauB_y);
  }
  print_table("box face (60 x 40 mm) on a slab, depth 5 mm (error: worse of full face / over the edge)", rows);
  expect_falling(rows);
}

}  // namespace
}  // namespace hemm::vps
