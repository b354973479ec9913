// The stations' local control: the control socket (one line in, one reply
// out, owner-only, hostile lines refused, a live station's socket never
// taken over).
#include "common/net/station_control.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace hn = hemm::net;
using namespace std::chrono_literals;

namespace {

std::string temp_dir() {
  std::string t = "/tmp/hemm-control-XXXXXX";
  return ::mkdtemp(t.data());
}

// Runs the server's io_context on a thread while the test talks to it.
struct Served {
  asio::io_context io;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work{io.get_executor()};
  std::thread thread;
  void run() { thread = std::thread([this] { io.run(); }); }
  ~Served() {
    work.reset();
    io.stop();
    if (thread.joinable()) thread.join();
  }
};

}  // namespace

TEST(ControlSocket, OneLineInOneReplyOutOwnerOnly) {
  const std::string dir = temp_dir(), path = dir + "/station.sock";
  Served s;
  std::vector<std::string> seen;
  asio::steady_timer later(s.io);
  hn::ControlServer server(s.io, path, [&](const std::string& cmd, hn::ControlServer::Respond respond) {
    seen.push_back(cmd);
    if (cmd == "slow") {  // a reply that waits, as for the robot's Ack
      later.expires_after(50ms);
      later.async_wait([respond](const asio::error_code&) { respond("ok late"); });
      return;
    }
    respond("ok " + cmd);
  });
  std::string err;
  ASSERT_TRUE(server.start(&err)) << err;
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  s.run();
  EXPECT_EQ(hn::control_request(path, "estop", 2s, &err).value_or(err), "ok estop");
  EXPECT_EQ(hn::control_request(path, "  status \r", 2s, &err).value_or(err), "ok status");
  EXPECT_EQ(hn::control_request(path, "slow", 2s, &err).value_or(err), "ok late");
  // Hostile lines: refused, never handed to the station.
  const auto bad = hn::control_request(path, std::string("est\x01op"), 2s, &err);
  ASSERT_TRUE(bad) << err;
  EXPECT_EQ(bad->rfind("error", 0), 0u) << *bad;
  const auto longer = hn::control_request(path, std::string(2 * hn::kMaxControlLine, 'x'), 2s, &err);
  ASSERT_TRUE(longer) << err;
  EXPECT_EQ(longer->rfind("error", 0), 0u) << *longer;
  EXPECT_EQ(server.requests(), 3u);
  EXPECT_EQ(server.rejected(), 2u);
  EXPECT_EQ(seen, (std::vector<std::string>{"estop", "status", "slow"}));
  // A live station's socket is not taken over.
  asio::io_context other;
  hn::ControlServer second(other, path, [](const std::string&, hn::ControlServer::Respond) {});
  EXPECT_FALSE(second.start(&err));
  EXPECT_NE(err.find("already listens"), std::string::npos) << err;
  server.stop();
  EXPECT_FALSE(std::filesystem::exists(path));
  EXPECT_FALSE(hn::control_request(path, "estop", 500ms, &err));
  EXPECT_NE(err.find("cannot connect"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

TEST(ControlSocket, StaleSocketIsReplacedOtherFilesAreNot) {
  const std::string dir = temp_dir(), path = dir + "/station.sock";
  asio::io_context io;
  {
    // A station that died: its socket file stays, nobody listens.
    asio::local::stream_protocol::acceptor dead(io, asio::local::stream_protocol::endpoint(path));
  }
  ASSERT_TRUE(std::filesystem::exists(path));
  std::string err;
  {
    hn::ControlServer server(io, path, [](const std::string&, hn::ControlServer::Respond r) { r("ok"); });
    EXPECT_TRUE(server.start(&err)) << err;
  }
  const std::string file = dir + "/notes.txt";
  std::ofstream(file) << "mine";
  hn::ControlServer server(io, file, [](const std::string&, hn::ControlServer::Respond) {});
  EXPECT_FALSE(server.start(&err));
  EXPECT_NE(err.find("not a socket"), std::string::npos) << err;
  EXPECT_TRUE(std::filesystem::exists(file));
  std::filesystem::remove_all(dir);
}
