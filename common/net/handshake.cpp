#include "common/net/handshake.h"

#include "common/net/bytes.h"
#include "common/net/log_guard.h"

namespace hemm::net {
namespace {

std::vector<uint8_t> serialize(const wire::SessionFrame& f) {
  std::vector<uint8_t> out(f.ByteSizeLong());
  if (!out.empty()) f.SerializeToArray(out.data(), static_cast<int>(out.size()));
  return out;
}

std::vector<uint8_t> make_transcript(std::span<const uint8_t> hello, const Nonce& server_nonce, uint64_t session_id,
                                     uint32_t version) {
  std::vector<uint8_t> t(4 + hello.size() + kNonceBytes + 8 + 4);
  put_u32(t.data(), static_cast<uint32_t>(hello.size()));
  std::copy(hello.begin(), hello.end(), t.begin() + 4);
  size_t o = 4 + hello.size();
  std::copy(server_nonce.begin(), server_nonce.end(), t.begin() + static_cast<std::ptrdiff_t>(o));
  o += kNonceBytes;
  put_u64(t.data() + o, session_id);
  put_u32(t.data() + o + 8, version);
  return t;
}

template <size_t N>
bool to_array(const std::string& s, std::array<uint8_t, N>* out) {
  if (s.size() != N) return false;
  std::copy(s.begin(), s.end(), out->begin());
  return true;
}

std::string as_string(std::span<const uint8_t> b) { return std::string(b.begin(), b.end()); }

}  // namespace

std::string truncate_text(const std::string& s, size_t n) { return s.size() <= n ? s : s.substr(0, n); }

std::vector<uint8_t> make_error_frame(wire::ErrorCode code, const std::string& reason) {
  wire::SessionFrame f;
  f.mutable_error()->set_code(code);
  f.mutable_error()->set_reason(truncate_text(reason, kMaxReasonBytes));
  return serialize(f);
}

namespace {
Proof refusal_tag(const Key& psk, std::span<const uint8_t> hello, wire::ErrorCode code, const std::string& reason) {
  std::vector<uint8_t> d(4 + hello.size() + 4 + reason.size());
  put_u32(d.data(), static_cast<uint32_t>(hello.size()));
  std::copy(hello.begin(), hello.end(), d.begin() + 4);
  put_u32(d.data() + 4 + hello.size(), static_cast<uint32_t>(code));
  std::copy(reason.begin(), reason.end(), d.begin() + static_cast<std::ptrdiff_t>(8 + hello.size()));
  return hmac_sha256(psk, "hemm-v1 refusal", d);
}
}  // namespace

std::vector<uint8_t> make_tagged_error_frame(const Key& psk, std::span<const uint8_t> hello, wire::ErrorCode code,
                                             const std::string& reason) {
  wire::SessionFrame f;
  const std::string r = truncate_text(reason, kMaxReasonBytes);
  f.mutable_error()->set_code(code);
  f.mutable_error()->set_reason(r);
  f.mutable_error()->set_refusal_tag(as_string(refusal_tag(psk, hello, code, r)));
  return serialize(f);
}

bool refusal_tag_matches(const Key& psk, std::span<const uint8_t> hello, const wire::Error& e) {
  const std::string& t = e.refusal_tag();
  if (t.size() != kProofBytes || hello.empty()) return false;
  const Proof expect = refusal_tag(psk, hello, e.code(), e.reason());
  return equal_constant_time(expect, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(t.data()), t.size()));
}

bool parse_session_frame(std::span<const uint8_t> payload, wire::SessionFrame* out) {
  wire::SessionFrame f;
  if (payload.size() > static_cast<size_t>(INT32_MAX)) return false;
  if (!f.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) return false;
  if (f.body_case() == wire::SessionFrame::BODY_NOT_SET) return false;
  out->Swap(&f);
  return true;
}

std::vector<uint8_t> seal_session_frame(FrameSealer& tx, const wire::SessionFrame& f) {
  return tx.seal(serialize(f));
}

bool open_session_frame(FrameOpener& rx, std::span<const uint8_t> sealed, wire::SessionFrame* out) {
  std::vector<uint8_t> inner;
  if (!rx.open(sealed, &inner)) return false;
  return parse_session_frame(inner, out);
}

// ------------------------------------------------------------------ client

ClientHandshake::ClientHandshake(Params p) : p_(std::move(p)) {
  if (p_.client_nonce) {
    client_nonce_ = *p_.client_nonce;
  } else {
    random_bytes(client_nonce_.data(), client_nonce_.size());
  }
}

namespace {
// The step both handshake sides return when they give up.
HandshakeStep failed_step(wire::ErrorCode code, std::string reason, bool send_error, bool by_peer,
                          bool authenticated) {
  HandshakeStep s;
  s.kind = HandshakeStep::Kind::kFailed;
  s.error = code;
  s.reason = std::move(reason);
  s.reported_by_peer = by_peer;
  s.authenticated = authenticated;
  if (send_error) s.reply = make_error_frame(code, s.reason);
  return s;
}
}  // namespace

