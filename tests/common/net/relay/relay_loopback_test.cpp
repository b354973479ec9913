// Loopback tests of the impairment relay with small echo servers (POSIX sockets on the
// test side, so the relay's Asio code is exercised against independent code). Timing
// assertions use medians with wide margins: the machine is a shared 2-core VM.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/net/relay/relay.h"
#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::net::relay {
namespace {

constexpr std::int64_t kMs = 1'000'000;


double median_ms(std::vector<std::int64_t> v) {
  if (v.empty()) return -1.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return static_cast<double>(v[v.size() / 2]) / kMs;
}

sockaddr_in loopback(std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(port);
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return a;
}

std::uint16_t local_port(int fd) {
  sockaddr_in a{};
  socklen_t len = sizeof(a);
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  return ntohs(a.sin_port);
}

// RAII file descriptor.
struct Fd {
  int fd = -1;
  explicit Fd(int f = -1) : fd(f) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& o) noexcept : fd(o.fd) { o.fd = -1; }
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

Fd udp_bound() {
  Fd s(::socket(AF_INET, SOCK_DGRAM, 0));
  const sockaddr_in a = loopback(0);
  EXPECT_EQ(::bind(s.fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)), 0);
  return s;
}

bool readable(int fd, int timeout_ms) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, timeout_ms) > 0;
}

// Datagram payload: sequence number and send time (one steady clock for all sides).
struct Stamp {
  std::uint32_t seq;
  std::int64_t sent_ns;
};

// UDP echo server on its own thread; records one-way delays and sequence numbers.
class UdpEcho {
 public:
  UdpEcho() : sock_(udp_bound()) {
    port_ = local_port(sock_.fd);
    thread_ = std::thread([this] { loop(); });
  }
  ~UdpEcho() {
    stop_ = true;
    thread_.join();
  }
  std::uint16_t port() const { return port_; }
  // Snapshot (the thread appends while running).
  std::vector<std::pair<Stamp, std::int64_t>> received() {
    std::lock_guard lock(mu_);
    return received_;
  }

 private:
  void loop() {
    char buf[2048];
    while (!stop_) {
      if (!readable(sock_.fd, 20)) continue;
      sockaddr_in from{};
      socklen_t len = sizeof(from);
      const ssize_t n =
          ::recvfrom(sock_.fd, buf, sizeof(buf), 0, reinterpret_cast<sockaddr*>(&from), &len);
      const std::int64_t t = hemm::steady_now_ns();
      if (n < static_cast<ssize_t>(sizeof(Stamp))) continue;
      Stamp s;
      std::memcpy(&s, buf, sizeof(s));
      {
        std::lock_guard lock(mu_);
        received_.push_back({s, t});
      }
      ::sendto(sock_.fd, buf, static_cast<std::size_t>(n), 0, reinterpret_cast<sockaddr*>(&from), len);
    }
  }
  Fd sock_;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::mutex mu_;
  std::vector<std::pair<Stamp, std::int64_t>> received_;
  std::thread thread_;
};

// TCP echo server: accepts one connection, echoes until EOF, then closes.
class TcpEcho {
 public:
  TcpEcho() : listen_(::socket(AF_INET, SOCK_STREAM, 0)) {
    const int one = 1;
    ::setsockopt(listen_.fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    const sockaddr_in a = loopback(0);
    EXPECT_EQ(::bind(listen_.fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)), 0);
    EXPECT_EQ(::listen(listen_.fd, 4), 0);
    port_ = local_port(listen_.fd);
    thread_ = std::thread([this] { loop(); });
  }
  ~TcpEcho() {
    stop_ = true;
    thread_.join();
  }
  std::uint16_t port() const { return port_; }
  std::int64_t first_byte_ns() const { return first_byte_ns_; }
  bool saw_eof() const { return eof_; }

