// Loopback tests with the real binaries: handshake, refusals with their exit
// codes, and forged/replayed datagrams counted by the robot. The last test
// plays the operator itself (with the codec library) so that it can send
// exactly the datagrams it wants.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <fstream>
#include <optional>
#include <thread>

#include "common/net/datagram.h"
#include "common/net/framing.h"
#include "common/net/handshake.h"
#include "tests/integration/link/child_process.h"
#include "tests/sanitizer_build.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;
using net::Key;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kKeyFile = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/demo.key";

struct Robot {
  std::string dir;
  int session_port, stream_port;
  std::unique_ptr<ChildProcess> proc;
  std::string err() const { return read_file(dir + "/robot.err"); }
  std::string json() const { return read_file(dir + "/robot.json"); }
};

Robot start_robot(const std::string& dir, double duration_s, std::vector<std::string> extra = {}) {
  Robot r;
  r.dir = dir;
  r.session_port = free_port();
  r.stream_port = free_port();
  std::vector<std::string> argv = {kBin + "hemm-robot",
                                   "--config",
                                   std::string(HEMM_SOURCE_DIR) + "/deploy/configs/robot.pbtxt",
                                   "--key",
                                   kKeyFile,
                                   "--listen",
                                   "127.0.0.1",
                                   "--session-port",
                                   std::to_string(r.session_port),
                                   "--stream-port",
                                   std::to_string(r.stream_port),
                                   "--duration",
                                   std::to_string(duration_s),
                                   "--stats-json",
                                   dir + "/robot.json"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  r.proc = std::make_unique<ChildProcess>(argv, dir + "/robot.out", dir + "/robot.err");
  EXPECT_TRUE(r.proc->started());
  EXPECT_TRUE(wait_for_text(dir + "/robot.err", "event=listening", 10s)) << r.err();
  return r;
}

std::unique_ptr<ChildProcess> start_operator(const Robot& r, const std::string& name, double duration_s,
                                             std::vector<std::string> extra = {}) {
  std::vector<std::string> argv = {kBin + "hemm-operator",
                                   "--config",
                                   std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator.pbtxt",
                                   "--robot",
                                   "127.0.0.1",
                                   "--session-port",
                                   std::to_string(r.session_port),
                                   "--duration",
                                   std::to_string(duration_s),
                                   "--stats-json",
                                   r.dir + "/" + name + ".json"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  auto p = std::make_unique<ChildProcess>(argv, r.dir + "/" + name + ".out", r.dir + "/" + name + ".err");
  EXPECT_TRUE(p->started());
  return p;
}

double num(const std::string& json, const std::string& key) {
  auto v = json_number(json, key);
  EXPECT_TRUE(v.has_value()) << "missing " << key << " in " << json;
  return v.value_or(-1);
}

TEST(LinkLoopbackTest, HandshakeSucceedsAndPingPongMeasuresTheLink) {
  const std::string dir = make_temp_dir();
  Robot r = start_robot(dir, 6.0);
  auto op = start_operator(r, "op", 2.5);
  const auto op_rc = op->wait(20s);
  ASSERT_TRUE(op_rc.has_value()) << "operator hung";
  EXPECT_EQ(*op_rc, 0) << read_file(dir + "/op.err");
  r.proc->signal(SIGTERM);  // clean shutdown on a signal
  const auto rc = r.proc->wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << r.err();

  const std::string oj = read_file(dir + "/op.json");
  const std::string rj = r.json();
  EXPECT_EQ(num(oj, "sessions_opened"), 1);
  EXPECT_EQ(num(rj, "sessions_opened"), 1);
  // ~2.5 s of 20 Hz pings; allow for a loaded machine.
  EXPECT_GT(num(oj, "pongs_received"), 10) << oj;
  EXPECT_GT(num(rj, "pongs_received"), 10) << rj;
  EXPECT_EQ(num(oj, "clock_valid"), 1);
  // Same host, same steady clock: the offset is ~0 and the RTT small; wall-clock
  // bounds, so the release pass's only (tests/sanitizer_build.h), as everywhere.
  if (!kSanitizerBuild) {
    EXPECT_LT(std::abs(num(oj, "clock_offset_ms")), 5.0) << oj;
    EXPECT_LT(num(oj, "rtt_median_ms"), 50.0) << oj;
  }
  EXPECT_GE(num(oj, "rtt_min_ms"), 0.0);
  for (const char* k : {"rejected_bad_tag", "rejected_replay", "rejected_unknown_session", "rejected_bad_size",
                        "rejected_bad_version", "duplicated", "link_lost_events"}) {
    EXPECT_EQ(num(rj, k), 0) << k << " " << rj;
    EXPECT_EQ(num(oj, k), 0) << k << " " << oj;
  }
  EXPECT_NE(r.err().find("event=session_open"), std::string::npos);
  EXPECT_NE(r.err().find("event=peer_bye"), std::string::npos) << "operator should say Bye at the end";
  EXPECT_NE(read_file(dir + "/op.out").find("link statistics (operator)"), std::string::npos);
}

TEST(LinkLoopbackTest, WrongKeyIsRefusedWithExitCode4) {
  const std::string dir = make_temp_dir();
  Robot r = start_robot(dir, 8.0);
  {
    std::ofstream k(dir + "/wrong.key");
    // A strong key that is not the robot's.
    k << "5d0c3a9e7b21f4866ac1d8e93f0b7254c6e18a2d9f3b5e07a4c92d61f8b0e375\n";
  }
  auto op = start_operator(r, "op", 5.0, {"--key", dir + "/wrong.key"});
  const auto rc = op->wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 4) << read_file(dir + "/op.err");
  EXPECT_NE(read_file(dir + "/op.err").find("authentication failed"), std::string::npos) << read_file(dir + "/op.err");
  r.proc->signal(SIGINT);
  ASSERT_TRUE(r.proc->wait(20s).has_value());
  EXPECT_GE(num(r.json(), "handshakes_failed"), 1);
  EXPECT_EQ(num(r.json(), "sessions_opened"), 0);
}

TEST(LinkLoopbackTest, BadKeyFileGivesExitCode3) {
  const std::string dir = make_temp_dir();
  {
    std::ofstream k(dir + "/short.key");
    k << "abcd\n";
  }
  ChildProcess op({kBin + "hemm-operator", "--key", dir + "/short.key", "--duration", "1"}, dir + "/op.out",
                  dir + "/op.err");
  const auto rc = op.wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 3);
  EXPECT_NE(read_file(dir + "/op.err").find("64 hexadecimal"), std::string::npos) << read_file(dir + "/op.err");
}

