// Mesh validation, mass properties and file loading (assimp) against exact values.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>

#include "common/mesh/mesh_io.h"
#include "common/mesh/primitives.h"
#include "tests/temp_dir.h"

namespace hemm::mesh {
namespace {

TEST(MeshValidate, ClosedPrimitivesAreWatertightWithExactVolume) {
  TriangleMesh out;
  MeshReport r;
  ASSERT_FALSE(validate_mesh(make_box({0.1, 0.2, 0.3}, 3), {}, &out, &r));
  EXPECT_TRUE(r.watertight());
  EXPECT_NEAR(r.signed_volume, 8 * 0.1 * 0.2 * 0.3, 1e-12);
  EXPECT_NEAR(r.area, 8 * (0.1 * 0.2 + 0.2 * 0.3 + 0.1 * 0.3), 1e-12);
  ASSERT_FALSE(validate_mesh(make_icosphere(1.0, 3), {}, &out, &r));
  EXPECT_TRUE(r.watertight());
  EXPECT_NEAR(r.signed_volume, 4.0 / 3.0 * std::numbers::pi, 0.05);
  ASSERT_FALSE(validate_mesh(make_uv_sphere(1.0, 32, 16), {}, &out, &r));
  EXPECT_TRUE(r.watertight());
  EXPECT_GT(r.signed_volume, 0.0);
  ASSERT_FALSE(validate_mesh(make_rectilinear_solid({0, 1, 2, 3}, {0, 1}, {0, 1},
                                                    [](int i, int, int) { return i != 1 || true; }),
                             {}, &out, &r));
  EXPECT_TRUE(r.watertight());
  EXPECT_NEAR(r.signed_volume, 3.0, 1e-12);
  // A 64-sided prism: volume and area of the polygon, exactly.
  const int n = 64;
  const double rc = 0.04, hh = 0.05, poly = 0.5 * n * rc * rc * std::sin(2 * std::numbers::pi / n);
  ASSERT_FALSE(validate_mesh(make_cylinder(rc, hh, n), {}, &out, &r));
  EXPECT_TRUE(r.watertight());
  EXPECT_NEAR(r.signed_volume, poly * 2 * hh, 1e-12);
  EXPECT_NEAR(r.area, 2 * poly + n * 2 * rc * std::sin(std::numbers::pi / n) * 2 * hh, 1e-12);
}

TEST(MeshValidate, FlagsOpenNonManifoldInconsistentAndFlipsInsideOut) {
  TriangleMesh out;
  MeshReport r;
  ASSERT_FALSE(validate_mesh(make_open_sheet(1.0, 4), {}, &out, &r));
  EXPECT_FALSE(r.closed);
  EXPECT_EQ(r.boundary_edges, 16u);
  // Inside-out box: re-wound, volume positive.
  TriangleMesh inv = make_box({1, 1, 1});
  for (auto& t : inv.triangles) std::swap(t[1], t[2]);
  ASSERT_FALSE(validate_mesh(inv, {}, &out, &r));
  EXPECT_TRUE(r.flipped);
  EXPECT_NEAR(r.signed_volume, 8.0, 1e-12);
  // One flipped triangle: closed but not consistently oriented.
  TriangleMesh one = make_box({1, 1, 1});
  std::swap(one.triangles[0][1], one.triangles[0][2]);
  ASSERT_FALSE(validate_mesh(one, {}, &out, &r));
  EXPECT_FALSE(r.consistently_oriented);
  EXPECT_FALSE(r.watertight());
  // Three triangles on one edge.
  TriangleMesh fan;
  fan.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  fan.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}};
  ASSERT_FALSE(validate_mesh(fan, {}, &out, &r));
  EXPECT_EQ(r.nonmanifold_edges, 1u);
}

