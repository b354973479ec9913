// The operator station's side of the link: connects to the robot's session
// port, runs the client handshake, opens the UDP stream link, and re-opens
// the session for up to reconnect_for_ms when the TCP connection drops.
//
// Time-outs follow the round trip: a TCP connect attempt has
// connect_timeout_ms + rtt_ms, each handshake step (Challenge, Welcome)
// handshake_timeout_ms + the round trip (the configured rtt_ms, or, once a
// Challenge came back, the measured Hello-to-Challenge time if longer),
// doubled after each step that timed out (up to 4x). Failed attempts are
// retried after 200 ms, doubling up to 5 s, for connect_for_ms on first
// contact and reconnect_for_ms after a lost session.
//
// Refusals (issue 23): only an authenticated refusal ends the attempts at
// once (net::HandshakeStep::authenticated: sealed with the session keys, or a
// clear Error tagged with the pre-shared key over our Hello): a wrong
// protocol version, and control taken before any session was open. An
// unauthenticated one (a clear Error without a valid tag, which anyone on the
// path or on the robot's port can send, or a Challenge whose proof does not
// match our key) fails that attempt only; when the time is up the client
// gives up with the code of the last refusal (give_up_code()).
// Runs on one io_context (the network thread); link_up(), has_control() and
// statistics() may be called from other threads.
//
// Later features plug in by registering handlers: streams().on(kind, ...)
// for StreamMessage kinds and on_session_frame(kind, ...) for SessionFrames.
#pragma once

#include <asio.hpp>
#include <atomic>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "common/net/exit_codes.h"
#include "common/net/handshake.h"
#include "common/net/link_options.h"
#include "common/net/session_connection.h"
#include "common/net/stream_link.h"

namespace hemm::op {

struct OperatorClientOptions : net::LinkOptions {
  OperatorClientOptions() { station_name = "operator"; }
  std::string robot_address = "127.0.0.1";
  uint16_t session_port = 47000;
  uint16_t stream_port = 0;  // 0: the port announced in Welcome
  std::string bind_address = "0.0.0.0";
  uint16_t local_stream_port = 0;
  bool want_control = true;
  uint32_t connect_timeout_ms = 3000;  // one TCP connect attempt
  uint32_t connect_for_ms = 30000;     // first contact: keep trying this long
  uint32_t reconnect_for_ms = 30000;   // after a session was lost
};

class OperatorClient {
 public:
  using SessionHandler = std::function<void(const wire::SessionFrame&)>;
  // Called once when the client gives up: an ExitCode and why.
  using FatalHandler = std::function<void(int exit_code, const std::string& reason)>;

  OperatorClient(asio::io_context& io, OperatorClientOptions o);
  ~OperatorClient();

  // Binds the UDP socket and starts connecting. False with *error on failure.
  bool start(FatalHandler on_fatal, std::string* error);
  // Says Bye and closes everything.
  void stop(const std::string& reason);

  bool session_open() const { return streams_.session_open(); }
  bool link_up() const { return streams_.link_up(); }
  bool has_control() const { return has_control_.load(std::memory_order_acquire); }
  // A session was open at some point (network thread).
  bool ever_opened() const { return ever_open_; }
  // The exit code for a run that ends before a session was ever opened
  // (network thread): the last refusal's (auth 4, version 5, refused 6), or
  // peer lost (7) when no attempt was refused.
  int give_up_code() const { return last_refusal_code_; }
  net::LinkStatistics statistics() const { return streams_.statistics(); }

  net::StreamLink& streams() { return streams_; }
  void on_session_frame(wire::SessionFrame::BodyCase kind, SessionHandler h) { handlers_[kind] = std::move(h); }
  // Sees every session frame received while the session is open, before its
  // handler (for the session recording); network thread.
  void set_session_frame_tap(SessionHandler tap) { frame_tap_ = std::move(tap); }
  void send_session_frame(const wire::SessionFrame& f);

 private:
  void connect();
  void arm_step_timer(uint64_t attempt);
  int64_t step_timeout_ms() const;
  void retry_or_fail(int code, const std::string& reason, bool timed_out = false, bool authenticated = false);
  void on_handshake_frame(uint64_t attempt, std::span<const uint8_t> payload);
  void on_open();
  void on_session_frame_in(const wire::SessionFrame& f);
  void session_lost(const std::string& reason);
  void fatal(int code, const std::string& reason);

  asio::io_context& io_;
  OperatorClientOptions o_;
  net::StreamLink streams_;
  asio::steady_timer timer_;  // connect/handshake deadline and retry delay
  asio::ip::address robot_addr_;
  FatalHandler on_fatal_;

  uint64_t attempt_ = 0;
  std::shared_ptr<asio::ip::tcp::socket> connecting_;
  std::shared_ptr<net::SessionConnection> conn_;
  std::unique_ptr<net::ClientHandshake> hs_;
  bool ever_open_ = false;
  bool open_ = false;
  int64_t trying_since_ns_ = 0;
  int64_t hello_sent_ns_ = 0;
  int64_t measured_rtt_ms_ = 0;  // Hello -> Challenge of the latest attempt that got one
  uint32_t failures_ = 0;        // consecutive failed attempts (retry back-off)
  uint32_t step_timeouts_ = 0;   // consecutive attempts that ended in a step time-out
  int last_refusal_code_ = net::kExitPeerLost;
  std::atomic<bool> has_control_{false};
  std::map<wire::SessionFrame::BodyCase, SessionHandler> handlers_;
  SessionHandler frame_tap_;
  bool stopped_ = false;
};

// Maps a refusal's ErrorCode to the process exit code.
int exit_code_for(wire::ErrorCode code);

}  // namespace hemm::op