TEST(LinkLoopbackTest, WeakKeyFileGivesExitCode3) {
  const std::string dir = make_temp_dir();
  {
    std::ofstream k(dir + "/zero.key");
    k << std::string(64, '0') << "\n";
  }
  for (const std::string bin : {"hemm-robot", "hemm-operator"}) {
    ChildProcess p({kBin + bin, "--key", dir + "/zero.key", "--duration", "1"}, dir + "/p.out", dir + "/p.err");
    const auto rc = p.wait(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 3) << bin << ": " << read_file(dir + "/p.err");
    EXPECT_NE(read_file(dir + "/p.err").find("key is weak"), std::string::npos) << read_file(dir + "/p.err");
  }
}

TEST(LinkLoopbackTest, DemoKeyIsRefusedOffLoopbackWithExitCode3) {
  const std::string dir = make_temp_dir();
  ChildProcess robot({kBin + "hemm-robot", "--config", std::string(HEMM_SOURCE_DIR) + "/deploy/configs/robot.pbtxt",
                      "--listen", "0.0.0.0", "--session-port", "0", "--stream-port", "0", "--duration", "1"},
                     dir + "/r.out", dir + "/r.err");
  auto rc = robot.wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 3) << read_file(dir + "/r.err");
  EXPECT_NE(read_file(dir + "/r.err").find("demo key is public"), std::string::npos) << read_file(dir + "/r.err");
  ChildProcess op({kBin + "hemm-operator", "--config", std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator.pbtxt",
                   "--robot", "192.0.2.7", "--duration", "1"},
                  dir + "/o.out", dir + "/o.err");
  rc = op.wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 3) << read_file(dir + "/o.err");
  EXPECT_NE(read_file(dir + "/o.err").find("demo key is public"), std::string::npos) << read_file(dir + "/o.err");
}

