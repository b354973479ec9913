// The e-stop with the real binaries on loopback (issue 9 item 9): hemm-robot
// and hemm-operator, each with a control socket; the operator's stdin is a
// pseudo-terminal. Pressed from the operator's terminal and from the command
// line (`hemm-operator estop|release`), the robot's Ack names the request and
// the robot reports the e-stop; the robot's own e-stop (`hemm-robot estop`)
// holds against the operator's release and only the robot releases it.
#include <fcntl.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";

struct Reply {
  int rc = -1;
  std::string out;
};

// `<binary> <command> --control-socket <socket>`, run to completion.
Reply control(const std::string& dir, const std::string& binary, const std::string& command,
              const std::string& socket) {
  static int n = 0;
  const std::string out = dir + "/control" + std::to_string(++n);
  ChildProcess p({kBin + binary, command, "--control-socket", socket}, out + ".out", out + ".err");
  const auto rc = p.wait(15s);
  Reply r;
  r.rc = rc.value_or(-1);
  r.out = read_file(out + ".out") + read_file(out + ".err");
  return r;
}

bool starts_with(const std::string& s, const std::string& p) { return s.rfind(p, 0) == 0; }

TEST(EStopLoopback, FromTheTerminalTheCommandLineAndTheRobotItself) {
  const std::string dir = make_temp_dir();
  const std::string robot_sock = dir + "/robot.sock", op_sock = dir + "/op.sock";
  const int tcp = free_port(), udp = free_port();
  ChildProcess robot({kBin + "hemm-robot", "--config", kConfigs + "robot.pbtxt", "--listen", "127.0.0.1",
                      "--session-port", std::to_string(tcp), "--stream-port", std::to_string(udp), "--duration",
                      "40", "--control-socket", robot_sock, "--stats-json", dir + "/robot.json"},
                     dir + "/robot.out", dir + "/robot.err");
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 15s)) << read_file(dir + "/robot.err");
  // The operator's stdin: a pseudo-terminal whose other end the test types on.
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0);
  ASSERT_EQ(::grantpt(master), 0);
  ASSERT_EQ(::unlockpt(master), 0);
  ChildProcess op({kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot", "127.0.0.1",
                   "--session-port", std::to_string(tcp), "--duration", "30", "--script", "idle",
                   "--control-socket", op_sock, "--station-json", dir + "/station.json"},
                  dir + "/op.out", dir + "/op.err", ::ptsname(master));
  auto logs = [&] { return "--- robot\n" + read_file(dir + "/robot.err") + "--- operator\n" + read_file(dir + "/op.err"); };
  ASSERT_TRUE(wait_for_text(dir + "/op.err", "event=estop_keys ", 15s)) << logs();
  // Wait for the session through the control socket.
  bool up = false;
  for (int i = 0; i < 100 && !up; ++i) {
    up = control(dir, "hemm-operator", "status", op_sock).out.find("link=up") != std::string::npos;
    if (!up) std::this_thread::sleep_for(100ms);
  }
  ASSERT_TRUE(up) << logs();

  // The terminal key: space engages, the robot acknowledges the request.
  ASSERT_EQ(::write(master, " ", 1), 1);
  ASSERT_TRUE(wait_for_text(dir + "/op.err", "via=terminal key reply=\"ok request_id=", 5s)) << logs();
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=engaged local=released"),
            std::string::npos);
  ASSERT_EQ(::write(master, "R", 1), 1);
  ASSERT_TRUE(wait_for_text(dir + "/op.err", "e-stop released", 5s)) << logs();

  // The command line against the running operator station.
  Reply r = control(dir, "hemm-operator", "estop", op_sock);
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_TRUE(starts_with(r.out, "ok request_id=")) << r.out;
  EXPECT_NE(r.out.find("e-stop engaged"), std::string::npos) << r.out;
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=engaged"), std::string::npos);
  r = control(dir, "hemm-operator", "release", op_sock);
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=released"), std::string::npos);

  // The robot's own e-stop: the operator hears of it and cannot release it.
  r = control(dir, "hemm-robot", "estop", robot_sock);
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=engaged local=engaged"),
            std::string::npos);
  bool reported = false;
  for (int i = 0; i < 50 && !reported; ++i) {
    reported = control(dir, "hemm-operator", "status", op_sock).out.find("estop=engaged") != std::string::npos;
    if (!reported) std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(reported) << logs();
  r = control(dir, "hemm-operator", "release", op_sock);
  EXPECT_EQ(r.rc, 6) << r.out;  // refused
  EXPECT_TRUE(starts_with(r.out, "error request_id=")) << r.out;
  EXPECT_NE(r.out.find("at the robot"), std::string::npos) << r.out;
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=engaged"), std::string::npos);
  r = control(dir, "hemm-robot", "release", robot_sock);
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_NE(control(dir, "hemm-robot", "status", robot_sock).out.find("estop=released local=released"),
            std::string::npos);

  // Bad use: an unknown command is refused; no station on the socket is exit 7.
  EXPECT_EQ(control(dir, "hemm-operator", "estop", dir + "/nobody.sock").rc, 7);
  op.signal(SIGTERM);
  EXPECT_EQ(op.wait(20s).value_or(-1), 0) << logs();
  robot.signal(SIGTERM);
  EXPECT_EQ(robot.wait(20s).value_or(-1), 0) << logs();
  const std::string station = read_file(dir + "/station.json");
  EXPECT_EQ(json_number(station, "acknowledged").value_or(-1), 4) << station;
  EXPECT_EQ(json_number(station, "refused").value_or(-1), 1) << station;
  EXPECT_EQ(json_number(read_file(dir + "/robot.json"), "estop_changes").value_or(-1), 6);
  ::close(master);
}

}  // namespace
}  // namespace hemm::test
