// The installed tree (docs/install.md): `cmake --install` of this build into
// a fresh temporary prefix, then every installed binary's --help, and a
// two-second loopback session of the installed hemm-robot and hemm-operator
// started without --config: each must find its default config in
// <prefix>/share/hemm and, through it, its scene and the demo key.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

// The tree is installed once (ctest runs each TEST in a process of its own):
// one test, its parts in turn.
TEST(InstalledTree, HoldsItsFilesPrintsUsageAndRunsASessionWithoutPaths) {
  const std::string dir = make_temp_dir();
  const std::string prefix = dir + "/prefix with space";
  const ProcessResult inst =
      run_to_completion({HEMM_CMAKE_COMMAND, "--install", HEMM_BINARY_DIR, "--prefix", prefix}, dir, 240s);
  ASSERT_EQ(inst.rc, 0) << inst.out << inst.err;
  const fs::path p(prefix);
  const std::string share = (p / "share/hemm").lexically_normal().string();

  {
    SCOPED_TRACE("the tree: tools, configs, scenes, meshes, key, docs");
    for (const char* b : {"hemm-robot", "hemm-operator", "hemm-relay", "hemm-truth", "hemm-vps"})
      EXPECT_TRUE(fs::is_regular_file(p / "bin" / b)) << b;
    for (const char* f : {"configs/robot.pbtxt", "configs/operator.pbtxt", "configs/demo.key",
                          "configs/operator_vps_peg.pbtxt", "scenes/home.xml", "scenes/robot.xml"})
      EXPECT_TRUE(fs::is_regular_file(p / "share/hemm" / f)) << f;
    // The VPS configs point at the installed meshes, and those are there.
    const std::string peg = read_file((p / "share/hemm/configs/operator_vps_peg.pbtxt").string());
    EXPECT_EQ(peg.find("out/vps"), std::string::npos) << peg;
    EXPECT_NE(peg.find("\"../meshes/peg-in-hole-scene.stl\""), std::string::npos) << peg;
    for (const char* m : {"peg-in-hole-scene.stl", "peg-in-hole-right.stl", "peg-in-hole-left.stl",
                          "assembly-scene.stl", "assembly-right.stl", "assembly-left.stl"}) {
      std::error_code ec;
      EXPECT_GT(fs::file_size(p / "share/hemm/meshes" / m, ec), 84u) << m;  // a binary STL's header and count
    }
    // The documentation, where Debian keeps a package's, with the README's plots.
    for (const char* d : {"README.md", "docs/design.md", "docs/realtime.md", "docs/measurements.md", "docs/img/timing.png"})
      EXPECT_TRUE(fs::is_regular_file(p / "share/doc/hemm" / d)) << d;
    // Only the user-facing tools: no tests or benchmarks.
    for (const auto& e : fs::directory_iterator(p / "bin"))
      EXPECT_EQ(e.path().filename().string().rfind("hemm-", 0), 0u) << e.path();
  }

  {
    SCOPED_TRACE("--help of every installed binary");
    int n = 0;
    for (const auto& e : fs::directory_iterator(p / "bin")) {
      const std::string run_dir = make_temp_dir();
      const ProcessResult r = run_to_completion({e.path().string(), "--help"}, run_dir, 30s);
      EXPECT_EQ(r.rc, 0) << e.path() << ": " << r.err;
      EXPECT_NE(r.out.find("Usage"), std::string::npos) << e.path() << ": " << r.out;
      EXPECT_GT(r.out.size(), 200u) << e.path();
      fs::remove_all(run_dir);
      ++n;
    }
    EXPECT_GE(n, 5);
  }

  {
    SCOPED_TRACE("a loopback session of the installed stations, default configs");
    const std::string bin = prefix + "/bin/";
    const int session_port = free_port(), stream_port = free_port();
    ChildProcess robot({bin + "hemm-robot", "--session-port", std::to_string(session_port), "--stream-port",
                        std::to_string(stream_port), "--duration", "10", "--stats-json", dir + "/robot.json"},
                       dir + "/robot.out", dir + "/robot.err");
    ASSERT_TRUE(robot.started());
    ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 20s)) << read_file(dir + "/robot.err");
    ChildProcess op({bin + "hemm-operator", "--session-port", std::to_string(session_port), "--duration", "2",
                     "--stats-json", dir + "/op.json"},
                    dir + "/op.out", dir + "/op.err");
    const auto op_rc = op.wait(30s);
    ASSERT_TRUE(op_rc.has_value()) << "operator hung";
    EXPECT_EQ(*op_rc, 0) << read_file(dir + "/op.err");
    robot.signal(SIGTERM);
    const auto robot_rc = robot.wait(20s);
    ASSERT_TRUE(robot_rc.has_value());
    EXPECT_EQ(*robot_rc, 0) << read_file(dir + "/robot.err");
    const std::string robot_err = read_file(dir + "/robot.err"), op_err = read_file(dir + "/op.err");
    EXPECT_NE(robot_err.find("event=default_config station=robot file=\"" + share + "/configs/robot.pbtxt\""),
              std::string::npos) << robot_err;
    EXPECT_NE(op_err.find("event=default_config station=operator file=\"" + share + "/configs/operator.pbtxt\""),
              std::string::npos) << op_err;
    EXPECT_NE(robot_err.find("scene=\"" + share + "/scenes/home.xml\""), std::string::npos) << robot_err;
    EXPECT_EQ(json_number(read_file(dir + "/op.json"), "sessions_opened").value_or(-1), 1);
    EXPECT_EQ(json_number(read_file(dir + "/robot.json"), "sessions_opened").value_or(-1), 1);
  }

  {
    SCOPED_TRACE("an explicit --config still wins");
    // A copy of the robot config whose scene (relative to the copy) does not
    // exist: given with --config it is the one loaded, and refused.
    const std::string cfg = dir + "/mine/robot.pbtxt";
    fs::create_directories(dir + "/mine");
    fs::copy_file(share + "/configs/robot.pbtxt", cfg);
    fs::copy_file(share + "/configs/demo.key", dir + "/mine/demo.key");
    const std::string run_dir = make_temp_dir();
    const ProcessResult r = run_to_completion(
        {prefix + "/bin/hemm-robot", "--config", cfg, "--session-port", "0", "--stream-port", "0", "--duration", "1"},
        run_dir, 30s);
    fs::remove_all(run_dir);
    EXPECT_EQ(r.rc, 2) << r.err;
    EXPECT_NE(r.err.find("cannot load scene '" + (fs::path(dir) / "scenes/home.xml").lexically_normal().string()),
              std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("event=default_config"), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hemm::test
