// StreamLink over real loopback sockets: a flood of rejected datagrams costs
// counters only, no allocation (no address text built per datagram).
#include "common/net/stream_link.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <functional>

#include <future>
#include <optional>
#include <thread>

#include "common/clock/steady_clock.h"
#include "common/net/datagram.h"
#include "tests/common/net/udp_forwarder.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::net {
namespace {

bool wait_until_true(const std::function<bool()>& pred, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pred();
}

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
    uint16_t bound = 0;
    const int fd = hemm::test::open_loopback_udp(&bound);
    timeval tv{0, 300000};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return std::make_pair(fd, bound);
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

// ---------------------------------------------------------------- issue 23 items 3 and 4

Key key_of(uint8_t seed) {
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(i * 37 + seed);
  return k;
}

// A peer played with a raw socket: answers every Ping of session `sid` with
// a Pong whose peer times are its own clock, `offset_ns` ahead of ours.
struct PongPeer {
  int fd = -1;
  uint16_t port = 0;
  uint64_t sid;
  Key tx, rx;  // peer -> link, link -> peer
  int64_t offset_ns;
  std::atomic<bool> stop{false};
  std::thread thread;
  PongPeer(uint64_t session, Key to_link, Key from_link, int64_t offset)
      : sid(session), tx(to_link), rx(from_link), offset_ns(offset) {
    fd = hemm::test::open_loopback_udp(&port);
    timeval tv{0, 20000};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    thread = std::thread([this] { run(); });
  }
  ~PongPeer() {
    stop = true;
    thread.join();
    ::close(fd);
  }
  asio::ip::udp::endpoint endpoint() const { return {asio::ip::address_v4::loopback(), port}; }
  void run() {
    uint8_t buf[2048];
    uint64_t seq = 1;
    while (!stop) {
      sockaddr_in from{};
      socklen_t len = sizeof from;
      const ssize_t n = ::recvfrom(fd, buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &len);
      if (n <= 0) continue;
      const int64_t t2 = steady_now_ns() + offset_ns;
      DatagramHeader h;
      std::vector<uint8_t> plain;
      wire::StreamMessage m;
      if (decode_datagram(std::span(buf, static_cast<size_t>(n)), sid, rx, &h, &plain) != DatagramError::kOk ||
          !m.ParseFromArray(plain.data(), static_cast<int>(plain.size())) || !m.has_ping())
        continue;
      wire::StreamMessage r;
      r.mutable_pong()->set_id(m.ping().id());
      r.mutable_pong()->set_t1_ns(m.ping().t1_ns());
      r.mutable_pong()->set_t2_ns(t2);
      r.mutable_pong()->set_t3_ns(steady_now_ns() + offset_ns);
      const std::string b = r.SerializeAsString();
      std::vector<uint8_t> d;
      encode_datagram(tx, DatagramHeader{sid, seq++, 0}, std::span(reinterpret_cast<const uint8_t*>(b.data()), b.size()),
                      &d);
      ::sendto(fd, d.data(), d.size(), 0, reinterpret_cast<sockaddr*>(&from), len);
    }
  }
};

// Runs f on the link's network thread and returns its result.
template <class F>
auto on_io(asio::io_context& io, F f) {
  std::promise<decltype(f())> p;
  auto fut = p.get_future();
  asio::post(io, [&] { p.set_value(f()); });
  return fut.get();
}

// Issue 23 item 3: a new session (a second operator host) starts with no
// clock estimate: the first host's offset and round trip are not used to
// judge its commands (with no estimate every command is refused as of
// unknown age), and the estimate it gets is of the new host only.
TEST(StreamLink, ANewSessionStartsWithoutAClockEstimateAndMeasuresOnlyItsOwnPeer) {
  asio::io_context io;
  StreamLinkParams p;
  p.role = "robot";
  p.ping_period_ms = 20;
  StreamLink link(io, p);
  std::string err;
  ASSERT_TRUE(link.bind(asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), 0), &err)) << err;
  PongPeer first(11, key_of(1), key_of(2), 0);
  PongPeer second(12, key_of(3), key_of(4), 3'000'000'000);  // its clock is 3 s ahead of ours
  link.open_session(11, key_of(2), key_of(1), first.endpoint());
  auto guard = asio::make_work_guard(io);
  std::thread net([&] { io.run(); });
  auto estimate = [&] { return on_io(io, [&] { return link.clock(); }); };
  ASSERT_TRUE(wait_until_true([&] { return estimate().samples >= 20; }, 5.0));
  const ClockEstimate e1 = estimate();
  EXPECT_LT(std::abs(e1.offset_ns), 5'000'000);
  // The first host leaves; the second opens a session. On the network thread,
  // right after the open (no pong can have come yet):
  const auto [valid_after_open, age] = on_io(io, [&] {
    link.close_session();
    link.open_session(12, key_of(4), key_of(3), second.endpoint());
    // A command stamped "now" on the new host's clock, as the robot judges it.
    return std::make_pair(link.clock().valid,
                          judge_message_age(link.clock(), steady_now_ns() + 3'000'000'000, steady_now_ns(),
                                            200'000'000));
  });
  EXPECT_FALSE(valid_after_open) << "the first host's estimate survived into the new session";
  EXPECT_FALSE(age.known);
  EXPECT_TRUE(age.stale);
  EXPECT_FALSE(link.statistics().clock.valid);
  ASSERT_TRUE(wait_until_true([&] { return estimate().samples >= 20; }, 5.0));
  const ClockEstimate e2 = estimate();
  std::printf("first host: offset %.3f ms; second host (3 s ahead): offset %.3f ms after %llu samples\n",
              e1.offset_ns * 1e-6, e2.offset_ns * 1e-6, static_cast<unsigned long long>(e2.samples));
  EXPECT_NEAR(static_cast<double>(e2.offset_ns), 3e9, 5e6);
  EXPECT_NEAR(static_cast<double>(link.statistics().clock.offset_ns), 3e9, 5e6);
  asio::post(io, [&] { link.stop(); });
  guard.reset();
  io.stop();
  net.join();
}