 private:
  void loop() {
    while (!stop_ && !readable(listen_.fd, 20)) {
    }
    if (stop_) return;
    Fd c(::accept(listen_.fd, nullptr, nullptr));
    const int one = 1;
    ::setsockopt(c.fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
    std::vector<char> buf(65536);
    while (!stop_) {
      if (!readable(c.fd, 20)) continue;
      const ssize_t n = ::recv(c.fd, buf.data(), buf.size(), 0);
      if (n <= 0) {
        eof_ = n == 0;
        break;
      }
      if (first_byte_ns_ == 0) first_byte_ns_ = hemm::steady_now_ns();
      std::size_t off = 0;
      while (off < static_cast<std::size_t>(n)) {
        const ssize_t w = ::send(c.fd, buf.data() + off, static_cast<std::size_t>(n) - off, MSG_NOSIGNAL);
        if (w <= 0) return;
        off += static_cast<std::size_t>(w);
      }
    }
  }
  Fd listen_;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<std::int64_t> first_byte_ns_{0};
  std::atomic<bool> eof_{false};
  std::thread thread_;
};

Fd tcp_connect(std::uint16_t port) {
  Fd s(::socket(AF_INET, SOCK_STREAM, 0));
  const sockaddr_in a = loopback(port);
  EXPECT_EQ(::connect(s.fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)), 0);
  const int one = 1;
  ::setsockopt(s.fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
  return s;
}

void send_stamp(int fd, std::uint16_t port, std::uint32_t seq) {
  const Stamp s{seq, hemm::steady_now_ns()};
  char buf[64] = {};
  std::memcpy(buf, &s, sizeof(s));
  const sockaddr_in a = loopback(port);
  ::sendto(fd, buf, sizeof(buf), 0, reinterpret_cast<const sockaddr*>(&a), sizeof(a));
}

// Receives echoes until `deadline_ns`, appending round-trip times and sequence numbers.
void drain_echoes(int fd, std::int64_t deadline_ns, std::vector<std::int64_t>& rtt,
                  std::vector<std::uint32_t>* seqs = nullptr) {
  char buf[2048];
  for (;;) {
    const std::int64_t left = deadline_ns - hemm::steady_now_ns();
    if (left <= 0) return;
    if (!readable(fd, static_cast<int>(std::max<std::int64_t>(1, left / kMs)))) continue;
    const ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n < static_cast<ssize_t>(sizeof(Stamp))) continue;
    Stamp s;
    std::memcpy(&s, buf, sizeof(s));
    rtt.push_back(hemm::steady_now_ns() - s.sent_ns);
    if (seqs) seqs->push_back(s.seq);
  }
}

RelayConfig udp_config(std::uint16_t forward_port) {
  RelayConfig cfg;
  cfg.udp_listen = HostPort{"127.0.0.1", 0};
  cfg.udp_forward = HostPort{"127.0.0.1", forward_port};
  return cfg;
}

RelayConfig tcp_config(std::uint16_t forward_port) {
  RelayConfig cfg;
  cfg.tcp_listen = HostPort{"127.0.0.1", 0};
  cfg.tcp_forward = HostPort{"127.0.0.1", forward_port};
  return cfg;
}

TEST(RelayLoopback, UdpOneWayAndRoundTripDelayMatchConfig) {
  UdpEcho echo;
  RelayConfig cfg = udp_config(echo.port());
  cfg.up.delay_ns = 40 * kMs;
  cfg.down.delay_ns = 20 * kMs;
  Relay relay(cfg);
  Fd client = udp_bound();
  std::vector<std::int64_t> rtt;
  const int n = 60;
  for (int i = 0; i < n; ++i) {
    send_stamp(client.fd, relay.udp_listen_port(), static_cast<std::uint32_t>(i));
    drain_echoes(client.fd, hemm::steady_now_ns() + 10 * kMs, rtt);
  }
  drain_echoes(client.fd, hemm::steady_now_ns() + 300 * kMs, rtt);
  std::vector<std::int64_t> one_way;
  for (const auto& [stamp, t] : echo.received()) one_way.push_back(t - stamp.sent_ns);
  ASSERT_EQ(one_way.size(), static_cast<std::size_t>(n));
  ASSERT_EQ(rtt.size(), static_cast<std::size_t>(n));
  // Never early: the release is at least the delay after the relay received it.
  EXPECT_GE(*std::min_element(one_way.begin(), one_way.end()), 40 * kMs);
  EXPECT_GE(*std::min_element(rtt.begin(), rtt.end()), 60 * kMs);
  const double ow = median_ms(one_way);
  const double rt = median_ms(rtt);
  EXPECT_GE(ow, 40.0);
  EXPECT_LE(ow, 46.0);
  EXPECT_GE(rt, 60.0);
  EXPECT_LE(rt, 70.0);
  const RelayStats s = relay.stats();
  EXPECT_EQ(s.udp_up.forwarded, static_cast<std::uint64_t>(n));
  EXPECT_EQ(s.udp_down.forwarded, static_cast<std::uint64_t>(n));
  EXPECT_EQ(s.udp_clients, 1u);
  EXPECT_EQ(s.send_errors, 0u);
  EXPECT_EQ(s.timing.samples, static_cast<std::uint64_t>(2 * n));
  EXPECT_LT(s.timing.median_us, 2000.0);
  std::printf("udp one-way median %.3f ms (config 40), rtt median %.3f ms (config 60); relay send "
              "error median %.1f us p99 %.1f us max %.1f us\n",
              ow, rt, s.timing.median_us, s.timing.p99_us, s.timing.max_us);
}

