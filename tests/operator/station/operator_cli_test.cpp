// hemm-operator's --goal and --station-json options, through the real binary:
// bad goals are usage errors (exit 2, one line naming the option and value)
// that start nothing; --station-json writes the summary at exit (here with no
// robot to talk to: the station runs its servo loop for --duration and gives
// up the connection attempts), and a write failure is reported with a
// non-zero exit.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "tests/integration/link/child_process.h"

namespace {

using hemm::test::read_file;

const std::string kOperator = std::string(HEMM_BINARY_DIR) + "/bin/hemm-operator";

using RunResult = hemm::test::ProcessResult;

// Runs the binary with the given arguments, stdout/stderr into files in dir.
RunResult run(const std::string& dir, std::vector<std::string> args) {
  args.insert(args.begin(), kOperator);
  return hemm::test::run_to_completion(std::move(args), dir, std::chrono::seconds(30));
}

// A loopback port nothing listens on (free a moment ago).
int closed_port() { return hemm::test::free_port(); }

class OperatorCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("hemm_operator_cli_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    std::ofstream(dir_ / "k.key") << "3f9a0c61d27e84b5c0e1f7a2946d3b58e1c07f4a92b6d35e8c14a7f02b9d6e3c" << "\n";
    std::filesystem::permissions(dir_ / "k.key", std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string d() const { return dir_.string(); }
  std::filesystem::path dir_;
};

TEST_F(OperatorCli, BadGoalsAreUsageErrors) {
  const std::vector<std::string> bad = {"1", "1,", ",2", "1,x", "x,1", "1,2,3", "nan,1", "1,inf", "1e999,0", " 1,2", ""};
  for (const std::string& g : bad) {
    const RunResult r = run(d(), {"--key", d() + "/k.key", "--script", "nav-to-goal", "--goal", g, "--station-json",
                            d() + "/s.json"});
    EXPECT_EQ(r.rc, 2) << "'" << g << "': " << r.err;
    EXPECT_NE(r.err.find("--goal '" + g + "'"), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir_ / "s.json"));  // nothing ran
  }
  // A good goal with another script.
  const RunResult r = run(d(), {"--key", d() + "/k.key", "--script", "idle", "--goal", "1,2"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--goal needs --script nav-to-goal"), std::string::npos) << r.err;
}

TEST_F(OperatorCli, StationJsonIsWrittenAtExit) {
  const int port = closed_port();
  ASSERT_GT(port, 0);
  const std::string json = d() + "/station.json";
  const RunResult r = run(d(), {"--key", d() + "/k.key", "--robot", "127.0.0.1", "--session-port", std::to_string(port),
                          "--script", "nav-to-goal", "--goal=-1.5,0.25", "--duration", "0.5", "--log-level", "off",
                          "--station-json", json});
  EXPECT_EQ(r.rc, 7) << r.err;  // no robot: the duration ends before a session opened (kExitPeerLost)
  const std::string text = read_file(json);
  for (const char* k : {"\"timing\"", "\"ticks\"", "\"misses\"", "\"period_us\"", "\"wake_latency_us\"",
                        "\"compute_us\"", "\"median\"", "\"p99\"", "\"model\"", "\"commands\"", "\"logs\"",
                        "\"robot_pose\"", "\"nav_goal\"", "\"goal_index\""})
    EXPECT_NE(text.find(k), std::string::npos) << k << " in " << text;
  EXPECT_NE(text.find("\"goal_x_m\": -1.5"), std::string::npos) << text;
  EXPECT_NE(text.find("\"goal_y_m\": 0.25"), std::string::npos) << text;
  EXPECT_NE(text.find("\"arrived\": false"), std::string::npos) << text;  // no robot: nothing to steer by
  EXPECT_FALSE(std::filesystem::exists(json + ".tmp"));
}

TEST_F(OperatorCli, StationJsonWriteFailureIsAnError) {
  const int port = closed_port();
  ASSERT_GT(port, 0);
  const std::string json = d() + "/no/such/dir/station.json";
  const RunResult r = run(d(), {"--key", d() + "/k.key", "--robot", "127.0.0.1", "--session-port", std::to_string(port),
                          "--duration", "0.3", "--log-level", "off", "--station-json", json});
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--station-json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no/such/dir"), std::string::npos) << r.err;
}

}  // namespace