TEST(LinkLoopbackTest, KeyFileReadableByOthersIsWarnedAbout) {
  const std::string dir = make_temp_dir();
  const std::string key = dir + "/station.key";
  {
    std::ofstream k(key);
    k << "5d0c3a9e7b21f4866ac1d8e93f0b7254c6e18a2d9f3b5e07a4c92d61f8b0e375\n";
  }
  ::chmod(key.c_str(), 0644);
  ChildProcess robot({kBin + "hemm-robot", "--config", std::string(HEMM_SOURCE_DIR) + "/deploy/configs/robot.pbtxt",
                      "--key", key, "--session-port", "0", "--stream-port", "0", "--duration", "0.5"},
                     dir + "/r.out", dir + "/r.err");
  const auto rc = robot.wait(30s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << read_file(dir + "/r.err");
  EXPECT_NE(read_file(dir + "/r.err").find("is accessible to group or others (mode 0644)"), std::string::npos)
      << read_file(dir + "/r.err");
}

TEST(LinkLoopbackTest, OperatorWhoseDurationEndsBeforeItEverConnectedExitsWith7) {
  const std::string dir = make_temp_dir();
  const int nobody = free_port();  // nothing listens there
  ChildProcess op({kBin + "hemm-operator", "--config", std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator.pbtxt",
                   "--session-port", std::to_string(nobody), "--duration", "1"},
                  dir + "/o.out", dir + "/o.err");
  const auto rc = op.wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 7) << read_file(dir + "/o.err");
  EXPECT_NE(read_file(dir + "/o.err").find("before a session was opened"), std::string::npos)
      << read_file(dir + "/o.err");
}

TEST(LinkLoopbackTest, BadConfigGivesExitCode2WithFileLineColumn) {
  const std::string dir = make_temp_dir();
  {
    std::ofstream c(dir + "/bad.pbtxt");
    c << "link {\n  heartbeat_period_ms: \"fast\"\n}\n";
  }
  ChildProcess robot({kBin + "hemm-robot", "--config", dir + "/bad.pbtxt"}, dir + "/r.out", dir + "/r.err");
  const auto rc = robot.wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 2);
  EXPECT_NE(read_file(dir + "/r.err").find(dir + "/bad.pbtxt:2:"), std::string::npos) << read_file(dir + "/r.err");
}

TEST(LinkLoopbackTest, WrongProtocolVersionIsRefusedWithExitCode5) {
  const std::string dir = make_temp_dir();
  Robot r = start_robot(dir, 8.0);
  auto op = start_operator(r, "op", 5.0, {"--test-protocol-version", "99"});
  const auto rc = op->wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 5) << read_file(dir + "/op.err");
  EXPECT_NE(read_file(dir + "/op.err").find("protocol version mismatch"), std::string::npos)
      << read_file(dir + "/op.err");
  EXPECT_TRUE(wait_for_text(dir + "/robot.err", "ERROR_VERSION_MISMATCH", 5s)) << r.err();
}

TEST(LinkLoopbackTest, SecondOperatorIsRefusedWithControlTakenAndExitCode6) {
  const std::string dir = make_temp_dir();
  Robot r = start_robot(dir, 12.0);
  auto first = start_operator(r, "first", 6.0);
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=link_up", 10s)) << r.err();
  auto second = start_operator(r, "second", 5.0);
  const auto rc2 = second->wait(20s);
  ASSERT_TRUE(rc2.has_value());
  EXPECT_EQ(*rc2, 6) << read_file(dir + "/second.err");
  const std::string err2 = read_file(dir + "/second.err");
  EXPECT_NE(err2.find("control taken"), std::string::npos) << err2;
  EXPECT_NE(err2.find("ERROR_CONTROL_TAKEN"), std::string::npos) << err2;
  // The first operator is undisturbed.
  EXPECT_TRUE(first->running());
  const auto rc1 = first->wait(20s);
  ASSERT_TRUE(rc1.has_value());
  EXPECT_EQ(*rc1, 0) << read_file(dir + "/first.err");
  EXPECT_EQ(num(read_file(dir + "/first.json"), "link_lost_events"), 0);
  r.proc->signal(SIGTERM);
  ASSERT_TRUE(r.proc->wait(20s).has_value());
  EXPECT_EQ(num(r.json(), "sessions_refused"), 1);
  EXPECT_EQ(num(r.json(), "sessions_opened"), 1);
}

// ---------------------------------------------------------------- the test as operator