TEST(RelayLoopback, UdpLossRateRoughlyRightAndCountersMatchDelivery) {
  UdpEcho echo;
  RelayConfig cfg = udp_config(echo.port());
  cfg.up.loss = 0.2;
  cfg.seed = 99;
  Relay relay(cfg);
  Fd client = udp_bound();
  const int n = 2000;
  std::vector<std::int64_t> rtt;
  for (int i = 0; i < n; ++i) {
    send_stamp(client.fd, relay.udp_listen_port(), static_cast<std::uint32_t>(i));
    // Paced (~2 datagrams/ms) so no socket buffer overflows on a loaded machine.
    if (i % 10 == 9) drain_echoes(client.fd, hemm::steady_now_ns() + 5 * kMs, rtt);
  }
  drain_echoes(client.fd, hemm::steady_now_ns() + 300 * kMs, rtt);
  const RelayStats s = relay.stats();
  const auto got = echo.received();
  EXPECT_EQ(s.udp_up.received, static_cast<std::uint64_t>(n));
  EXPECT_EQ(got.size(), s.udp_up.forwarded);
  EXPECT_EQ(rtt.size(), got.size());  // nothing lost on the way back
  const double loss = 1.0 - static_cast<double>(got.size()) / n;
  EXPECT_NEAR(loss, 0.2, 0.04);
  EXPECT_EQ(s.udp_up.dropped_random, static_cast<std::uint64_t>(n) - got.size());
}

TEST(RelayLoopback, UdpRepliesComeFromTheListenAddressPerClient) {
  UdpEcho echo;
  Relay relay(udp_config(echo.port()));
  Fd a = udp_bound();
  Fd b = udp_bound();
  send_stamp(a.fd, relay.udp_listen_port(), 1);
  send_stamp(b.fd, relay.udp_listen_port(), 2);
  for (Fd* f : {&a, &b}) {
    ASSERT_TRUE(readable(f->fd, 2000));
    char buf[128];
    sockaddr_in from{};
    socklen_t len = sizeof(from);
    const ssize_t n = ::recvfrom(f->fd, buf, sizeof(buf), 0, reinterpret_cast<sockaddr*>(&from), &len);
    ASSERT_GE(n, static_cast<ssize_t>(sizeof(Stamp)));
    Stamp s;
    std::memcpy(&s, buf, sizeof(s));
    EXPECT_EQ(s.seq, f == &a ? 1u : 2u);  // each client gets its own reply
    EXPECT_EQ(ntohs(from.sin_port), relay.udp_listen_port());
  }
  EXPECT_EQ(relay.stats().udp_clients, 2u);
}