// The robot's and the operator's stream links on one network thread, the
// operator sending to a forwarder (tests/common/net/udp_forwarder.h) that
// passes its datagrams on to the robot: the genuine path.
struct Pair {
  asio::io_context io;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work;
  std::unique_ptr<StreamLink> robot, op;
  std::unique_ptr<hemm::test::UdpForwarder> path;
  std::thread thread;
  Pair() {
    StreamLinkParams rp;
    rp.role = "robot";
    rp.learn_peer_from_source = true;
    rp.link_timeout_ms = 1000;  // quiet time: 500 ms
    robot = std::make_unique<StreamLink>(io, rp);
    StreamLinkParams op_p;
    op_p.role = "operator";
    op_p.link_timeout_ms = 1000;
    op = std::make_unique<StreamLink>(io, op_p);
    std::string err;
    EXPECT_TRUE(robot->bind(asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), 0), &err)) << err;
    EXPECT_TRUE(op->bind(asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), 0), &err)) << err;
    path = std::make_unique<hemm::test::UdpForwarder>(robot->local_endpoint().port());
    robot->open_session(77, key_of(5), key_of(6), std::nullopt);
    op->open_session(77, key_of(6), key_of(5),
                     asio::ip::udp::endpoint(asio::ip::address_v4::loopback(), path->front_port()));
    work.emplace(io.get_executor());
    thread = std::thread([this] { io.run(); });
  }
  ~Pair() {
    asio::post(io, [this] {
      robot->stop();
      op->stop();
    });
    work.reset();
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    io.stop();
    thread.join();
  }
  PathCounters counters() { return robot->statistics().path; }
};