class RawOperator {
 public:
  bool connect_tcp(int port) {
    tcp_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a = loopback(port);
    return ::connect(tcp_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~RawOperator() {
    if (tcp_ >= 0) ::close(tcp_);
    if (udp_ >= 0) ::close(udp_);
  }
  static sockaddr_in loopback(int port) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(port));
    return a;
  }
  void send_frame(const std::vector<uint8_t>& payload) {
    std::vector<uint8_t> f;
    net::encode_frame(payload, &f);
    ASSERT_EQ(::send(tcp_, f.data(), f.size(), MSG_NOSIGNAL), static_cast<ssize_t>(f.size()));
  }
  std::optional<std::vector<uint8_t>> recv_frame(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::vector<uint8_t> p;
    for (;;) {
      if (dec_.next(&p) == net::FrameDecoder::Status::kFrame) return p;
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::nullopt;
      pollfd pf{tcp_, POLLIN, 0};
      if (::poll(&pf, 1, static_cast<int>(left.count())) <= 0) return std::nullopt;
      uint8_t buf[4096];
      const ssize_t n = ::recv(tcp_, buf, sizeof buf, 0);
      if (n <= 0) return std::nullopt;
      dec_.feed(std::span<const uint8_t>(buf, static_cast<size_t>(n)));
    }
  }
  void open_udp() {
    udp_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a = loopback(0);
    ::bind(udp_, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  void send_datagram(const std::vector<uint8_t>& d, int port) {
    sockaddr_in a = loopback(port);
    ::sendto(udp_, d.data(), d.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  std::optional<std::vector<uint8_t>> recv_datagram(std::chrono::milliseconds timeout) {
    pollfd pf{udp_, POLLIN, 0};
    if (::poll(&pf, 1, static_cast<int>(timeout.count())) <= 0) return std::nullopt;
    std::vector<uint8_t> b(2048);
    const ssize_t n = ::recv(udp_, b.data(), b.size(), 0);
    if (n < 0) return std::nullopt;
    b.resize(static_cast<size_t>(n));
    return b;
  }

  int tcp_ = -1, udp_ = -1;
  net::FrameDecoder dec_{1 << 20};
};

std::vector<uint8_t> datagram_of(const wire::StreamMessage& m, const Key& k, uint64_t sid, uint64_t seq) {
  const std::string p = m.SerializeAsString();
  std::vector<uint8_t> d;
  net::encode_datagram(k, net::DatagramHeader{sid, seq, net::DatagramHeader{}.send_time_ns},
                       std::span(reinterpret_cast<const uint8_t*>(p.data()), p.size()), &d);
  return d;
}

std::vector<uint8_t> heartbeat_datagram(const Key& k, uint64_t sid, uint64_t seq) {
  wire::StreamMessage m;
  m.mutable_heartbeat()->set_period_ms(50);
  return datagram_of(m, k, sid, seq);
}

TEST(LinkLoopbackTest, ForgedReplayedAndStaleDatagramsAreRejectedAndCounted) {
  const std::string dir = make_temp_dir();
  Robot r = start_robot(dir, 30.0);
  std::string key_error;
  const auto psk = net::load_key_file(kKeyFile, &key_error);
  ASSERT_TRUE(psk) << key_error;

  RawOperator op;
  ASSERT_TRUE(op.connect_tcp(r.session_port));
  net::ClientHandshake::Params hp;
  hp.psk = *psk;
  hp.station_name = "test-raw-operator";
  net::ClientHandshake hs(hp);
  op.send_frame(hs.start());
  auto challenge = op.recv_frame(5s);
  ASSERT_TRUE(challenge);
  auto step = hs.on_frame(*challenge);
  ASSERT_EQ(step.kind, net::HandshakeStep::Kind::kContinue) << step.reason;
  op.send_frame(step.reply);
  auto welcome = op.recv_frame(5s);
  ASSERT_TRUE(welcome);
  ASSERT_EQ(hs.on_frame(*welcome).kind, net::HandshakeStep::Kind::kOpen);
  net::SessionSecrets sec = hs.take_secrets();
  const uint64_t sid = sec.session_id;
  const Key k = sec.keys.udp_c2s;
  ASSERT_EQ(hs.welcome().stream_port(), static_cast<uint32_t>(r.stream_port));

  op.open_udp();
  const int port = r.stream_port;
  // 20 good ones: the robot challenges our address (path validation) ...
  for (uint64_t s = 1; s <= 20; ++s) op.send_datagram(heartbeat_datagram(k, sid, s), port);
  std::optional<wire::StreamMessage> challenge_msg;
  for (int i = 0; i < 20 && !challenge_msg; ++i) {
    auto d = op.recv_datagram(500ms);
    if (!d) continue;
    net::DatagramHeader h;
    std::vector<uint8_t> payload;
    wire::StreamMessage m;
    if (net::decode_datagram(*d, sid, sec.keys.udp_s2c, &h, &payload) == net::DatagramError::kOk &&
        m.ParseFromArray(payload.data(), static_cast<int>(payload.size())) && m.has_path_challenge()) {
      challenge_msg = m;
    }
  }
  ASSERT_TRUE(challenge_msg) << "the robot sent no path challenge";
  // ... we answer it (seq 21), and the link comes up.
  wire::StreamMessage response;
  response.mutable_path_response()->set_token(challenge_msg->path_challenge().token());
  op.send_datagram(datagram_of(response, k, sid, 21), port);
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=link_up", 5s)) << r.err();
  // 3 exact replays of seq 5.
  for (int i = 0; i < 3; ++i) op.send_datagram(heartbeat_datagram(k, sid, 5), port);
  // 4 forged: fresh sequence numbers, wrong key.
  Key wrong = k;
  wrong[0] ^= 0x80;
  for (uint64_t s = 22; s <= 25; ++s) op.send_datagram(heartbeat_datagram(wrong, sid, s), port);
  // 2 for an unknown session, 1 with a bad version (protocol 1's), 1 too short.
  op.send_datagram(heartbeat_datagram(k, sid + 1, 22), port);
  op.send_datagram(heartbeat_datagram(k, sid ^ 0xff00, 23), port);
  auto bad_version = heartbeat_datagram(k, sid, 24);
  bad_version[2] = 1;
  op.send_datagram(bad_version, port);
  op.send_datagram(std::vector<uint8_t>(20, 0x48), port);
  // Jump ahead to 2021: seq 22..2020 count as lost, and seq 10 is now behind the 1024 window.
  op.send_datagram(heartbeat_datagram(k, sid, 2021), port);
  std::this_thread::sleep_for(100ms);
  op.send_datagram(heartbeat_datagram(k, sid, 10), port);
  // Silence past link_timeout (500 ms): the robot reports the link lost...
  ASSERT_TRUE(wait_for_text(dir + "/robot.err", "event=link_lost", 5s)) << r.err();
  // ...and restores it when authenticated datagrams resume.
  op.send_datagram(heartbeat_datagram(k, sid, 2022), port);
  EXPECT_TRUE(wait_for_text(dir + "/robot.err", "event=link_restored", 5s)) << r.err();
  // A forged session frame (an injected e-stop) closes the session.
  wire::SessionFrame estop;
  estop.mutable_estop()->set_engaged(false);
  net::FrameSealer forger(wrong);
  op.send_frame(net::seal_session_frame(forger, estop));
  EXPECT_TRUE(wait_for_text(dir + "/robot.err", "session frame failed authentication", 5s)) << r.err();

  r.proc->signal(SIGTERM);
  const auto rc = r.proc->wait(20s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0);
  const std::string j = r.json();
  EXPECT_EQ(num(j, "delivered"), 23);  // 1..20, the path response 21, 2021, 2022
  EXPECT_EQ(num(j, "duplicated"), 3);
  EXPECT_EQ(num(j, "rejected_bad_tag"), 4);
  EXPECT_EQ(num(j, "rejected_unknown_session"), 2);
  EXPECT_EQ(num(j, "rejected_bad_version"), 1);
  EXPECT_EQ(num(j, "rejected_bad_size"), 1);
  EXPECT_EQ(num(j, "rejected_replay"), 1);
  EXPECT_EQ(num(j, "lost"), 1999);
  EXPECT_EQ(num(j, "paths_validated"), 1);
  // At least once each (a multi-second stall of a loaded machine could add more).
  EXPECT_GE(num(j, "link_lost_events"), 1);
  EXPECT_GE(num(j, "link_restored_events"), 1);
}

}  // namespace
}  // namespace hemm::test
