// The session handshake as two pure state machines (no sockets, no clocks):
//
//   operator (client)                         robot (server)
//   Hello{version, role, name, client_nonce, want_control}  ->
//                                <- Challenge{version, server_nonce, session_id, server_proof}
//   Proof{client_proof}  ->
//                                <- Welcome{...}  (first authenticated frame)  or  Error{...}
//
// transcript   = len(hello)(4, BE) || hello bytes as sent || server_nonce(32)
//                || session_id(8, BE) || challenge protocol_version(4, BE)
// server_proof = HMAC-SHA256(psk, "hemm-v1 server" || transcript)
// client_proof = HMAC-SHA256(psk, "hemm-v1 client" || transcript)
// Proofs are compared in constant time. After a valid Proof both sides derive
// the session keys (crypto.h) and every further TCP frame is sealed
// (framing.h). Hello, Challenge, Proof and the refusals of a failed handshake
// (version mismatch, bad proof, malformed frame) are the only frames in clear.
//
// Refusals and who may make them final (issue 23): anyone between the
// stations, or anyone answering on the robot's port, can send a clear Error.
// So the client marks a refusal `authenticated` only when it is sealed with
// the session keys (after the Proof), or when it is a clear Error whose
// refusal_tag = HMAC-SHA256(psk, "hemm-v1 refusal" || len(hello)(4, BE) ||
// hello || code(4, BE) || reason) matches this client's own Hello (the robot
// tags every refusal it sends once it has the Hello; a version mismatch of a
// robot with the same key is therefore authenticated). A Challenge whose
// proof matches but whose version differs is an authenticated version
// mismatch too. Everything else (an untagged clear Error, a Challenge whose
// proof does not match our key, a malformed frame) fails this attempt only:
// the operator tries again (operator/client).
//
// Every method validates its input completely; a bad frame fails the
// handshake with an ErrorCode and a reason and never throws.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/net/crypto.h"
#include "common/net/framing.h"
#include "wire.pb.h"

namespace hemm::net {

inline constexpr uint32_t kProtocolVersion = wire::PROTOCOL_VERSION_CURRENT;
inline constexpr size_t kMaxStationNameBytes = 64;
inline constexpr size_t kMaxReasonBytes = 256;

// What a finished handshake leaves: the session id, the keys and the sealed
// TCP channel state of this side.
struct SessionSecrets {
  uint64_t session_id = 0;
  SessionKeys keys;
  std::unique_ptr<FrameSealer> tx;  // our direction's tcp key
  std::unique_ptr<FrameOpener> rx;  // the peer's
};

struct HandshakeStep {
  enum class Kind {
    kContinue,       // send `reply` (if any), wait for the next frame
    kAuthenticated,  // server: the client proved the key; caller sends Welcome or Error (sealed)
    kOpen,           // client: Welcome received; session open
    kFailed,         // send `reply` (an Error, if any) and close
  };
  Kind kind = Kind::kContinue;
  std::vector<uint8_t> reply;  // a frame payload, possibly empty
  wire::ErrorCode error = wire::ERROR_UNSPECIFIED;
  std::string reason;             // peer-supplied parts made log-safe (log_guard.h)
  bool reported_by_peer = false;  // the failure came in an Error frame from the peer
  // The peer's refusal is authenticated (see the file comment): only such a
  // refusal may end the operator's attempts for good.
  bool authenticated = false;
};

// Serialises a SessionFrame (clear) with an Error body, reason truncated to kMaxReasonBytes.
std::vector<uint8_t> make_error_frame(wire::ErrorCode code, const std::string& reason);
// The same, tagged for the client whose Hello bytes are `hello` (file comment).
std::vector<uint8_t> make_tagged_error_frame(const Key& psk, std::span<const uint8_t> hello, wire::ErrorCode code,
                                             const std::string& reason);
// True if `e` carries a refusal tag that matches (psk, hello) (constant time).
bool refusal_tag_matches(const Key& psk, std::span<const uint8_t> hello, const wire::Error& e);
// Parses a clear frame payload; false if not a valid SessionFrame with a body.
bool parse_session_frame(std::span<const uint8_t> payload, wire::SessionFrame* out);
// Truncates to at most n bytes on a UTF-8 boundary-agnostic basis (logs only).
std::string truncate_text(const std::string& s, size_t n);

class ClientHandshake {
 public:
  struct Params {
    Key psk{};
    uint32_t protocol_version = kProtocolVersion;
    std::string station_name = "operator";
    bool want_control = true;
    std::optional<Nonce> client_nonce;  // tests only; random if unset
  };
  explicit ClientHandshake(Params p);

  // The Hello frame payload (call once, first).
  std::vector<uint8_t> start();
  // Feeds one received frame payload.
  HandshakeStep on_frame(std::span<const uint8_t> payload);

  bool open() const { return state_ == State::kOpen; }
  const wire::Welcome& welcome() const { return welcome_; }
  // Moves the session secrets out (valid after kOpen).
  SessionSecrets take_secrets() { return std::move(secrets_); }

 private:
  enum class State { kStart, kAwaitChallenge, kAwaitWelcome, kOpen, kFailed };
  HandshakeStep fail(wire::ErrorCode code, std::string reason, bool send_error, bool by_peer = false,
                     bool authenticated = false);

  Params p_;
  State state_ = State::kStart;
  Nonce client_nonce_{};
  std::vector<uint8_t> hello_bytes_;
  SessionSecrets secrets_;
  wire::Welcome welcome_;
};

class ServerHandshake {
 public:
  struct Params {
    Key psk{};
    uint32_t protocol_version = kProtocolVersion;
    std::optional<Nonce> server_nonce;  // tests only; random if unset
    std::optional<uint64_t> session_id; // tests only; random if unset
  };
  explicit ServerHandshake(Params p);

  HandshakeStep on_frame(std::span<const uint8_t> payload);

  bool authenticated() const { return state_ == State::kAuthenticated; }
  const wire::Hello& hello() const { return hello_; }
  uint64_t session_id() const { return session_id_; }
  SessionSecrets take_secrets() { return std::move(secrets_); }

 private:
  enum class State { kAwaitHello, kAwaitProof, kAuthenticated, kFailed };
  HandshakeStep fail(wire::ErrorCode code, std::string reason, bool send_error, bool by_peer = false);

  Params p_;
  State state_ = State::kAwaitHello;
  std::vector<uint8_t> hello_bytes_;  // as received: what refusals are tagged over
  wire::Hello hello_;
  Nonce server_nonce_{};
  uint64_t session_id_ = 0;
  std::vector<uint8_t> transcript_;
  SessionSecrets secrets_;
};

// Seals a SessionFrame with the session's tx state; returns the frame payload.
std::vector<uint8_t> seal_session_frame(FrameSealer& tx, const wire::SessionFrame& f);
// Opens and parses a sealed frame payload. False on a bad tag or a bad frame.
bool open_session_frame(FrameOpener& rx, std::span<const uint8_t> sealed, wire::SessionFrame* out);

}  // namespace hemm::net
