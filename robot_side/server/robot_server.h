// The robot station's side of the link: listens for operator sessions on TCP,
// runs the server handshake, keeps at most one controlling operator, and runs
// the UDP stream link. Runs on one io_context (the network thread); only
// link_up(), operator_in_control() and statistics() may be called from other
// threads.
//
// Handshake exhaustion: a connection that has not finished its handshake is
// *pending*. New connections are always accepted; room is made by closing
// the oldest pending connection of the same source (an IPv4 address or an
// IPv6 /64) when that source holds max_pending_per_source, and, when all
// max_pending_handshakes are taken, the oldest of the source holding the most
// (idle ones, without a Hello, first). So idle connections from one place
// cannot lock out an operator elsewhere, and an operator's own fresh
// connection is never the one closed. Each handshake step (Hello, Proof) has
// handshake_timeout_ms + rtt_ms. Accept errors (e.g. out of descriptors)
// back off from 10 ms to 1 s. Lines a peer can cause are rate-limited
// (net::LogLimiter) and peer text is made log-safe.
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

#include "common/net/handshake.h"
#include "common/net/link_options.h"
#include "common/net/log_guard.h"
#include "common/net/session_connection.h"
#include "common/net/stream_link.h"

namespace hemm::robot {

struct RobotServerOptions : net::LinkOptions {
  RobotServerOptions() { station_name = "robot"; }
  std::string listen_address = "127.0.0.1";
  uint16_t session_port = 47000;  // 0: any free port
  uint16_t stream_port = 47001;   // 0: any free port
  size_t max_pending_handshakes = 64;
  size_t max_pending_per_source = 4;
};

class RobotServer {
 public:
  using SessionHandler = std::function<void(const wire::SessionFrame&)>;

  RobotServer(asio::io_context& io, RobotServerOptions o);
  ~RobotServer();

  // Binds TCP and UDP and starts accepting. False with *error on failure.
  bool start(std::string* error);
  // Says Bye to the operator and closes everything.
  void stop(const std::string& reason);

  uint16_t session_port() const { return session_port_; }
  uint16_t stream_port() const { return stream_port_; }

  // True while authenticated datagrams arrive within link_timeout. The robot
  // must not move when this is false.
  bool link_up() const { return streams_.link_up(); }
  bool operator_in_control() const { return in_control_.load(std::memory_order_acquire); }
  net::LinkStatistics statistics() const { return streams_.statistics(); }

  net::StreamLink& streams() { return streams_; }
  // How old a message stamped on the operator's clock is on arrival (network
  // thread): stale when older than the measured round trip plus
  // stale_margin_ms, or when there is no clock estimate yet.
  net::MessageAge message_age(int64_t operator_stamp_ns, int64_t arrival_ns) const {
    return net::judge_message_age(streams_.clock(), operator_stamp_ns, arrival_ns,
                                  int64_t{o_.stale_margin_ms} * 1'000'000);
  }
  void on_session_frame(wire::SessionFrame::BodyCase kind, SessionHandler h) { handlers_[kind] = std::move(h); }
  // Sends a sealed frame to the active operator (no-op without one).
  void send_session_frame(const wire::SessionFrame& f);

 private:
  struct Pending {
    std::shared_ptr<net::SessionConnection> conn;
    std::unique_ptr<net::ServerHandshake> hs;
    std::unique_ptr<asio::steady_timer> timer;
    std::string source;  // per-source limits: IPv4 address or IPv6 /64
    bool got_hello = false;
  };

  void accept();
  void accept_failed(const asio::error_code& ec);
  void admit(asio::ip::tcp::socket sock);
  void arm_step_timer(uint64_t id);
  void evict_oldest(const std::string& source, const char* why);
  void on_pending_frame(uint64_t id, std::span<const uint8_t> payload);
  void drop_pending(uint64_t id);
  bool log_allowed(uint64_t* suppressed);
  void activate(Pending p);
  void on_active_frame(const wire::SessionFrame& f);
  void end_active(const std::string& reason, bool send_bye);

  asio::io_context& io_;
  RobotServerOptions o_;
  asio::ip::tcp::acceptor acceptor_;
  asio::steady_timer accept_timer_;
  int accept_backoff_ms_ = 0;
  net::LogLimiter peer_log_{10.0, 30.0};  // lines per connection / refusal
  net::StreamLink streams_;
  uint16_t session_port_ = 0;
  uint16_t stream_port_ = 0;

  uint64_t next_pending_id_ = 1;
  std::map<uint64_t, Pending> pending_;

  std::shared_ptr<net::SessionConnection> active_;
  uint64_t active_session_ = 0;
  int64_t active_since_ns_ = 0;
  std::string active_name_;
  bool active_control_ = false;
  std::atomic<bool> in_control_{false};
  std::map<wire::SessionFrame::BodyCase, SessionHandler> handlers_;
  bool stopped_ = false;
};

}  // namespace hemm::robot