TEST(MeshValidate, DropsDegeneratesAndRejectsHostileInputUntouched) {
  TriangleMesh m = make_box({1, 1, 1});
  const std::size_t n = m.triangles.size();
  m.triangles.push_back({0, 0, 1});               // repeated index
  m.vertices.push_back({5, 5, 5});
  m.vertices.push_back({6, 6, 6});
  m.vertices.push_back({7, 7, 7});                // collinear: zero area
  const auto k = static_cast<std::uint32_t>(m.vertices.size());
  m.triangles.push_back({k - 3, k - 2, k - 1});
  TriangleMesh out;
  MeshReport r;
  ASSERT_FALSE(validate_mesh(m, {}, &out, &r));
  EXPECT_EQ(r.degenerate_dropped, 2u);
  EXPECT_EQ(out.triangles.size(), n);
  EXPECT_TRUE(r.watertight());

  TriangleMesh sentinel;
  sentinel.vertices = {{42, 42, 42}};
  MeshReport rs;
  rs.area = 42;
  auto expect_error = [&](const TriangleMesh& bad, const char* what) {
    TriangleMesh o = sentinel;
    MeshReport rr = rs;
    const auto e = validate_mesh(bad, {}, &o, &rr);
    ASSERT_TRUE(e) << what;
    EXPECT_FALSE(e->message.empty());
    EXPECT_EQ(o.vertices, sentinel.vertices) << what;
    EXPECT_EQ(rr.area, 42) << what;
  };
  expect_error(TriangleMesh{}, "empty");
  TriangleMesh bad = make_box({1, 1, 1});
  bad.vertices[3].y() = std::numeric_limits<double>::infinity();
  expect_error(bad, "inf");
  bad = make_box({1, 1, 1});
  bad.vertices[3].y() = std::nan("");
  expect_error(bad, "nan");
  bad = make_box({1, 1, 1});
  bad.triangles[2][1] = 999;
  expect_error(bad, "index");
  expect_error(make_box({3000, 1, 1}), "too large");
  expect_error(make_box({1e-8, 1e-8, 1e-8}), "too small");
  TriangleMesh flat;
  flat.vertices = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  flat.triangles = {{0, 1, 2}};
  expect_error(flat, "only degenerate");
}

TEST(MeshMass, BoxInertiaMatchesClosedForm) {
  const Eigen::Vector3d h(0.1, 0.2, 0.3);
  TriangleMesh m = make_box(h, 2);
  append_mesh(&m, TriangleMesh{}, Eigen::Isometry3d::Identity());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(1, -2, 3);
  TriangleMesh shifted;
  append_mesh(&shifted, m, T);
  const MassProperties p = compute_mass_properties(shifted, 500.0);
  const double mass = 500.0 * 8 * h.prod();
  EXPECT_NEAR(p.mass, mass, 1e-9);
  EXPECT_NEAR((p.centre_of_mass - T.translation()).norm(), 0.0, 1e-12);
  const double a = 2 * h.x(), b = 2 * h.y(), c = 2 * h.z();
  EXPECT_NEAR(p.inertia_com(0, 0), mass * (b * b + c * c) / 12, 1e-9);
  EXPECT_NEAR(p.inertia_com(1, 1), mass * (a * a + c * c) / 12, 1e-9);
  EXPECT_NEAR(p.inertia_com(2, 2), mass * (a * a + b * b) / 12, 1e-9);
  EXPECT_NEAR(p.inertia_com(0, 1), 0.0, 1e-9);
}

class MeshFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = hemm::test::make_temp_dir("hemm_mesh_test");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const auto p = (dir_ / name).string();
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }
  std::filesystem::path dir_;
};

std::string box_obj(const TriangleMesh& m) {
  std::string s;
  char buf[128];
  for (const auto& v : m.vertices) {
    std::snprintf(buf, sizeof buf, "v %.9g %.9g %.9g\n", v.x(), v.y(), v.z());
    s += buf;
  }
  for (const auto& t : m.triangles) s += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " +
                                         std::to_string(t[2] + 1) + "\n";
  return s;
}