HandshakeStep ClientHandshake::fail(wire::ErrorCode code, std::string reason, bool send_error, bool by_peer,
                                    bool authenticated) {
  state_ = State::kFailed;
  return failed_step(code, std::move(reason), send_error, by_peer, authenticated);
}

std::vector<uint8_t> ClientHandshake::start() {
  if (state_ != State::kStart) return {};
  wire::SessionFrame f;
  auto* h = f.mutable_hello();
  h->set_protocol_version(p_.protocol_version);
  h->set_role(wire::ROLE_OPERATOR);
  h->set_station_name(truncate_text(p_.station_name, kMaxStationNameBytes));
  h->set_client_nonce(as_string(client_nonce_));
  h->set_want_control(p_.want_control);
  hello_bytes_ = serialize(f);
  state_ = State::kAwaitChallenge;
  return hello_bytes_;
}

HandshakeStep ClientHandshake::on_frame(std::span<const uint8_t> payload) {
  switch (state_) {
    case State::kStart:
    case State::kOpen:
    case State::kFailed:
      return fail(wire::ERROR_MALFORMED, "handshake frame in wrong state", false);
    case State::kAwaitChallenge: {
      wire::SessionFrame f;
      if (!parse_session_frame(payload, &f)) return fail(wire::ERROR_MALFORMED, "malformed frame, expected Challenge", true);
      if (f.has_error()) {
        const bool tagged = refusal_tag_matches(p_.psk, hello_bytes_, f.error());
        return fail(f.error().code(),
                    std::string(tagged ? "robot refused: " : "robot refused (unauthenticated): ") +
                        log_safe(f.error().reason(), kMaxReasonBytes),
                    false, true, tagged);
      }
      if (!f.has_challenge()) return fail(wire::ERROR_MALFORMED, "expected Challenge", true);
      const auto& c = f.challenge();
      Nonce sn{};
      Proof sp{};
      if (!to_array(c.server_nonce(), &sn) || !to_array(c.server_proof(), &sp) || c.session_id() == 0) {
        return fail(wire::ERROR_MALFORMED, "malformed Challenge", true);
      }
      // The proof covers the version: a matching proof makes a mismatch the robot's own word.
      const auto transcript = make_transcript(hello_bytes_, sn, c.session_id(), c.protocol_version());
      const Proof expect = hmac_sha256(p_.psk, "hemm-v1 server", transcript);
      if (!equal_constant_time(expect, sp)) {
        return fail(wire::ERROR_AUTH_FAILED, "authentication failed: the robot's proof does not match our key", true);
      }
      if (c.protocol_version() != p_.protocol_version) {
        return fail(wire::ERROR_VERSION_MISMATCH,
                    "protocol version mismatch: robot " + std::to_string(c.protocol_version()) + ", operator " +
                        std::to_string(p_.protocol_version),
                    true, false, true);
      }
      secrets_.session_id = c.session_id();
      secrets_.keys = derive_session_keys(p_.psk, client_nonce_, sn, c.session_id());
      secrets_.tx = std::make_unique<FrameSealer>(secrets_.keys.tcp_c2s);
      secrets_.rx = std::make_unique<FrameOpener>(secrets_.keys.tcp_s2c);
      wire::SessionFrame pf;
      const Proof cp = hmac_sha256(p_.psk, "hemm-v1 client", transcript);
      pf.mutable_proof()->set_client_proof(as_string(cp));
      state_ = State::kAwaitWelcome;
      HandshakeStep s;
      s.reply = serialize(pf);
      return s;
    }
    case State::kAwaitWelcome: {
      wire::SessionFrame f;
      if (open_session_frame(*secrets_.rx, payload, &f)) {
        if (f.has_error()) {
          return fail(f.error().code(), "robot refused: " + log_safe(f.error().reason(), kMaxReasonBytes), false,
                      true, true);
        }
        if (!f.has_welcome() || f.welcome().session_id() != secrets_.session_id) {
          return fail(wire::ERROR_MALFORMED, "expected Welcome for our session", false);
        }
        welcome_ = f.welcome();
        state_ = State::kOpen;
        HandshakeStep s;
        s.kind = HandshakeStep::Kind::kOpen;
        return s;
      }
      // A robot that rejected our proof answers in clear (it has no session
      // keys), tagged with the pre-shared key when it has ours.
      if (parse_session_frame(payload, &f) && f.has_error()) {
        const bool tagged = refusal_tag_matches(p_.psk, hello_bytes_, f.error());
        return fail(f.error().code(),
                    std::string(tagged ? "robot refused: " : "robot refused (unauthenticated): ") +
                        log_safe(f.error().reason(), kMaxReasonBytes),
                    false, true, tagged);
      }
      return fail(wire::ERROR_AUTH_FAILED, "Welcome failed authentication", false);
    }
  }
  return fail(wire::ERROR_INTERNAL, "unreachable", false);
}

