#include "common/net/handshake.h"

#include <gtest/gtest.h>
#include <sodium.h>

#include "common/net/bytes.h"

namespace hemm::net {
namespace {

ServerHandshake::Params server_params(const Key& k) {
  ServerHandshake::Params p;
  p.psk = k;
  return p;
}
ClientHandshake::Params client_params(const Key& k) {
  ClientHandshake::Params p;
  p.psk = k;
  return p;
}

Key key(uint8_t v) {
  Key k{};
  k.fill(v);
  k[0] = 0x42;
  return k;
}

struct Pair {
  ClientHandshake client;
  ServerHandshake server;
  Pair(const Key& ck, const Key& sk, uint32_t cv = kProtocolVersion, uint32_t sv = kProtocolVersion)
      : client(ClientHandshake::Params{ck, cv, "op", true, Nonce{1, 2, 3}}),
        server(ServerHandshake::Params{sk, sv, Nonce{9, 8, 7}, 0x1234}) {}
};

wire::SessionFrame parse(const std::vector<uint8_t>& b) {
  wire::SessionFrame f;
  EXPECT_TRUE(parse_session_frame(b, &f));
  return f;
}

TEST(HandshakeTest, SucceedsAndBothSidesDeriveMatchingKeys) {
  Pair p(key(1), key(1));
  const auto hello = p.client.start();
  auto s1 = p.server.on_frame(hello);
  ASSERT_EQ(s1.kind, HandshakeStep::Kind::kContinue);
  ASSERT_TRUE(parse(s1.reply).has_challenge());
  auto c1 = p.client.on_frame(s1.reply);
  ASSERT_EQ(c1.kind, HandshakeStep::Kind::kContinue);
  ASSERT_TRUE(parse(c1.reply).has_proof());
  auto s2 = p.server.on_frame(c1.reply);
  ASSERT_EQ(s2.kind, HandshakeStep::Kind::kAuthenticated) << s2.reason;
  EXPECT_TRUE(p.server.hello().want_control());
  EXPECT_EQ(p.server.hello().station_name(), "op");
  SessionSecrets ss = p.server.take_secrets();
  EXPECT_EQ(ss.session_id, 0x1234u);
  wire::SessionFrame w;
  w.mutable_welcome()->set_session_id(0x1234);
  w.mutable_welcome()->set_stream_port(5);
  auto c2 = p.client.on_frame(seal_session_frame(*ss.tx, w));
  ASSERT_EQ(c2.kind, HandshakeStep::Kind::kOpen) << c2.reason;
  EXPECT_EQ(p.client.welcome().stream_port(), 5u);
  SessionSecrets cs = p.client.take_secrets();
  EXPECT_EQ(cs.keys.udp_c2s, ss.keys.udp_c2s);
  EXPECT_EQ(cs.keys.udp_s2c, ss.keys.udp_s2c);
  EXPECT_EQ(cs.keys.tcp_c2s, ss.keys.tcp_c2s);
  EXPECT_NE(cs.keys.udp_c2s, cs.keys.udp_s2c);
  EXPECT_NE(cs.keys.udp_c2s, cs.keys.tcp_c2s);
  // The sealed channel works both ways after the Welcome.
  wire::SessionFrame bye;
  bye.mutable_bye()->set_reason("x");
  wire::SessionFrame got;
  ASSERT_TRUE(open_session_frame(*ss.rx, seal_session_frame(*cs.tx, bye), &got));
  EXPECT_EQ(got.bye().reason(), "x");
}

TEST(HandshakeTest, ProofsAndKeysMatchAnIndependentHmacReference) {
  Pair p(key(1), key(1));
  const auto hello = p.client.start();
  auto s1 = p.server.on_frame(hello);
  const auto ch = parse(s1.reply).challenge();
  // transcript = len(hello) || hello || server_nonce || session_id || version
  // Sized once, then filled: GCC 12 at -O3 reports a false -Warray-bounds
  // on inserting into a vector of known size 4 (its realloc path).
  std::vector<uint8_t> t(4 + hello.size());
  put_u32(t.data(), static_cast<uint32_t>(hello.size()));
  std::copy(hello.begin(), hello.end(), t.begin() + 4);
  t.insert(t.end(), ch.server_nonce().begin(), ch.server_nonce().end());
  uint8_t b[12];
  put_u64(b, ch.session_id());
  put_u32(b + 8, kProtocolVersion);
  t.insert(t.end(), b, b + 12);
  auto ref = [&](const std::string& label, const std::vector<uint8_t>& data) {
    std::vector<uint8_t> msg(label.begin(), label.end());
    msg.insert(msg.end(), data.begin(), data.end());
    std::string out(32, '\0');
    const Key k = key(1);
    crypto_auth_hmacsha256(reinterpret_cast<unsigned char*>(out.data()), msg.data(), msg.size(), k.data());
    return out;
  };
  EXPECT_EQ(ch.server_proof(), ref("hemm-v1 server", t));
  auto c1 = p.client.on_frame(s1.reply);
  EXPECT_EQ(parse(c1.reply).proof().client_proof(), ref("hemm-v1 client", t));
  ASSERT_EQ(p.server.on_frame(c1.reply).kind, HandshakeStep::Kind::kAuthenticated);
  const SessionSecrets ss = p.server.take_secrets();
  std::vector<uint8_t> ctx(32, 0);
  ctx[0] = 1, ctx[1] = 2, ctx[2] = 3;
  std::vector<uint8_t> sn(32, 0);
  sn[0] = 9, sn[1] = 8, sn[2] = 7;
  ctx.insert(ctx.end(), sn.begin(), sn.end());
  put_u64(b, 0x1234);
  ctx.insert(ctx.end(), b, b + 8);
  const std::string k = ref("hemm-v1 udp c2s", ctx);
  EXPECT_EQ(std::string(ss.keys.udp_c2s.begin(), ss.keys.udp_c2s.end()), k);
}

TEST(HandshakeTest, ClientWithWrongKeyRejectsTheRobotsProof) {
  Pair p(key(2), key(1));
  auto s1 = p.server.on_frame(p.client.start());
  auto c1 = p.client.on_frame(s1.reply);
  EXPECT_EQ(c1.kind, HandshakeStep::Kind::kFailed);
  EXPECT_EQ(c1.error, wire::ERROR_AUTH_FAILED);
  EXPECT_EQ(parse(c1.reply).error().code(), wire::ERROR_AUTH_FAILED);
}

TEST(HandshakeTest, ServerRejectsAForgedProofAndSaysSoInClear) {
  Pair p(key(1), key(1));
  auto s1 = p.server.on_frame(p.client.start());
  auto c1 = p.client.on_frame(s1.reply);
  auto f = parse(c1.reply);
  std::string proof = f.proof().client_proof();
  proof[31] ^= 1;
  f.mutable_proof()->set_client_proof(proof);
  std::vector<uint8_t> forged(f.ByteSizeLong());
  f.SerializeToArray(forged.data(), static_cast<int>(forged.size()));
  auto s2 = p.server.on_frame(forged);
  EXPECT_EQ(s2.kind, HandshakeStep::Kind::kFailed);
  EXPECT_EQ(s2.error, wire::ERROR_AUTH_FAILED);
  EXPECT_FALSE(p.server.authenticated());
  // The client reads the refusal in clear while waiting for the Welcome.
  auto c2 = p.client.on_frame(s2.reply);
  EXPECT_EQ(c2.kind, HandshakeStep::Kind::kFailed);
  EXPECT_EQ(c2.error, wire::ERROR_AUTH_FAILED);
  EXPECT_TRUE(c2.reported_by_peer);
}

TEST(HandshakeTest, VersionMismatchIsRefusedByTheServer) {
  Pair p(key(1), key(1), 7, kProtocolVersion);
  auto s1 = p.server.on_frame(p.client.start());
  EXPECT_EQ(s1.kind, HandshakeStep::Kind::kFailed);
  EXPECT_EQ(s1.error, wire::ERROR_VERSION_MISMATCH);
  auto c1 = p.client.on_frame(s1.reply);
  EXPECT_EQ(c1.kind, HandshakeStep::Kind::kFailed);
  EXPECT_EQ(c1.error, wire::ERROR_VERSION_MISMATCH);
  EXPECT_NE(c1.reason.find("version"), std::string::npos);
}

TEST(HandshakeTest, MalformedHellosAreRefused) {
  auto try_hello = [](const wire::SessionFrame& f) {
    ServerHandshake s(server_params(key(1)));
    std::vector<uint8_t> b(f.ByteSizeLong());
    f.SerializeToArray(b.data(), static_cast<int>(b.size()));
    return s.on_frame(b);
  };
  wire::SessionFrame f;
  auto* h = f.mutable_hello();
  h->set_protocol_version(kProtocolVersion);
  h->set_role(wire::ROLE_OPERATOR);
  h->set_client_nonce(std::string(32, 'n'));
  EXPECT_EQ(try_hello(f).kind, HandshakeStep::Kind::kContinue);
  h->set_client_nonce(std::string(31, 'n'));
  EXPECT_EQ(try_hello(f).error, wire::ERROR_MALFORMED);
  h->set_client_nonce(std::string(32, 'n'));
  h->set_station_name(std::string(65, 'a'));
  EXPECT_EQ(try_hello(f).error, wire::ERROR_MALFORMED);
  h->set_station_name("ok");
  h->set_role(wire::ROLE_ROBOT);
  EXPECT_EQ(try_hello(f).error, wire::ERROR_MALFORMED);
  wire::SessionFrame other;
  other.mutable_proof()->set_client_proof(std::string(32, 'p'));
  EXPECT_EQ(try_hello(other).error, wire::ERROR_MALFORMED);
  ServerHandshake s(server_params(key(1)));
  const std::vector<uint8_t> junk = {0xff, 0xff, 0xff};
  EXPECT_EQ(s.on_frame(junk).error, wire::ERROR_MALFORMED);
  // After failing, nothing is accepted.
  EXPECT_EQ(s.on_frame(junk).kind, HandshakeStep::Kind::kFailed);
}

TEST(HandshakeTest, TamperedOrReplayedWelcomeIsRejected) {
  Pair p(key(1), key(1));
  auto s1 = p.server.on_frame(p.client.start());
  auto c1 = p.client.on_frame(s1.reply);
  ASSERT_EQ(p.server.on_frame(c1.reply).kind, HandshakeStep::Kind::kAuthenticated);
  SessionSecrets ss = p.server.take_secrets();
  wire::SessionFrame w;
  w.mutable_welcome()->set_session_id(0x1234);
  auto sealed = seal_session_frame(*ss.tx, w);
  sealed[1] ^= 0x10;
  auto c2 = p.client.on_frame(sealed);
  EXPECT_EQ(c2.kind, HandshakeStep::Kind::kFailed);
  EXPECT_FALSE(p.client.open());
}

TEST(HandshakeTest, ChallengeWithZeroSessionOrShortNonceIsMalformed) {
  ClientHandshake c(client_params(key(1)));
  c.start();
  wire::SessionFrame f;
  f.mutable_challenge()->set_protocol_version(kProtocolVersion);
  f.mutable_challenge()->set_server_nonce(std::string(32, 's'));
  f.mutable_challenge()->set_session_id(0);
  f.mutable_challenge()->set_server_proof(std::string(32, 'p'));
  std::vector<uint8_t> b(f.ByteSizeLong());
  f.SerializeToArray(b.data(), static_cast<int>(b.size()));
  EXPECT_EQ(c.on_frame(b).error, wire::ERROR_MALFORMED);
}

TEST(HandshakeTest, ErrorReasonsAreTruncated) {
  const auto b = make_error_frame(wire::ERROR_INTERNAL, std::string(1000, 'r'));
  wire::SessionFrame f;
  ASSERT_TRUE(parse_session_frame(b, &f));
  EXPECT_EQ(f.error().reason().size(), kMaxReasonBytes);
}

// A peer's Error reason ends up in the other station's log: a newline and a
// forged key=value line, an escape sequence and a quote must not get there.
TEST(HandshakeTest, PeerSuppliedReasonsAreMadeLogSafe) {
  const std::string hostile =
      "x\n2026-01-01T00:00:00.000 level=critical station=robot event=estop engaged=false\x1b[2J\"\\ \xc3\xa9";
  wire::SessionFrame f;
  f.mutable_error()->set_code(wire::ERROR_INTERNAL);
  f.mutable_error()->set_reason(hostile);
  const std::string bytes = f.SerializeAsString();
  const std::vector<uint8_t> frame(bytes.begin(), bytes.end());
  auto check = [&](const HandshakeStep& st) {
    ASSERT_EQ(st.kind, HandshakeStep::Kind::kFailed);
    EXPECT_TRUE(st.reported_by_peer);
    for (char c : st.reason) {
      EXPECT_TRUE(c >= 0x20 && c <= 0x7e && c != '"' && c != '\\') << "byte " << static_cast<int>(c) << " in "
                                                                       << st.reason;
    }
    EXPECT_NE(st.reason.find("level=critical"), std::string::npos);  // kept, but on the same line
  };
  ServerHandshake server(server_params(key(1)));
  check(server.on_frame(frame));
  ClientHandshake client(client_params(key(1)));
  client.start();
  check(client.on_frame(frame));
}

// Issue 23 item 5: which refusals are authenticated. The robot's own
// refusals in clear carry a tag over the operator's Hello (with the key);
// the same Error without the tag, with another client's tag, or with the
// code or reason changed is not authenticated. A refusal sealed after the
// Proof is.
TEST(HandshakeTest, OnlyTaggedOrSealedRefusalsAreAuthenticated) {
  {  // version mismatch, as the robot sends it
    Pair p(key(1), key(1), 7, kProtocolVersion);
    const auto hello = p.client.start();
    const auto s1 = p.server.on_frame(hello);
    ASSERT_EQ(s1.kind, HandshakeStep::Kind::kFailed);
    const wire::SessionFrame f = parse(s1.reply);
    EXPECT_EQ(f.error().refusal_tag().size(), kProofBytes);
    EXPECT_TRUE(refusal_tag_matches(key(1), hello, f.error()));
    EXPECT_FALSE(refusal_tag_matches(key(2), hello, f.error()));
    const auto c1 = p.client.on_frame(s1.reply);
    EXPECT_EQ(c1.error, wire::ERROR_VERSION_MISMATCH);
    EXPECT_TRUE(c1.authenticated);
  }
  {  // the same refusal, tampered with or untagged: not authenticated
    Pair p(key(1), key(1), 7, kProtocolVersion);
    const auto s1 = p.server.on_frame(p.client.start());
    wire::SessionFrame f = parse(s1.reply);
    f.mutable_error()->set_code(wire::ERROR_AUTH_FAILED);
    const std::string changed = f.SerializeAsString();
    const auto c1 = p.client.on_frame(std::vector<uint8_t>(changed.begin(), changed.end()));
    EXPECT_EQ(c1.kind, HandshakeStep::Kind::kFailed);
    EXPECT_FALSE(c1.authenticated);
    EXPECT_NE(c1.reason.find("unauthenticated"), std::string::npos) << c1.reason;
    ClientHandshake other(client_params(key(1)));
    other.start();
    EXPECT_FALSE(other.on_frame(make_error_frame(wire::ERROR_VERSION_MISMATCH, "no")).authenticated);
  }
  {  // a tag made for another client's Hello
    Pair p(key(1), key(1), 7, kProtocolVersion);
    const auto s1 = p.server.on_frame(p.client.start());
    ClientHandshake other(ClientHandshake::Params{key(1), 7, "op", true, Nonce{4, 5, 6}});
    other.start();
    EXPECT_FALSE(other.on_frame(s1.reply).authenticated);
  }
  {  // a forged proof: the robot's clear refusal is tagged; the client sees it authenticated
    Pair p(key(1), key(1));
    auto s1 = p.server.on_frame(p.client.start());
    auto c1 = p.client.on_frame(s1.reply);
    auto f = parse(c1.reply);
    std::string proof = f.proof().client_proof();
    proof[0] ^= 1;
    f.mutable_proof()->set_client_proof(proof);
    const std::string forged = f.SerializeAsString();
    const auto s2 = p.server.on_frame(std::vector<uint8_t>(forged.begin(), forged.end()));
    const auto c2 = p.client.on_frame(s2.reply);
    EXPECT_EQ(c2.error, wire::ERROR_AUTH_FAILED);
    EXPECT_TRUE(c2.authenticated);
  }
  {  // a wrong key: the robot's proof does not match ours, this attempt fails, unauthenticated
    Pair p(key(2), key(1));
    const auto c1 = p.client.on_frame(p.server.on_frame(p.client.start()).reply);
    EXPECT_EQ(c1.error, wire::ERROR_AUTH_FAILED);
    EXPECT_FALSE(c1.authenticated);
  }
}

}  // namespace
}  // namespace hemm::net