TEST(RelayLoopback, TcpDataArrivesCompleteAndInOrderWithJitter) {
  TcpEcho echo;
  RelayConfig cfg = tcp_config(echo.port());
  cfg.up.delay_ns = 5 * kMs;
  cfg.up.jitter_ns = 4 * kMs;
  cfg.down.delay_ns = 3 * kMs;
  cfg.down.jitter_ns = 3 * kMs;
  cfg.down.jitter_distribution = JitterDistribution::kNormal;
  Relay relay(cfg);
  Fd c = tcp_connect(relay.tcp_listen_port());
  const std::size_t total = 3u << 20;
  std::vector<char> data(total);
  std::mt19937 rng(5);
  for (char& ch : data) ch = static_cast<char>(rng());
  std::thread writer([&] {
    std::size_t off = 0;
    while (off < total) {
      const std::size_t chunk = std::min<std::size_t>(total - off, 1000 + rng() % 30000);
      const ssize_t w = ::send(c.fd, data.data() + off, chunk, MSG_NOSIGNAL);
      if (w <= 0) return;
      off += static_cast<std::size_t>(w);
    }
    ::shutdown(c.fd, SHUT_WR);
  });
  std::vector<char> back;
  back.reserve(total);
  std::vector<char> buf(65536);
  bool eof = false;
  const std::int64_t deadline = hemm::steady_now_ns() + 30'000 * kMs;
  while (hemm::steady_now_ns() < deadline) {
    if (!readable(c.fd, 100)) continue;
    const ssize_t n = ::recv(c.fd, buf.data(), buf.size(), 0);
    if (n <= 0) {
      eof = n == 0;
      break;
    }
    back.insert(back.end(), buf.begin(), buf.begin() + n);
  }
  writer.join();
  EXPECT_TRUE(eof) << "end of stream passed through both ways";
  ASSERT_EQ(back.size(), total);
  EXPECT_TRUE(back == data);
  const RelayStats s = relay.stats();
  EXPECT_EQ(s.tcp_up.bytes_received, total);
  EXPECT_EQ(s.tcp_down.bytes_received, total);
  EXPECT_EQ(s.tcp_up.reordered, 0u);
  EXPECT_EQ(s.tcp_connections, 1u);
  EXPECT_TRUE(echo.saw_eof());
}