// ------------------------------------------------------------------ server

ServerHandshake::ServerHandshake(Params p) : p_(std::move(p)) {}

HandshakeStep ServerHandshake::fail(wire::ErrorCode code, std::string reason, bool send_error, bool by_peer) {
  state_ = State::kFailed;
  HandshakeStep s = failed_step(code, std::move(reason), send_error, by_peer, false);
  // Once the Hello is known, the refusal is tagged for that operator.
  if (send_error && !hello_bytes_.empty()) s.reply = make_tagged_error_frame(p_.psk, hello_bytes_, code, s.reason);
  return s;
}

HandshakeStep ServerHandshake::on_frame(std::span<const uint8_t> payload) {
  switch (state_) {
    case State::kAuthenticated:
    case State::kFailed:
      return fail(wire::ERROR_MALFORMED, "handshake frame in wrong state", false);
    case State::kAwaitHello: {
      wire::SessionFrame f;
      if (!parse_session_frame(payload, &f)) return fail(wire::ERROR_MALFORMED, "malformed frame, expected Hello", true);
      if (f.has_error()) {
        return fail(f.error().code(), "operator reported: " + log_safe(f.error().reason(), kMaxReasonBytes),
                    false, true);
      }
      if (!f.has_hello()) return fail(wire::ERROR_MALFORMED, "expected Hello", true);
      hello_bytes_.assign(payload.begin(), payload.end());
      const auto& h = f.hello();
      if (h.protocol_version() != p_.protocol_version) {
        return fail(wire::ERROR_VERSION_MISMATCH,
                    "protocol version mismatch: robot speaks " + std::to_string(p_.protocol_version) +
                        ", operator sent " + std::to_string(h.protocol_version()),
                    true);
      }
      if (h.role() != wire::ROLE_OPERATOR) return fail(wire::ERROR_MALFORMED, "Hello role must be operator", true);
      if (h.client_nonce().size() != kNonceBytes) return fail(wire::ERROR_MALFORMED, "client nonce must be 32 bytes", true);
      if (h.station_name().size() > kMaxStationNameBytes) {
        return fail(wire::ERROR_MALFORMED, "station name longer than 64 bytes", true);
      }
      hello_ = h;
      if (p_.server_nonce) {
        server_nonce_ = *p_.server_nonce;
      } else {
        random_bytes(server_nonce_.data(), server_nonce_.size());
      }
      session_id_ = p_.session_id.value_or(0);
      if (session_id_ == 0) session_id_ = random_u64_nonzero();
      transcript_ = make_transcript(payload, server_nonce_, session_id_, p_.protocol_version);
      wire::SessionFrame cf;
      auto* c = cf.mutable_challenge();
      c->set_protocol_version(p_.protocol_version);
      c->set_server_nonce(as_string(server_nonce_));
      c->set_session_id(session_id_);
      c->set_server_proof(as_string(hmac_sha256(p_.psk, "hemm-v1 server", transcript_)));
      state_ = State::kAwaitProof;
      HandshakeStep s;
      s.reply = serialize(cf);
      return s;
    }
    case State::kAwaitProof: {
      wire::SessionFrame f;
      if (!parse_session_frame(payload, &f)) return fail(wire::ERROR_MALFORMED, "malformed frame, expected Proof", true);
      if (f.has_error()) {
        return fail(f.error().code(), "operator reported: " + log_safe(f.error().reason(), kMaxReasonBytes),
                    false, true);
      }
      if (!f.has_proof()) return fail(wire::ERROR_MALFORMED, "expected Proof", true);
      const Proof expect = hmac_sha256(p_.psk, "hemm-v1 client", transcript_);
      const std::string& got = f.proof().client_proof();
      if (!equal_constant_time(expect, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(got.data()), got.size()))) {
        return fail(wire::ERROR_AUTH_FAILED, "authentication failed: the operator's proof does not match our key", true);
      }
      Nonce cn{};
      to_array(hello_.client_nonce(), &cn);
      secrets_.session_id = session_id_;
      secrets_.keys = derive_session_keys(p_.psk, cn, server_nonce_, session_id_);
      secrets_.tx = std::make_unique<FrameSealer>(secrets_.keys.tcp_s2c);
      secrets_.rx = std::make_unique<FrameOpener>(secrets_.keys.tcp_c2s);
      state_ = State::kAuthenticated;
      HandshakeStep s;
      s.kind = HandshakeStep::Kind::kAuthenticated;
      return s;
    }
  }
  return fail(wire::ERROR_INTERNAL, "unreachable", false);
}

}  // namespace hemm::net
