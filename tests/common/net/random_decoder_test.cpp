// Feeds 200,000+ random and mutated datagrams, TCP byte streams and
// handshake frames to the decoders of both stations. Nothing may crash (run
// it under ASan/UBSan too), and nothing the spec rejects may be accepted:
// every mutated sealed datagram or frame must be rejected, a datagram sealed
// for one direction never opens in the other, and a handshake never
// authenticates from forged or mutated frames unless the authenticated
// content is unchanged.
#include <google/protobuf/stubs/logging.h>
#include <gtest/gtest.h>

#include <random>

#include "common/net/datagram.h"
#include "common/net/framing.h"
#include "common/net/handshake.h"
#include "common/net/stream_receiver.h"

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

Key make_key(uint8_t v) {
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(v * 31 + i);
  return k;
}


// A random mutation that always changes the bytes.
std::vector<uint8_t> mutate(std::vector<uint8_t> b, std::mt19937_64& rng) {
  const auto orig = b;
  do {
    b = orig;
    const int kind = static_cast<int>(rng() % 6);
    switch (kind) {
      case 0:  // flip 1..4 bits
        for (int i = 0, n = 1 + static_cast<int>(rng() % 4); i < n && !b.empty(); ++i)
          b[rng() % b.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
        break;
      case 1:  // set a byte
        if (!b.empty()) b[rng() % b.size()] = static_cast<uint8_t>(rng());
        break;
      case 2:  // truncate
        b.resize(rng() % (b.size() + 1));
        break;
      case 3:  // append
        for (int i = 0, n = 1 + static_cast<int>(rng() % 40); i < n; ++i) b.push_back(static_cast<uint8_t>(rng()));
        break;
      case 4:  // insert
        b.insert(b.begin() + static_cast<std::ptrdiff_t>(rng() % (b.size() + 1)), static_cast<uint8_t>(rng()));
        break;
      case 5:  // erase a range
        if (!b.empty()) {
          const size_t at = rng() % b.size();
          b.erase(b.begin() + static_cast<std::ptrdiff_t>(at),
                  b.begin() + static_cast<std::ptrdiff_t>(std::min(b.size(), at + 1 + rng() % 8)));
        }
        break;
    }
  } while (b == orig);
  return b;
}

std::vector<uint8_t> random_bytes_vec(std::mt19937_64& rng, size_t max) {
  std::vector<uint8_t> b(rng() % (max + 1));
  for (auto& x : b) x = static_cast<uint8_t>(rng());
  return b;
}

struct Session {
  SessionSecrets client, server;
  std::vector<uint8_t> hello, challenge, proof;
};

Session handshake(const Key& psk, uint64_t seed) {
  Session s;
  Nonce cn{}, sn{};
  cn[0] = static_cast<uint8_t>(seed);
  sn[1] = static_cast<uint8_t>(seed >> 8);
  ClientHandshake c(ClientHandshake::Params{psk, kProtocolVersion, "op", true, cn});
  ServerHandshake sv(ServerHandshake::Params{psk, kProtocolVersion, sn, seed | 1});
  s.hello = c.start();
  auto st1 = sv.on_frame(s.hello);
  s.challenge = st1.reply;
  auto st2 = c.on_frame(s.challenge);
  s.proof = st2.reply;
  EXPECT_EQ(sv.on_frame(s.proof).kind, HandshakeStep::Kind::kAuthenticated);
  s.server = sv.take_secrets();
  wire::SessionFrame w;
  w.mutable_welcome()->set_session_id(seed | 1);
  EXPECT_EQ(c.on_frame(seal_session_frame(*s.server.tx, w)).kind, HandshakeStep::Kind::kOpen);
  s.client = c.take_secrets();
  return s;
}

std::vector<uint8_t> stream_datagram(const Key& k, uint64_t sid, uint64_t seq, std::mt19937_64& rng) {
  wire::StreamMessage m;
  switch (rng() % 4) {
    case 0: m.mutable_heartbeat()->set_period_ms(50); break;
    case 1: m.mutable_ping()->set_id(seq), m.mutable_ping()->set_t1_ns(static_cast<int64_t>(rng())); break;
    case 2: {
      auto* p = m.mutable_pong();
      p->set_id(seq);
      p->set_t1_ns(1);
      p->set_t2_ns(2);
      p->set_t3_ns(3);
      break;
    }
    default: {
      auto* sc = m.mutable_range_scan();
      sc->set_first_beam(static_cast<uint32_t>(rng() % 100));
      for (int i = 0; i < 50; ++i) sc->add_ranges(static_cast<float>(i));
      break;
    }
  }
  const std::string p = m.SerializeAsString();
  std::vector<uint8_t> d;
  encode_datagram(k, DatagramHeader{sid, seq, static_cast<int64_t>(seq)},
                  std::span(reinterpret_cast<const uint8_t*>(p.data()), p.size()), &d);
  return d;
}

TEST(RandomDecoderTest, TwoHundredThousandRandomAndMutatedInputs) {
  // Invalid UTF-8 in proto3 strings is rejected with a log line; keep the output readable.
  google::protobuf::LogSilencer quiet;
  const Key psk = make_key(1);
  std::mt19937_64 rng(20261122);
  Session s = handshake(psk, 0xabcdef);
  const uint64_t sid = s.server.session_id;
  // Robot side receives c2s, operator side receives s2c.
  StreamReceiver robot_rx(1024), op_rx(1024);
  robot_rx.open(sid, s.server.keys.udp_c2s);
  op_rx.open(sid, s.client.keys.udp_s2c);
  uint64_t robot_seq = 0, op_seq = 0;

  size_t inputs = 0;
  size_t mutated_datagrams = 0, mutated_frames = 0, handshake_inputs = 0, random_streams = 0;
  DatagramHeader h;
  wire::StreamMessage m;
  const size_t kTotal = 200000;
  while (inputs < kTotal) {
    const int what = static_cast<int>(rng() % 10);
    if (what <= 3) {
      // Mutated authenticated datagram to either side; then the original, which must still be fresh.
      const bool to_robot = rng() & 1;
      StreamReceiver& rx = to_robot ? robot_rx : op_rx;
      const Key& k = to_robot ? s.client.keys.udp_c2s : s.server.keys.udp_s2c;
      uint64_t& seq = to_robot ? robot_seq : op_seq;
      const auto good = stream_datagram(k, sid, ++seq, rng);
      const auto bad = mutate(good, rng);
      const auto before = rx.counters();
      const auto v = rx.receive(bad, &h, &m);
      ASSERT_EQ(v, StreamReceiver::Verdict::kRejected) << "a mutated datagram was accepted";
      ASSERT_EQ(rx.counters().delivered, before.delivered);
      ASSERT_EQ(rx.counters().rejected_total(), before.rejected_total() + 1);
      // Reflected to the other station (same session, other direction's key): never opens.
      StreamReceiver& other = to_robot ? op_rx : robot_rx;
      const auto other_bad_tag = other.counters().rejected_bad_tag;
      ASSERT_EQ(other.receive(good, &h, &m), StreamReceiver::Verdict::kRejected) << "a reflected datagram opened";
      ASSERT_EQ(other.counters().rejected_bad_tag, other_bad_tag + 1);
      ASSERT_EQ(rx.receive(good, &h, &m), StreamReceiver::Verdict::kDeliver);
      ++mutated_datagrams;
      inputs += 2;
    } else if (what == 4) {
      // Pure random datagrams (also with a valid-looking header).
      auto b = random_bytes_vec(rng, 1300);
      if (b.size() >= kDatagramOverheadBytes && (rng() & 1)) {
        b[0] = 'H', b[1] = 'M', b[2] = kDatagramVersion, b[3] = 0;
        for (int i = 0; i < 8; ++i) b[4 + i] = static_cast<uint8_t>(sid >> (56 - 8 * i));
      }
      StreamReceiver& rx = (rng() & 1) ? robot_rx : op_rx;
      ASSERT_EQ(rx.receive(b, &h, &m), StreamReceiver::Verdict::kRejected);
      ++inputs;
    } else if (what == 5) {
      // Replay of an old authenticated datagram: duplicate or too old, never delivered.
      if (robot_seq > 2) {
        const uint64_t old = 1 + rng() % (robot_seq - 1);
        const auto d = stream_datagram(s.client.keys.udp_c2s, sid, old, rng);
        const auto v = robot_rx.receive(d, &h, &m);
        ASSERT_TRUE(v == StreamReceiver::Verdict::kDuplicate || v == StreamReceiver::Verdict::kRejected);
      }
      ++inputs;
    } else if (what == 6) {
      // Random TCP byte stream in random chunks to a frame decoder; any frame
      // it yields goes to a sealed-frame opener and to both handshake machines.
      FrameDecoder dec(4096);
      FrameOpener opener(s.server.keys.tcp_c2s);
      const auto stream = random_bytes_vec(rng, 600);
      size_t i = 0;
      std::vector<uint8_t> p;
      while (i < stream.size()) {
        const size_t n = std::min<size_t>(stream.size() - i, 1 + rng() % 64);
        dec.feed(std::span(stream.data() + i, n));
        i += n;
        while (dec.next(&p) == FrameDecoder::Status::kFrame) {
          std::vector<uint8_t> inner;
          ASSERT_FALSE(opener.open(p, &inner));
          ServerHandshake sv(server_params(psk));
          const auto st = sv.on_frame(p);
          ASSERT_NE(st.kind, HandshakeStep::Kind::kAuthenticated);
          ClientHandshake c(client_params(psk));
          c.start();
          ASSERT_NE(c.on_frame(p).kind, HandshakeStep::Kind::kOpen);
        }
      }
      ++random_streams;
      ++inputs;
    } else if (what == 7) {
      // Mutated sealed session frames (e.g. an injected mode change or e-stop).
      FrameSealer tx(s.client.keys.tcp_c2s);
      FrameOpener rx(s.client.keys.tcp_c2s);
      wire::SessionFrame f;
      f.mutable_estop()->set_engaged(rng() & 1);
      f.mutable_estop()->set_reason("r");
      auto sealed = seal_session_frame(tx, f);
      std::vector<uint8_t> stream;
      encode_frame(mutate(sealed, rng), &stream);
      FrameDecoder dec(4096);
      dec.feed(stream);
      std::vector<uint8_t> p, inner;
      if (dec.next(&p) == FrameDecoder::Status::kFrame) {
        ASSERT_FALSE(rx.open(p, &inner));
      }
      ASSERT_EQ(rx.counter(), 0u);
      ++mutated_frames;
      ++inputs;
    } else {
      // Handshake: mutated Hello / Challenge / Proof / Welcome.
      ++handshake_inputs;
      ++inputs;
      const int step = static_cast<int>(rng() % 4);
      Nonce cn{}, sn{};
      cn[3] = 1;
      sn[4] = 2;
      ClientHandshake c(ClientHandshake::Params{psk, kProtocolVersion, "op", true, cn});
      ServerHandshake sv(ServerHandshake::Params{psk, kProtocolVersion, sn, 77});
      const auto hello = c.start();
      if (step == 0) {
        // A mutated Hello may be accepted only if it parses; the client then
        // cannot verify the Challenge (the transcript differs) unless bytes match.
        const auto bad = mutate(hello, rng);
        const auto st = sv.on_frame(bad);
        if (st.kind == HandshakeStep::Kind::kContinue) {
          ASSERT_NE(c.on_frame(st.reply).kind, HandshakeStep::Kind::kContinue)
              << "client accepted a Challenge over a different Hello";
        }
        continue;
      }
      const auto st1 = sv.on_frame(hello);
      ASSERT_EQ(st1.kind, HandshakeStep::Kind::kContinue);
      wire::SessionFrame good_ch;
      ASSERT_TRUE(parse_session_frame(st1.reply, &good_ch));
      if (step == 1) {
        const auto bad = mutate(st1.reply, rng);
        const auto st = c.on_frame(bad);
        if (st.kind == HandshakeStep::Kind::kContinue) {
          // Only possible if the authenticated fields are unchanged.
          wire::SessionFrame f;
          ASSERT_TRUE(parse_session_frame(bad, &f));
          ASSERT_TRUE(f.has_challenge());
          ASSERT_EQ(f.challenge().server_nonce(), good_ch.challenge().server_nonce());
          ASSERT_EQ(f.challenge().session_id(), good_ch.challenge().session_id());
          ASSERT_EQ(f.challenge().protocol_version(), good_ch.challenge().protocol_version());
        }
        continue;
      }
      const auto st2 = c.on_frame(st1.reply);
      ASSERT_EQ(st2.kind, HandshakeStep::Kind::kContinue);
      if (step == 2) {
        const auto bad = mutate(st2.reply, rng);
        const auto st = sv.on_frame(bad);
        if (st.kind == HandshakeStep::Kind::kAuthenticated) {
          wire::SessionFrame f, g;
          ASSERT_TRUE(parse_session_frame(bad, &f));
          ASSERT_TRUE(parse_session_frame(st2.reply, &g));
          ASSERT_EQ(f.proof().client_proof(), g.proof().client_proof());
        }
        continue;
      }
      ASSERT_EQ(sv.on_frame(st2.reply).kind, HandshakeStep::Kind::kAuthenticated);
      SessionSecrets sec = sv.take_secrets();
      wire::SessionFrame w;
      w.mutable_welcome()->set_session_id(77);
      const auto bad = mutate(seal_session_frame(*sec.tx, w), rng);
      ASSERT_NE(c.on_frame(bad).kind, HandshakeStep::Kind::kOpen) << "client opened on a mutated Welcome";
    }
  }
  EXPECT_GE(inputs, kTotal);
  // Every kind of input was exercised in volume.
  EXPECT_GT(mutated_datagrams, 50000u);
  EXPECT_GT(mutated_frames, 10000u);
  EXPECT_GT(handshake_inputs, 20000u);
  EXPECT_GT(random_streams, 10000u);
  const auto& rc = robot_rx.counters();
  EXPECT_GT(rc.rejected_bad_tag + rc.rejected_bad_size + rc.rejected_bad_magic, 0u);
  EXPECT_EQ(rc.lost, 0u);
}

}  // namespace
}  // namespace hemm::net