TEST_F(MeshFiles, LoadsObjStlPlyOffAndValidates) {
  const TriangleMesh box = make_box({0.1, 0.2, 0.3}, 2);
  std::string stl = "solid box\n", off = "OFF\n", ply;
  off += std::to_string(box.vertices.size()) + " " + std::to_string(box.triangles.size()) + " 0\n";
  ply = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(box.vertices.size()) +
        "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
        std::to_string(box.triangles.size()) + "\nproperty list uchar int vertex_indices\nend_header\n";
  char buf[256];
  for (const auto& v : box.vertices) {
    std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g\n", v.x(), v.y(), v.z());
    off += buf;
    ply += buf;
  }
  for (const auto& t : box.triangles) {
    const std::string f = "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
    off += f;
    ply += f;
    const Eigen::Vector3d& a = box.vertices[t[0]];
    const Eigen::Vector3d& b = box.vertices[t[1]];
    const Eigen::Vector3d& c = box.vertices[t[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    std::snprintf(buf, sizeof buf, "facet normal %g %g %g\n outer loop\n", n.x(), n.y(), n.z());
    stl += buf;
    for (const auto* p : {&a, &b, &c}) {
      std::snprintf(buf, sizeof buf, "  vertex %.9g %.9g %.9g\n", p->x(), p->y(), p->z());
      stl += buf;
    }
    stl += " endloop\nendfacet\n";
  }
  stl += "endsolid box\n";
  for (const auto& [name, text] : std::vector<std::pair<std::string, std::string>>{
           {"box.obj", box_obj(box)}, {"box.stl", stl}, {"box.ply", ply}, {"box.off", off}}) {
    TriangleMesh m;
    MeshReport r;
    const auto e = load_mesh(write(name, text), {}, &m, &r);
    ASSERT_FALSE(e) << name << ": " << e->message;
    EXPECT_EQ(m.triangles.size(), box.triangles.size()) << name;
    EXPECT_TRUE(r.watertight()) << name;
    EXPECT_NEAR(r.signed_volume, 8 * 0.1 * 0.2 * 0.3, 1e-6) << name;
  }
  // Millimetre file with scale.
  LoadOptions mmopt;
  mmopt.scale = 0.001;
  TriangleMesh mm_box = make_box({100, 200, 300}, 1);
  TriangleMesh m;
  MeshReport r;
  ASSERT_FALSE(load_mesh(write("mm.obj", box_obj(mm_box)), mmopt, &m, &r));
  EXPECT_NEAR(r.bounds.sizes().x(), 0.2, 1e-9);
}

TEST_F(MeshFiles, SavedMeshesLoadBackTheSame) {
  // Written through assimp's exporters, read back through its importers:
  // same triangles, same volume (float STL: 1e-7 relative), still watertight.
  const TriangleMesh sphere = make_icosphere(0.05, 3);
  mesh::MeshReport ref;
  TriangleMesh valid;
  ASSERT_FALSE(validate_mesh(sphere, {}, &valid, &ref));
  for (const char* name : {"s.stl", "s.obj", "s.ply"}) {
    const std::string path = (dir_ / name).string();
    ASSERT_FALSE(save_mesh(path, sphere)) << name;
    TriangleMesh m;
    MeshReport r;
    const auto e = load_mesh(path, {}, &m, &r);
    ASSERT_FALSE(e) << name << ": " << e->message;
    EXPECT_EQ(m.triangles.size(), sphere.triangles.size()) << name;
    EXPECT_TRUE(r.watertight()) << name;
    EXPECT_NEAR(r.signed_volume, ref.signed_volume, 1e-6 * ref.signed_volume) << name;
  }
  EXPECT_TRUE(save_mesh((dir_ / "s.xyz").string(), sphere));
  EXPECT_TRUE(save_mesh((dir_ / "e.stl").string(), TriangleMesh{}));
  TriangleMesh bad = sphere;
  bad.triangles[3][1] = 1000000;
  EXPECT_TRUE(save_mesh((dir_ / "b.stl").string(), bad));
}

TEST_F(MeshFiles, BadFilesGiveClearErrors) {
  TriangleMesh m;
  m.vertices = {{1, 2, 3}};
  MeshReport r;
  auto e = load_mesh((dir_ / "missing.obj").string(), {}, &m, &r);
  ASSERT_TRUE(e);
  EXPECT_NE(e->message.find("missing.obj"), std::string::npos);
  e = load_mesh(write("garbage.stl", "this is not a mesh \x01\x02\x03"), {}, &m, &r);
  EXPECT_TRUE(e);
  e = load_mesh(write("nan.obj", "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n"), {}, &m, &r);
  EXPECT_TRUE(e);
  e = load_mesh(write("huge.obj", "v 0 0 0\nv 1e7 0 0\nv 0 1 0\nf 1 2 3\n"), {}, &m, &r);
  ASSERT_TRUE(e);
  EXPECT_NE(e->message.find("extent"), std::string::npos);
  EXPECT_EQ(m.vertices.size(), 1u);  // untouched
}

}  // namespace
}  // namespace hemm::mesh
