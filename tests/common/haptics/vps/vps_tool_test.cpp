// hemm-vps end to end: build a .vps from a mesh file, evaluate poses, and the
// clear errors for truncated/corrupt caches and bad pose files (file:line).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <sys/wait.h>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/mesh/primitives.h"

namespace {

namespace fs = std::filesystem;

struct ToolRun {
  int code;
  std::string out;
};

ToolRun run(const std::string& args) {
  std::string cmd = HEMM_BINARY_DIR;
  cmd.append("/bin/hemm-vps ").append(args).append(" 2>&1");
  ToolRun r{-1, {}};
  std::FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) r.out += buf;
  const int st = pclose(p);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

void write_obj(const std::string& path, const hemm::mesh::TriangleMesh& m) {
  std::ofstream f(path);
  for (const auto& v : m.vertices) f << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
  for (const auto& t : m.triangles) f << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
}

TEST(HemmVpsTool, BuildEvalAndHostileFiles) {
  const fs::path dir = fs::temp_directory_path() / ("hemm_vps_tool_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string d = dir.string();
  write_obj(d + "/scene.obj", hemm::mesh::make_box({0.1, 0.1, 0.02}, 2));
  write_obj(d + "/tool.obj", hemm::mesh::make_icosphere(0.02, 3));
  ToolRun r = run("build --mesh " + d + "/scene.obj --voxel 0.004 -o " + d + "/scene.vps");
  ASSERT_EQ(r.code, 0) << r.out;
  r = run("build --mesh " + d + "/tool.obj --voxel 0.003 -o " + d + "/tool.vps");
  ASSERT_EQ(r.code, 0) << r.out;
  // Tool sphere (R 20 mm) 2 mm into the slab top (z = 0.02): force up.
  {
    std::ofstream f(d + "/poses.csv");
    f << "t,x,y,z,qw,qx,qy,qz\n0,0,0,0.038,1,0,0,0\n0.001,0,0,0.1,1,0,0,0\n";
  }
  r = run("eval --scene " + d + "/scene.vps --tool " + d + "/tool.vps --poses " + d + "/poses.csv -o " + d +
          "/forces.csv");
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream ff(d + "/forces.csv");
  std::string header, l1, l2;
  std::getline(ff, header);
  std::getline(ff, l1);
  std::getline(ff, l2);
  EXPECT_EQ(header, "t,fx,fy,fz,tx,ty,tz,contacts,max_penetration");
  double t, fx, fy, fz;
  ASSERT_EQ(std::sscanf(l1.c_str(), "%lf,%lf,%lf,%lf", &t, &fx, &fy, &fz), 4);
  EXPECT_GT(fz, 0.0);
  EXPECT_LT(std::abs(fx) + std::abs(fy), 0.05 * fz);
  ASSERT_EQ(std::sscanf(l2.c_str(), "%lf,%lf,%lf,%lf", &t, &fx, &fy, &fz), 4);
  EXPECT_EQ(fz, 0.0);

  // Truncated and corrupted caches.
  const auto size = fs::file_size(d + "/tool.vps");
  fs::copy_file(d + "/tool.vps", d + "/trunc.vps");
  fs::resize_file(d + "/trunc.vps", size - 100);
  r = run("eval --scene " + d + "/scene.vps --tool " + d + "/trunc.vps --poses " + d + "/poses.csv -o " + d + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("trunc"), std::string::npos) << r.out;
  {
    std::fstream f(d + "/tool.vps", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(size / 2));
    f.put('\x5a');
  }
  r = run("eval --scene " + d + "/scene.vps --tool " + d + "/tool.vps --poses " + d + "/poses.csv -o " + d + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("checksum"), std::string::npos) << r.out;

  // Bad pose files: file:line errors.
  {
    std::ofstream f(d + "/bad.csv");
    f << "t,x,y,z,qw,qx,qy,qz\n0,0,0,0.038,1,0,0,0\n0.001,0,abc,0.1,1,0,0,0\n";
  }
  r = run("eval --scene " + d + "/scene.vps --tool " + d + "/scene.vps --poses " + d + "/bad.csv -o " + d + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("bad.csv:3:"), std::string::npos) << r.out;
  {
    std::ofstream f(d + "/bad2.csv");
    f << "0,0,0,0.038,2,0,0,0\n";
  }
  r = run("eval --scene " + d + "/scene.vps --tool " + d + "/scene.vps --poses " + d + "/bad2.csv -o " + d + "/x.csv");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("bad2.csv:1:"), std::string::npos) << r.out;
  // Bad mesh and missing options.
  {
    std::ofstream f(d + "/nan.obj");
    f << "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n";
  }
  r = run("build --mesh " + d + "/nan.obj --voxel 0.01 -o " + d + "/n.vps");
  EXPECT_NE(r.code, 0);
  r = run("build --mesh " + d + "/scene.obj -o " + d + "/n.vps");
  EXPECT_NE(r.code, 0);
  // A point cloud becomes a scene voxmap (when built with PCL).
  {
    std::ofstream f(d + "/cloud.pcd");
    f << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 400\nHEIGHT 1\n"
         "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 400\nDATA ascii\n";
    for (int i = 0; i < 20; ++i)
      for (int j = 0; j < 20; ++j) f << i * 0.005 << " " << j * 0.005 << " 0\n";
  }
  r = run("build --help");
  if (r.out.find("--points") != std::string::npos) {
    r = run("build --points " + d + "/cloud.pcd --voxel 0.005 -o " + d + "/cloud.vps");
    EXPECT_EQ(r.code, 0) << r.out;
    r = run("eval --scene " + d + "/cloud.vps --tool " + d + "/tool.vps --poses " + d + "/poses.csv -o " + d +
            "/x.csv");
    EXPECT_NE(r.code, 0);  // tool.vps was corrupted above: still refused
    r = run("build --points " + d + "/cloud.pcd --mesh " + d + "/scene.obj --voxel 0.005 -o " + d + "/c2.vps");
    EXPECT_NE(r.code, 0);  // one input only
  }
  r = run("--help");
  EXPECT_NE(r.out.find("report"), std::string::npos);
  r = run("scene --name nonsense --out " + d);
  EXPECT_EQ(r.code, 2) << r.out;
  fs::remove_all(dir);
}

TEST(HemmVpsTool, SceneWritesMeshesAndHandsThatLoadBack) {
  const fs::path dir = fs::temp_directory_path() / ("hemm_vps_scene_" + std::to_string(::getpid()));
  const std::string d = dir.string();
  ToolRun r = run("scene --name peg-in-hole --out " + d);
  ASSERT_EQ(r.code, 0) << r.out;
  // The written meshes build into caches; the hand CSV has both objects' poses.
  r = run("build --mesh " + d + "/peg-in-hole-right.stl --voxel 0.002 -o " + d + "/pins.vps");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("watertight"), std::string::npos) << r.out;
  std::ifstream f(d + "/peg-in-hole-hands.csv");
  std::string header, line;
  std::getline(f, header);
  EXPECT_EQ(header, "t,rx,ry,rz,rqw,rqx,rqy,rqz,lx,ly,lz,lqw,lqx,lqy,lqz");
  int rows = 0;
  double t = 0, rz = 0;
  while (std::getline(f, line)) {
    ++rows;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%*f,%*f,%lf", &t, &rz), 2) << line;
  }
  EXPECT_EQ(rows, 1801);  // 1.8 s at 1 kHz
  EXPECT_NEAR(rz, 0.013, 1e-9);  // the pins end pressed 2 mm into the block
  fs::remove_all(dir);
}

TEST(HemmVpsTool, ReportRunsAndMeetsTheAccuracyTarget) {
  // A small run of the engine report (one boss, no paper-scale run): it
  // completes, and the full cycle's force errors against the exact
  // references are within the 2 % target.
  const ToolRun r = run("report --bosses 1 --paper-bosses 0 --ticks 60 --repeats 1 --fcl-every 30 --budgets 500");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto row = r.out.find("| VPS full cycle");
  ASSERT_NE(row, std::string::npos) << r.out;
  const std::string line = r.out.substr(row, r.out.find('\n', row) - row);
  // Columns: run, tris, voxel, memory, build, 4 times, F err R, F err L, ...
  std::vector<std::string> cols;
  std::stringstream ss(line);
  std::string c;
  while (std::getline(ss, c, '|')) cols.push_back(c);
  ASSERT_GE(cols.size(), 12u) << line;
  const double f_err_r = std::stod(cols[10]), f_err_l = std::stod(cols[11]);
  EXPECT_LT(f_err_r, 2.0) << line;
  EXPECT_LT(f_err_l, 2.0) << line;
  EXPECT_NE(r.out.find("FCL"), std::string::npos);
  EXPECT_NE(r.out.find("time-critical 500"), std::string::npos);
}

}  // namespace