void sleep_ms(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

// The forwarder in the genuine path earns a token: the operator's traffic has
// a short gap (600 ms, past the robot's quiet time, short of its link
// timeout), and in it the forwarder sends a copy of an operator datagram from
// a second address of its own; the robot challenges that address. The
// forwarder keeps the challenge, lets the genuine path carry traffic again
// (a heartbeat or two: 80 ms), then passes the challenge to the operator,
// whose answer goes to the robot. The token is still live (well inside its
// 250 ms floor), but the current path is not silent: the answer validates
// nothing, and the robot keeps sending to the genuine path.
TEST(StreamLink, ATokenEarnedInAShortGapCannotBeRedeemedWhileTheGenuinePathCarriesTraffic) {
  Pair s;
  ASSERT_TRUE(wait_until_true([&] { return s.robot->link_up() && s.counters().validated == 1; }, 3.0));
  s.path->set_upstream_paused(true);
  sleep_ms(600);
  const auto earned = std::chrono::steady_clock::now();
  ASSERT_TRUE(s.path->send_copy_from_side());
  ASSERT_TRUE(wait_until_true([&] { return s.path->side_held() >= 1; }, 1.0)) << "the robot sent no challenge";
  s.path->set_upstream_paused(false);
  sleep_ms(80);
  ASSERT_TRUE(s.robot->link_up());
  const uint64_t side_before = s.path->side_received();
  ASSERT_EQ(s.path->release_side_to_operator(), 1u);
  const double held_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - earned).count();
  sleep_ms(300);
  const PathCounters c = s.counters();
  const uint64_t side_after = s.path->side_received();
  std::printf("redeemed %.0f ms after it was earned, the path carrying traffic: validated %llu, unmatched %llu, "
              "refused %llu; datagrams to the forwarder's second address after: %llu\n",
              held_ms, static_cast<unsigned long long>(c.validated),
              static_cast<unsigned long long>(c.responses_unmatched),
              static_cast<unsigned long long>(c.responses_refused),
              static_cast<unsigned long long>(side_after - side_before));
  EXPECT_EQ(c.validated, 1u) << "the robot switched to the forwarder's second address";
  EXPECT_EQ(side_after - side_before, 0u);
  EXPECT_EQ(c.responses_refused + c.responses_unmatched, 1u);
  // Refused for the live path, not for its age (when this VM did not stall
  // the test past the token's 250 ms).
  if (held_ms < 200.0) {
    EXPECT_EQ(c.responses_refused, 1u);
  }
}

// The same forwarder keeps the token for 2 s and redeems it in a second gap of
// the genuine path (the path silent again, so only the token's age can refuse
// it): a token lives a few round trips (here the floor), not 20 s.
TEST(StreamLink, ATokenHeldLongerThanAFewRoundTripsValidatesNothing) {
  Pair s;
  ASSERT_TRUE(wait_until_true([&] { return s.robot->link_up() && s.counters().validated == 1; }, 3.0));
  s.path->set_upstream_paused(true);
  sleep_ms(600);
  ASSERT_TRUE(s.path->send_copy_from_side());
  ASSERT_TRUE(wait_until_true([&] { return s.path->side_held() >= 1; }, 1.0)) << "the robot sent no challenge";
  s.path->set_upstream_paused(false);
  sleep_ms(1400);
  // A second gap, long enough that the genuine path is silent.
  s.path->set_upstream_paused(true);
  sleep_ms(600);
  ASSERT_EQ(s.path->release_side_to_operator(), 1u);
  // The operator's answer goes to the robot from the forwarder's second
  // address (the genuine path still silent).
  sleep_ms(50);
  EXPECT_GT(s.path->send_held_upstream_from_side(), 0u);
  sleep_ms(200);
  const PathCounters c = s.counters();
  std::printf("redeemed 2 s later in a second gap: validated %llu, unmatched %llu, refused %llu\n",
              static_cast<unsigned long long>(c.validated), static_cast<unsigned long long>(c.responses_unmatched),
              static_cast<unsigned long long>(c.responses_refused));
  EXPECT_EQ(c.validated, 1u) << "a 2 s old token validated the forwarder's second address";
  EXPECT_GE(c.responses_unmatched, 1u);  // expired
  EXPECT_EQ(c.responses_refused, 0u);    // the path was silent: only the age refused it
  s.path->set_upstream_paused(false);
}

// The genuine move still works: the operator's NAT gives its flow a new port
// (the old one falls silent at once); after the quiet time the robot
// challenges the new address, the operator answers, and the robot's streams
// go there.
TEST(StreamLink, AnOperatorWhoseNatRebindsIsValidatedAtItsNewAddressAfterTheOldOneWentQuiet) {
  Pair s;
  ASSERT_TRUE(wait_until_true([&] { return s.robot->link_up() && s.counters().validated == 1; }, 3.0));
  const uint64_t down_before = s.path->forwarded_down();
  s.path->rebind_exit();
  ASSERT_TRUE(wait_until_true([&] { return s.counters().validated == 2; }, 3.0));
  const uint64_t down_mid = s.path->forwarded_down();
  sleep_ms(300);
  std::printf("NAT rebinding: validated again; robot -> operator datagrams through the new port: %llu\n",
              static_cast<unsigned long long>(s.path->forwarded_down() - down_mid));
  EXPECT_GT(s.path->forwarded_down(), down_mid);
  EXPECT_GT(down_mid, down_before);
  EXPECT_TRUE(s.robot->link_up());
}

}  // namespace
}  // namespace hemm::net