TEST(RelayLoopback, TcpRateLimitPacesThroughputWithBackpressure) {
  TcpEcho echo;
  RelayConfig cfg = tcp_config(echo.port());
  cfg.up.rate_bytes_per_s = 200'000;  // 1.6 Mbit/s
  cfg.up.queue_bytes = 16'000;
  cfg.tcp_max_pending_bytes = 16'000;  // reading pauses beyond this: TCP backpressure
  Relay relay(cfg);
  Fd c = tcp_connect(relay.tcp_listen_port());
  const std::size_t total = 200'000;
  std::vector<char> data(total, 'x');
  const std::int64_t t0 = hemm::steady_now_ns();
  std::thread writer([&] {
    std::size_t off = 0;
    while (off < total) {
      const ssize_t w = ::send(c.fd, data.data() + off, total - off, MSG_NOSIGNAL);
      if (w <= 0) return;
      off += static_cast<std::size_t>(w);
    }
  });
  std::size_t got = 0;
  std::vector<char> buf(65536);
  while (got < total && hemm::steady_now_ns() - t0 < 10'000 * kMs) {
    if (!readable(c.fd, 100)) continue;
    const ssize_t n = ::recv(c.fd, buf.data(), buf.size(), 0);
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  const double seconds = static_cast<double>(hemm::steady_now_ns() - t0) * 1e-9;
  writer.join();
  ASSERT_EQ(got, total);
  // 200 kB at 200 kB/s: one second, plus scheduling slack.
  EXPECT_GE(seconds, 0.98);
  EXPECT_LE(seconds, 1.4);
  EXPECT_EQ(relay.stats().tcp_up.dropped(), 0u);
  std::printf("tcp 200 kB at 200 kB/s took %.3f s\n", seconds);
}

TEST(RelayLoopback, TcpRoundTripDelayMatchesConfig) {
  TcpEcho echo;
  RelayConfig cfg = tcp_config(echo.port());
  cfg.up.delay_ns = 25 * kMs;
  cfg.down.delay_ns = 15 * kMs;
  Relay relay(cfg);
  Fd c = tcp_connect(relay.tcp_listen_port());
  std::vector<std::int64_t> rtt;
  for (int i = 0; i < 15; ++i) {
    const std::int64_t t0 = hemm::steady_now_ns();
    const char ping = static_cast<char>('a' + i);
    ASSERT_EQ(::send(c.fd, &ping, 1, MSG_NOSIGNAL), 1);
    ASSERT_TRUE(readable(c.fd, 3000));
    char pong = 0;
    ASSERT_EQ(::recv(c.fd, &pong, 1, 0), 1);
    EXPECT_EQ(pong, ping);
    rtt.push_back(hemm::steady_now_ns() - t0);
  }
  EXPECT_GE(*std::min_element(rtt.begin(), rtt.end()), 40 * kMs);
  const double med = median_ms(rtt);
  EXPECT_LE(med, 48.0);
  std::printf("tcp rtt median %.3f ms (config 40)\n", med);
}

TEST(RelayLoopback, OutageHoldsTcpAndDropsUdp) {
  UdpEcho uecho;
  TcpEcho techo;
  RelayConfig cfg;
  cfg.udp_listen = HostPort{"127.0.0.1", 0};
  cfg.udp_forward = HostPort{"127.0.0.1", uecho.port()};
  cfg.tcp_listen = HostPort{"127.0.0.1", 0};
  cfg.tcp_forward = HostPort{"127.0.0.1", techo.port()};
  for (auto* d : {&cfg.up, &cfg.down}) d->outages = {{300 * kMs, 400 * kMs}};
  const std::int64_t before = hemm::steady_now_ns();  // the relay's start (outage origin) is after this
  Relay relay(cfg);
  const std::int64_t t0 = hemm::steady_now_ns();  // ... and before this
  Fd tcp = tcp_connect(relay.tcp_listen_port());
  Fd udp = udp_bound();
  std::vector<std::int64_t> rtt;
  std::vector<std::uint32_t> echoed;
  std::vector<std::int64_t> udp_sent_rel(120);
  bool tcp_sent = false;
  std::int64_t tcp_sent_rel = 0;
  for (std::uint32_t i = 0; i < 120; ++i) {
    udp_sent_rel[i] = hemm::steady_now_ns() - t0;
    send_stamp(udp.fd, relay.udp_listen_port(), i);
    if (!tcp_sent && udp_sent_rel[i] >= 400 * kMs) {
      tcp_sent_rel = hemm::steady_now_ns() - t0;
      ASSERT_EQ(::send(tcp.fd, "held", 4, MSG_NOSIGNAL), 4);
      tcp_sent = true;
    }
    drain_echoes(udp.fd, t0 + (i + 1) * 10 * kMs, rtt, &echoed);
  }
  ASSERT_TRUE(tcp_sent);
  EXPECT_LT(tcp_sent_rel, 650 * kMs);
  drain_echoes(udp.fd, hemm::steady_now_ns() + 100 * kMs, rtt, &echoed);
  // TCP: held until the outage ends, then delivered intact.
  ASSERT_TRUE(readable(tcp.fd, 3000));
  char buf[16] = {};
  std::size_t got = 0;
  while (got < 4 && readable(tcp.fd, 1000)) {
    const ssize_t n = ::recv(tcp.fd, buf + got, 4 - got, 0);
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  EXPECT_EQ(std::string(buf, got), "held");
  EXPECT_GE(techo.first_byte_ns() - before, 700 * kMs);

  // UDP: datagrams sent well inside the window are dropped, well outside delivered.
  std::vector<bool> arrived(120, false);
  for (const auto& [stamp, t] : uecho.received()) arrived[stamp.seq] = true;
  int inside = 0, inside_lost = 0, outside = 0, outside_ok = 0;
  for (std::size_t i = 0; i < 120; ++i) {
    const std::int64_t rel = udp_sent_rel[i];
    if (rel >= 310 * kMs && rel < 650 * kMs) {
      ++inside;
      inside_lost += !arrived[i];
    } else if (rel < 250 * kMs || rel >= 760 * kMs) {
      ++outside;
      outside_ok += arrived[i];
    }
  }
  ASSERT_GT(inside, 20);
  ASSERT_GT(outside, 40);
  EXPECT_GE(inside_lost, inside * 9 / 10);
  EXPECT_GE(outside_ok, outside * 9 / 10);
  const RelayStats s = relay.stats();
  EXPECT_GE(s.udp_up.dropped_outage, static_cast<std::uint64_t>(inside_lost));
  EXPECT_EQ(s.tcp_up.held_outage, 1u);
  EXPECT_EQ(s.tcp_up.dropped(), 0u);
}

TEST(RelayLoopback, StopIsCleanWithTrafficInFlight) {
  UdpEcho echo;
  RelayConfig cfg = udp_config(echo.port());
  cfg.up.delay_ns = 500 * kMs;  // still scheduled when we stop
  auto relay = std::make_unique<Relay>(cfg);
  Fd client = udp_bound();
  for (std::uint32_t i = 0; i < 50; ++i) send_stamp(client.fd, relay->udp_listen_port(), i);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  relay->stop();
  relay->stop();  // idempotent
  EXPECT_EQ(relay->stats().udp_up.received, 50u);
  relay.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_TRUE(echo.received().empty());  // scheduled sends were cancelled
}

TEST(RelayConfigTest, ValidationAndEndpointParsing) {
  RelayConfig cfg;
  EXPECT_NE(validate(cfg), "");  // nothing to relay
  cfg.udp_listen = HostPort{"127.0.0.1", 0};
  EXPECT_NE(validate(cfg).find("UDP"), std::string::npos);
  cfg.udp_forward = HostPort{"127.0.0.1", 9};
  EXPECT_EQ(validate(cfg), "");
  cfg.down.loss = -0.5;
  EXPECT_EQ(validate(cfg).rfind("down: ", 0), 0u);
  EXPECT_THROW(Relay{cfg}, std::invalid_argument);

  HostPort hp{"unchanged", 7};
  EXPECT_EQ(parse_host_port("127.0.0.1:9000", hp), "");
  EXPECT_EQ(hp.host, "127.0.0.1");
  EXPECT_EQ(hp.port, 9000);
  EXPECT_EQ(parse_host_port("[::1]:80", hp), "");
  EXPECT_EQ(hp.host, "::1");
  EXPECT_EQ(to_string(hp), "[::1]:80");
  for (const char* bad : {"127.0.0.1", "127.0.0.1:", "127.0.0.1:70000", "127.0.0.1:12x",
                          "nohost.example:80", "::1:80", "[::1]80", ""}) {
    HostPort keep{"keep", 1};
    EXPECT_NE(parse_host_port(bad, keep), "") << bad;
    EXPECT_EQ(keep.host, "keep");
    EXPECT_EQ(keep.port, 1);
  }
}

// ---------------------------------------------------------------- the binary

std::string relay_binary() { return std::string(HEMM_BINARY_DIR) + "/bin/hemm-relay"; }

int run_status(const std::string& args) {
  const int st = std::system((relay_binary() + " " + args + " >/dev/null 2>&1").c_str());
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

TEST(RelayBinary, BadArgumentsExitWithCode2) {
  const std::string udp = "--udp-listen 127.0.0.1:0 --udp-forward 127.0.0.1:9 ";
  EXPECT_EQ(run_status(udp + "--loss 2"), 2);
  EXPECT_EQ(run_status(udp + "--up-loss -0.1"), 2);
  EXPECT_EQ(run_status(udp + "--bogus-option 1"), 2);
  EXPECT_EQ(run_status(udp + "--jitter-dist cauchy"), 2);
  EXPECT_EQ(run_status(udp + "--ge 0.1,0.2,0.3"), 2);
  EXPECT_EQ(run_status(udp + "--outage 5"), 2);
  EXPECT_EQ(run_status(udp + "--delay-ms abc"), 2);
  EXPECT_EQ(run_status("--udp-listen 127.0.0.1:0"), 2);  // pair incomplete
  EXPECT_EQ(run_status("--tcp-listen 127.0.0.1:99999 --tcp-forward 127.0.0.1:9"), 2);
  EXPECT_EQ(run_status(""), 2);  // nothing to relay
  EXPECT_EQ(run_status("--help"), 0);
}

std::uint16_t free_udp_port() {
  Fd s = udp_bound();
  return local_port(s.fd);
}

TEST(RelayBinary, RelaysAndWritesJsonStats) {
  UdpEcho echo;
  const std::uint16_t port = free_udp_port();
  const std::string json_path =
      std::string(HEMM_BINARY_DIR) + "/relay_binary_stats_" + std::to_string(::getpid()) + ".json";
  std::remove(json_path.c_str());
  const std::string cmd = relay_binary() + " --udp-listen 127.0.0.1:" + std::to_string(port) +
                          " --udp-forward 127.0.0.1:" + std::to_string(echo.port()) +
                          " --delay-ms 10 --up-delay-ms 20 --seed 3 --duration 1.5 --stats-json " +
                          json_path + " 2>/dev/null";
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  char line[256] = {};
  ASSERT_NE(std::fgets(line, sizeof(line), p), nullptr);
  EXPECT_EQ(std::string(line), "hemm-relay ready\n");
  Fd client = udp_bound();
  std::vector<std::int64_t> rtt;
  for (std::uint32_t i = 0; i < 20; ++i) {
    send_stamp(client.fd, port, i);
    drain_echoes(client.fd, hemm::steady_now_ns() + 5 * kMs, rtt);
  }
  drain_echoes(client.fd, hemm::steady_now_ns() + 200 * kMs, rtt);
  std::string out;
  while (std::fgets(line, sizeof(line), p)) out += line;
  const int st = ::pclose(p);
  ASSERT_TRUE(WIFEXITED(st));
  EXPECT_EQ(WEXITSTATUS(st), 0);
  EXPECT_EQ(rtt.size(), 20u);
  EXPECT_GE(median_ms(rtt), 30.0);  // 20 ms up + 10 ms down
  EXPECT_LE(median_ms(rtt), 40.0);
  EXPECT_NE(out.find("stats {\"tcp\":{\"up\":{"), std::string::npos) << out;
  std::ifstream f(json_path);
  ASSERT_TRUE(f.good());
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string json = ss.str();
  const report::Relay r = hemm::test::read_report_json<report::Relay>(json);  // strictly: no unknown keys
  EXPECT_EQ(r.tcp().up().received(), 0u);
  EXPECT_EQ(r.udp().up().received(), 20u);
  EXPECT_EQ(r.udp().up().forwarded(), 20u);
  EXPECT_EQ(r.udp().down().received(), 20u);
  EXPECT_EQ(r.udp().down().forwarded(), 20u);
  std::remove(json_path.c_str());
}

TEST(RelayBinary, SigtermStopsAndWritesStats) {
  const std::uint16_t port = free_udp_port();
  const std::string json_path =
      std::string(HEMM_BINARY_DIR) + "/relay_sigterm_stats_" + std::to_string(::getpid()) + ".json";
  std::remove(json_path.c_str());
  const std::string bin = relay_binary();
  const std::string listen = "127.0.0.1:" + std::to_string(port);
  std::vector<std::string> args = {bin, "--udp-listen", listen, "--udp-forward", "127.0.0.1:9",
                                   "--tcp-listen", "127.0.0.1:0", "--tcp-forward", "127.0.0.1:9",
                                   "--stats-json", json_path, "--duration", "0"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  int out[2];
  ASSERT_EQ(::pipe(out), 0);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, out[1], 1);
  posix_spawn_file_actions_addclose(&fa, out[0]);
  posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  ASSERT_EQ(::posix_spawn(&pid, bin.c_str(), &fa, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&fa);
  ::close(out[1]);
  FILE* f = ::fdopen(out[0], "r");
  ASSERT_NE(f, nullptr);
  char line[256] = {};
  ASSERT_NE(std::fgets(line, sizeof(line), f), nullptr);
  EXPECT_EQ(std::string(line), "hemm-relay ready\n");
  Fd client = udp_bound();
  for (std::uint32_t i = 0; i < 5; ++i) send_stamp(client.fd, port, i);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ASSERT_EQ(::kill(pid, SIGTERM), 0);
  std::string rest;
  while (std::fgets(line, sizeof(line), f)) rest += line;
  std::fclose(f);
  int st = 0;
  ASSERT_EQ(::waitpid(pid, &st, 0), pid);
  ASSERT_TRUE(WIFEXITED(st));
  EXPECT_EQ(WEXITSTATUS(st), 0);
  EXPECT_NE(rest.find("\"udp\":{\"up\":{\"received\":\"5\","), std::string::npos) << rest;
  std::ifstream jf(json_path);
  ASSERT_TRUE(jf.good());
  std::stringstream ss;
  ss << jf.rdbuf();
  EXPECT_NE(ss.str().find("\"udp\":{\"up\":{\"received\":\"5\","), std::string::npos) << ss.str();
  std::remove(json_path.c_str());
}

}  // namespace
}  // namespace hemm::net::relay
