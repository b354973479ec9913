// StreamLink over real loopback sockets: a flood of rejected datagrams costs
// counters only, no allocation (no address text built per datagram).
#include "common/net/stream_link.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <thread>

#include "common/net/datagram.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::net {
namespace {

// Waits until `n` datagrams were received or none came for 300 ms (a loaded
// machine may drop some from the socket buffer); returns how many came.
uint64_t wait_received(StreamLink& link, uint64_t n) {
  uint64_t last = 0;
  int quiet_ms = 0;
  while (quiet_ms < 300) {
    const uint64_t got = link.statistics().rx.received;
    if (got >= n) return got;
    quiet_ms = got == last ? quiet_ms + 10 : 0;
    last = got;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return last;
}

TEST(StreamLink, RejectedDatagramsCostNoAllocation) {
  asio::io_context io;
  StreamLinkParams p;
  p.role = "robot";
  p.learn_peer_from_source = true;
  StreamLink link(io, p);
  std::string err;
  // Dual stack: IPv4 senders show up as ::ffff:127.0.0.1, text too long for a
  // short-string buffer, so building it per datagram would allocate.
  if (!link.bind(asio::ip::udp::endpoint(asio::ip::address_v6::any(), 0), &err)) GTEST_SKIP() << err;
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(i * 29 + 7);
  link.open_session(42, k, k, std::nullopt);
  const uint16_t port = link.local_endpoint().port();
  std::thread net([&] { io.run(); });

  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  to.sin_port = htons(port);
  // Rejected for every reason the receiver checks before and at the AEAD.
  std::vector<std::vector<uint8_t>> bad;
  bad.push_back(std::vector<uint8_t>(20, 0x48));         // too short
  bad.push_back(std::vector<uint8_t>(100, 0x00));        // bad magic
  std::vector<uint8_t> d;
  encode_datagram(k, DatagramHeader{43, 1, 0}, std::vector<uint8_t>(30, 1), &d);  // unknown session
  bad.push_back(d);
  Key wrong = k;
  wrong[0] ^= 1;
  encode_datagram(wrong, DatagramHeader{42, 1, 0}, std::vector<uint8_t>(30, 1), &d);  // bad tag
  bad.push_back(d);
  auto send_all = [&](int n) {
    for (int i = 0; i < n; ++i) {
      const auto& b = bad[static_cast<size_t>(i) % bad.size()];
      ::sendto(fd, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
      if (i % 64 == 63) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // no socket-buffer drops
    }
  };
  send_all(200);  // warm-up: handler memory, first-time paths
  ASSERT_GE(wait_received(link, 200), 100u);
  asio::post(io, [] { hemm::test::count_allocations_on_this_thread(true); });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const uint64_t before = hemm::test::counted_allocations();
  const uint64_t received_before = link.statistics().rx.received;
  send_all(4000);
  const uint64_t n = wait_received(link, received_before + 4000) - received_before;
  ASSERT_GE(n, 1000u) << "too few datagrams arrived to judge";
  asio::post(io, [] { hemm::test::count_allocations_on_this_thread(false); });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const uint64_t allocations = hemm::test::counted_allocations() - before;
  const auto st = link.statistics();
  std::printf("%llu rejected datagrams: %llu allocations on the network thread (its timers included)\n",
              static_cast<unsigned long long>(n), static_cast<unsigned long long>(allocations));
  EXPECT_EQ(st.rx.delivered, 0u);
  EXPECT_EQ(st.rx.rejected_total(), st.rx.received);
  // The link's own 50 ms heartbeat/ping timer allocates a few messages while
  // the window is open; per datagram there must be nothing.
  EXPECT_LT(allocations, 20 + n / 20);
  ::close(fd);
  asio::post(io, [&] { link.stop(); });
  io.stop();
  net.join();
}

// The operator answers a path challenge only when it comes from the address
// it sends to: a challenge the robot sent to someone else's address, passed
// on to the operator from there, gets no answer (else that address would be
// validated by the operator's own response).
TEST(StreamLink, OperatorAnswersPathChallengesOnlyFromItsPeer) {
  asio::io_context io;
  StreamLinkParams p;
  p.role = "operator";
  StreamLink link(io, p);
  std::string err;
  ASSERT_TRUE(link.bind(asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), 0), &err)) << err;
  const uint16_t port = link.local_endpoint().port();
  auto udp = [] {
    const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    timeval tv{0, 300000};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return std::make_pair(fd, ntohs(a.sin_port));
  };
  const auto [robot_fd, robot_port] = udp();
  const auto [other_fd, other_port] = udp();
  Key c2s{}, s2c{};
  for (size_t i = 0; i < c2s.size(); ++i) {
    c2s[i] = static_cast<uint8_t>(i * 31 + 1);
    s2c[i] = static_cast<uint8_t>(i * 17 + 5);
  }
  link.open_session(7, c2s, s2c,
                    asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), static_cast<uint16_t>(robot_port)));
  std::thread net([&] { io.run(); });
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  to.sin_port = htons(port);
  auto challenge = [&](uint64_t seq, uint8_t first) {
    wire::StreamMessage m;
    std::string token(16, '\x11');
    token[0] = static_cast<char>(first);
    m.mutable_path_challenge()->set_token(token);
    const std::string b = m.SerializeAsString();
    std::vector<uint8_t> d;
    encode_datagram(s2c, DatagramHeader{7, seq, 0}, std::span(reinterpret_cast<const uint8_t*>(b.data()), b.size()),
                    &d);
    return d;
  };
  // Responses the "robot" socket gets (it also gets the operator's heartbeats and pings).
  auto responses = [&](int fd) {
    std::vector<std::string> tokens;
    uint8_t buf[2048];
    // The operator keeps sending heartbeats and pings: read for a while, not until silence.
    const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(500);
    while (std::chrono::steady_clock::now() < end) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) continue;
      DatagramHeader h;
      std::vector<uint8_t> plain;
      wire::StreamMessage m;
      if (decode_datagram(std::span(buf, static_cast<size_t>(n)), 7, c2s, &h, &plain) == DatagramError::kOk &&
          m.ParseFromArray(plain.data(), static_cast<int>(plain.size())) && m.has_path_response()) {
        tokens.push_back(m.path_response().token());
      }
    }
    return tokens;
  };
  const auto from_other = challenge(1, 0xaa);
  ::sendto(other_fd, from_other.data(), from_other.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
  const auto from_robot = challenge(2, 0xbb);
  ::sendto(robot_fd, from_robot.data(), from_robot.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to);
  const auto got = responses(robot_fd);
  ASSERT_EQ(got.size(), 1u) << "exactly one challenge answered";
  EXPECT_EQ(static_cast<uint8_t>(got[0][0]), 0xbb);
  EXPECT_TRUE(responses(other_fd).empty());
  EXPECT_EQ(link.statistics().path.ignored, 1u);
  ::close(robot_fd);
  ::close(other_fd);
  asio::post(io, [&] { link.stop(); });
  io.stop();
  net.join();
}

}  // namespace
}  // namespace hemm::net
