// The operator's client against a fake robot front over real loopback
// sockets (issue 23 item 5): a clear, unauthenticated Error during the
// handshake (which anyone between the stations, or anyone answering on the
// robot's port, can send) does not make the operator give up for good; it
// tries again. Only an authenticated refusal (sealed with the session keys,
// or tagged with the pre-shared key over the operator's own Hello) is final.
//
// The front accepts the operator's TCP connections. For the connections it
// is told to spoil it answers with a clear Error: in place of the Challenge
// (right after the Hello), or in place of the robot's sealed Welcome (after
// passing Hello, Challenge and Proof through). Every other connection it
// relays, frame by frame, to a real RobotServer.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "common/clock/steady_clock.h"
#include "common/net/framing.h"
#include "common/net/handshake.h"
#include "operator/client/operator_client.h"
#include "robot_side/server/robot_server.h"

namespace hemm::test {
namespace {

net::Key test_key() {
  net::Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(53 * i + 11);
  return k;
}

bool wait_until(const std::function<bool()>& pred, double timeout_s) {
  const int64_t end = steady_now_ns() + static_cast<int64_t>(timeout_s * 1e9);
  while (steady_now_ns() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pred();
}

// The real robot's server on its own network thread.
struct Robot {
  asio::io_context io;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work;
  std::unique_ptr<robot::RobotServer> server;
  std::thread thread;
  explicit Robot(const net::Key& key) {
    robot::RobotServerOptions o;
    o.session_port = 0;
    o.stream_port = 0;
    o.psk = key;
    server = std::make_unique<robot::RobotServer>(io, o);
    std::string err;
    EXPECT_TRUE(server->start(&err)) << err;
    work.emplace(io.get_executor());
    thread = std::thread([this] { io.run(); });
  }
  ~Robot() {
    asio::post(io, [this] { server->stop("test over"); });
    work.reset();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    io.stop();
    thread.join();
  }
};

// How the front treats one connection.
enum class Spoil { kNone, kErrorForChallenge, kErrorForWelcome };

class Front {
 public:
  // spoil(i): what to do with the i-th connection (0-based).
  Front(uint16_t robot_port, std::function<Spoil(int)> spoil, wire::ErrorCode code)
      : robot_port_(robot_port), spoil_(std::move(spoil)), code_(code) {
    listen_ = ::socket(AF_INET, SOCK_STREAM, 0);
    int one = 1;
    ::setsockopt(listen_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a = loopback(0);
    ::bind(listen_, reinterpret_cast<sockaddr*>(&a), sizeof a);
    ::listen(listen_, 16);
    socklen_t len = sizeof a;
    ::getsockname(listen_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { accept_loop(); });
  }
  ~Front() {
    stop_ = true;
    ::shutdown(listen_, SHUT_RDWR);
    thread_.join();
    ::close(listen_);
    for (auto& t : relays_) t.join();
  }
  uint16_t port() const { return port_; }
  int connections() const { return connections_.load(); }
  int spoiled() const { return spoiled_.load(); }

 private:
  static sockaddr_in loopback(uint16_t port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    return a;
  }
  static bool write_all(int fd, const std::vector<uint8_t>& b) {
    size_t off = 0;
    while (off < b.size()) {
      const ssize_t n = ::send(fd, b.data() + off, b.size() - off, MSG_NOSIGNAL);
      if (n <= 0) return false;
      off += static_cast<size_t>(n);
    }
    return true;
  }
  // Reads one frame (header + payload) from fd, or nothing (closed, stopped).
  std::optional<std::vector<uint8_t>> read_frame(int fd, net::FrameDecoder& dec) {
    std::vector<uint8_t> payload;
    uint8_t buf[4096];
    while (!stop_) {
      if (dec.next(&payload) == net::FrameDecoder::Status::kFrame) return payload;
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) return std::nullopt;
      dec.feed(std::span<const uint8_t>(buf, static_cast<size_t>(n)));
    }
    return std::nullopt;
  }
  void send_frame(int fd, const std::vector<uint8_t>& payload) {
    std::vector<uint8_t> out;
    net::encode_frame(payload, &out);
    write_all(fd, out);
  }
  void accept_loop() {
    while (!stop_) {
      pollfd p{listen_, POLLIN, 0};
      if (::poll(&p, 1, 20) <= 0) continue;
      const int c = ::accept(listen_, nullptr, nullptr);
      if (c < 0) continue;
      const int i = connections_++;
      relays_.emplace_back([this, c, i] { serve(c, spoil_(i)); });
    }
  }
  void serve(int client, Spoil s) {
    net::FrameDecoder from_client(1 << 21), from_robot(1 << 21);
    const auto hello = read_frame(client, from_client);
    if (!hello) {
      ::close(client);
      return;
    }
    if (s == Spoil::kErrorForChallenge) {
      ++spoiled_;
      send_frame(client, net::make_error_frame(code_, "refused by the front (clear, unauthenticated)"));
      ::close(client);
      return;
    }
    const int robot = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a = loopback(robot_port_);
    if (::connect(robot, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      ::close(robot);
      ::close(client);
      return;
    }
    send_frame(robot, *hello);
    if (s == Spoil::kErrorForWelcome) {
      const auto challenge = read_frame(robot, from_robot);
      if (challenge) send_frame(client, *challenge);
      const auto proof = read_frame(client, from_client);
      if (proof) send_frame(robot, *proof);
      const auto welcome = read_frame(robot, from_robot);  // sealed: dropped
      ++spoiled_;
      if (welcome) send_frame(client, net::make_error_frame(code_, "refused by the front (clear, unauthenticated)"));
      ::close(robot);
      ::close(client);
      return;
    }
    // Relay bytes both ways until either side closes.
    uint8_t buf[16384];
    while (!stop_) {
      pollfd p[2] = {{client, POLLIN, 0}, {robot, POLLIN, 0}};
      if (::poll(p, 2, 20) <= 0) continue;
      bool closed = false;
      for (int k = 0; k < 2 && !closed; ++k) {
        if (!(p[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        const ssize_t n = ::recv(p[k].fd, buf, sizeof buf, 0);
        if (n <= 0 || !write_all(k == 0 ? robot : client, std::vector<uint8_t>(buf, buf + n))) closed = true;
      }
      if (closed) break;
    }
    ::close(robot);
    ::close(client);
  }

  uint16_t robot_port_;
  std::function<Spoil(int)> spoil_;
  wire::ErrorCode code_;
  int listen_ = -1;
  uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<int> connections_{0}, spoiled_{0};
  std::thread thread_;
  std::vector<std::thread> relays_;  // accept thread only, joined after it
};

// The operator's client on its own network thread.
struct Client {
  asio::io_context io;
  std::unique_ptr<op::OperatorClient> client;
  std::thread thread;
  std::atomic<int> fatal_code{-1};
  std::atomic<int64_t> fatal_ns{0};
  std::mutex mu;
  std::string fatal_reason;
  int64_t started_ns = 0;
  Client(uint16_t port, const net::Key& key, uint32_t connect_for_ms, uint32_t protocol_version = net::kProtocolVersion) {
    op::OperatorClientOptions o;
    o.station_name = "client-test";
    o.robot_address = "127.0.0.1";
    o.session_port = port;
    o.bind_address = "127.0.0.1";
    o.psk = key;
    o.connect_for_ms = connect_for_ms;
    o.reconnect_for_ms = 0;
    o.protocol_version = protocol_version;
    client = std::make_unique<op::OperatorClient>(io, o);
    std::string err;
    started_ns = steady_now_ns();
    EXPECT_TRUE(client->start(
        [this](int code, const std::string& why) {
          std::lock_guard<std::mutex> lk(mu);
          fatal_reason = why;
          fatal_ns = steady_now_ns();
          fatal_code = code;
        },
        &err))
        << err;
    thread = std::thread([this] { io.run(); });
  }
  ~Client() {
    asio::post(io, [this] { client->stop("test over"); });
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    io.stop();
    thread.join();
  }
  std::string reason() {
    std::lock_guard<std::mutex> lk(mu);
    return fatal_reason;
  }
};

// A clear Error in place of the Challenge, twice (auth failed, then version
// mismatch): the operator tries again and opens its session on the third
// connection, which the front passes through.
TEST(OperatorClientHandshake, AClearErrorInPlaceOfTheChallengeIsNotFinal) {
  for (const wire::ErrorCode code : {wire::ERROR_AUTH_FAILED, wire::ERROR_VERSION_MISMATCH}) {
    Robot robot(test_key());
    Front front(robot.server->session_port(), [](int i) { return i < 2 ? Spoil::kErrorForChallenge : Spoil::kNone; },
                code);
    Client c(front.port(), test_key(), 10000);
    const bool opened = wait_until([&] { return c.client->session_open(); }, 8.0);
    std::printf("%s in clear, twice: %d connections, session %s, fatal %d \"%s\"\n",
                wire::ErrorCode_Name(code).c_str(), front.connections(), opened ? "open" : "never opened",
                c.fatal_code.load(), c.reason().c_str());
    EXPECT_TRUE(opened) << wire::ErrorCode_Name(code);
    EXPECT_EQ(c.fatal_code.load(), -1) << c.reason();
    EXPECT_EQ(front.spoiled(), 2);
  }
}

// A clear Error in place of the robot's sealed Welcome (after a correct
// Challenge and Proof): also not final, whatever code it claims.
TEST(OperatorClientHandshake, AClearErrorInPlaceOfTheWelcomeIsNotFinal) {
  for (const wire::ErrorCode code : {wire::ERROR_CONTROL_TAKEN, wire::ERROR_AUTH_FAILED}) {
    Robot robot(test_key());
    Front front(robot.server->session_port(), [](int i) { return i < 1 ? Spoil::kErrorForWelcome : Spoil::kNone; },
                code);
    Client c(front.port(), test_key(), 10000);
    const bool opened = wait_until([&] { return c.client->session_open(); }, 8.0);
    std::printf("%s in clear after the Proof: %d connections, session %s, fatal %d \"%s\"\n",
                wire::ErrorCode_Name(code).c_str(), front.connections(), opened ? "open" : "never opened",
                c.fatal_code.load(), c.reason().c_str());
    EXPECT_TRUE(opened) << wire::ErrorCode_Name(code);
    EXPECT_EQ(c.fatal_code.load(), -1) << c.reason();
    EXPECT_EQ(front.spoiled(), 1);
  }
}

// A front that always answers with a clear Error: the operator keeps trying
// for its whole connect_for_ms, then gives up with the code the Errors claimed.
TEST(OperatorClientHandshake, ClearErrorsToTheEndOfTheBudgetGiveUpOnlyThenWithTheirCode) {
  Robot robot(test_key());
  Front front(robot.server->session_port(), [](int) { return Spoil::kErrorForChallenge; }, wire::ERROR_AUTH_FAILED);
  Client c(front.port(), test_key(), 1500);
  ASSERT_TRUE(wait_until([&] { return c.fatal_code.load() >= 0; }, 10.0));
  const double after_s = static_cast<double>(c.fatal_ns.load() - c.started_ns) * 1e-9;
  std::printf("gave up after %.2f s and %d connections: exit %d \"%s\"\n", after_s, front.connections(),
              c.fatal_code.load(), c.reason().c_str());
  EXPECT_GE(after_s, 1.4);
  EXPECT_GE(front.connections(), 3);
  EXPECT_EQ(c.fatal_code.load(), net::kExitAuth);
}

// What stays final at once: the robot's own, authenticated refusals. Control
// taken (sealed with the session keys) and a protocol version mismatch
// (before any key is derived; tagged with the pre-shared key over the
// operator's Hello).
TEST(OperatorClientHandshake, AnAuthenticatedRefusalIsFinalAtOnce) {
  Robot robot(test_key());
  Client first(robot.server->session_port(), test_key(), 10000);
  ASSERT_TRUE(wait_until([&] { return first.client->session_open() && first.client->link_up(); }, 5.0));
  Client second(robot.server->session_port(), test_key(), 10000);
  ASSERT_TRUE(wait_until([&] { return second.fatal_code.load() >= 0; }, 5.0));
  EXPECT_EQ(second.fatal_code.load(), net::kExitRefused) << second.reason();
  EXPECT_LT(static_cast<double>(second.fatal_ns.load() - second.started_ns) * 1e-9, 2.0);
  Client old(robot.server->session_port(), test_key(), 10000, 99);
  ASSERT_TRUE(wait_until([&] { return old.fatal_code.load() >= 0; }, 5.0));
  EXPECT_EQ(old.fatal_code.load(), net::kExitVersion) << old.reason();
  EXPECT_LT(static_cast<double>(old.fatal_ns.load() - old.started_ns) * 1e-9, 2.0);
  EXPECT_TRUE(first.client->session_open());
}

}  // namespace
}  // namespace hemm::test
