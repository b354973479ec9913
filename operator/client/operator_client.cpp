#include "operator/client/operator_client.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/net/log_guard.h"
#include "common/net/session_id.h"

namespace hemm::op {
namespace {

constexpr int64_t kFirstRetryDelayMs = 200;
constexpr int64_t kMaxRetryDelayMs = 5000;

}  // namespace

int exit_code_for(wire::ErrorCode code) {
  switch (code) {
    case wire::ERROR_AUTH_FAILED: return net::kExitAuth;
    case wire::ERROR_VERSION_MISMATCH: return net::kExitVersion;
    case wire::ERROR_CONTROL_TAKEN: return net::kExitRefused;
    case wire::ERROR_INTERNAL: return net::kExitInternal;
    default: return net::kExitPeerLost;
  }
}

OperatorClient::OperatorClient(asio::io_context& io, OperatorClientOptions o)
    : io_(io),
      o_(std::move(o)),
      streams_(io, net::StreamLinkParams{"operator", o_.heartbeat_period_ms, o_.ping_period_ms, o_.link_timeout_ms,
                                         o_.replay_window, /*learn_peer_from_source=*/false, o_.rtt_ms}),
      timer_(io) {}

OperatorClient::~OperatorClient() {
  if (conn_) conn_->close();
  if (connecting_) {
    asio::error_code ec;
    connecting_->close(ec);
  }
  streams_.stop();
}

bool OperatorClient::start(FatalHandler on_fatal, std::string* error) {
  on_fatal_ = std::move(on_fatal);
  asio::error_code ec;
  robot_addr_ = asio::ip::make_address(o_.robot_address, ec);
  if (ec) {
    *error = "bad robot address '" + o_.robot_address + "' (give an IP address): " + ec.message();
    return false;
  }
  const auto bind_addr = asio::ip::make_address(o_.bind_address, ec);
  if (ec) {
    *error = "bad bind address '" + o_.bind_address + "': " + ec.message();
    return false;
  }
  if (!streams_.bind(asio::ip::udp::endpoint(bind_addr, o_.local_stream_port), error)) return false;
  trying_since_ns_ = net::steady_now_ns();
  connect();
  return true;
}

void OperatorClient::stop(const std::string& reason) {
  if (stopped_) return;
  stopped_ = true;
  timer_.cancel();
  if (connecting_) {
    asio::error_code ec;
    connecting_->close(ec);
  }
  if (conn_) {
    if (open_) {
      wire::SessionFrame b;
      b.mutable_bye()->set_reason(reason);
      conn_->send(b);
      conn_->close_after_send();
    } else {
      conn_->close();
    }
  }
  open_ = false;
  streams_.close_session();
  streams_.stop();
}

int64_t OperatorClient::step_timeout_ms() const {
  const int64_t rtt = std::max<int64_t>(o_.rtt_ms, measured_rtt_ms_);
  return (int64_t{o_.handshake_timeout_ms} + rtt) << std::min<uint32_t>(step_timeouts_, 2);
}

void OperatorClient::arm_step_timer(uint64_t attempt) {
  timer_.expires_after(std::chrono::milliseconds(step_timeout_ms()));
  timer_.async_wait([this, attempt](const asio::error_code& tec) {
    if (tec || attempt != attempt_ || stopped_ || open_) return;
    if (conn_) conn_->close();
    conn_.reset();
    retry_or_fail(net::kExitPeerLost, "handshake timed out", /*timed_out=*/true);
  });
}

void OperatorClient::connect() {
  if (stopped_) return;
  const uint64_t attempt = ++attempt_;
  auto sock = std::make_shared<asio::ip::tcp::socket>(io_);
  connecting_ = sock;
  const asio::ip::tcp::endpoint ep(robot_addr_, o_.session_port);
  timer_.expires_after(std::chrono::milliseconds(int64_t{o_.connect_timeout_ms} + o_.rtt_ms));
  timer_.async_wait([this, attempt](const asio::error_code& ec) {
    if (ec || attempt != attempt_ || stopped_) return;
    if (connecting_) {
      asio::error_code ignore;
      connecting_->close(ignore);  // completes the connect with operation_aborted
    }
  });
  sock->async_connect(ep, [this, attempt, sock](const asio::error_code& ec) {
    if (attempt != attempt_ || stopped_) return;
    connecting_.reset();
    if (ec) {
      retry_or_fail(net::kExitPeerLost, "cannot connect to robot at " + o_.robot_address + ":" +
                                            std::to_string(o_.session_port) + ": " + ec.message());
      return;
    }
    // The Challenge must come within one step of the Hello.
    arm_step_timer(attempt);
    conn_ = std::make_shared<net::SessionConnection>(std::move(*sock), o_.max_frame_bytes);
    net::ClientHandshake::Params hp;
    hp.psk = o_.psk;
    hp.protocol_version = o_.protocol_version;
    hp.station_name = o_.station_name;
    hp.want_control = o_.want_control;
    hs_ = std::make_unique<net::ClientHandshake>(hp);
    conn_->start([this, attempt](std::span<const uint8_t> p) { on_handshake_frame(attempt, p); },
                 [this](const wire::SessionFrame& f) { on_session_frame_in(f); },
                 [this, attempt](const std::string& reason) {
                   if (attempt != attempt_) return;
                   if (open_) {
                     session_lost(reason);
                   } else {
                     conn_.reset();
                     retry_or_fail(net::kExitPeerLost, "connection closed during handshake: " + reason);
                   }
                 });
    spdlog::info("event=connected robot={}:{} step_timeout_ms={}", o_.robot_address, o_.session_port,
                 step_timeout_ms());
    hello_sent_ns_ = net::steady_now_ns();
    conn_->send_raw(hs_->start());
  });
}

void OperatorClient::retry_or_fail(int code, const std::string& reason, bool timed_out, bool authenticated) {
  if (stopped_) return;
  const int64_t now = net::steady_now_ns();
  // First contact: try for connect_for_ms. After a session: for reconnect_for_ms.
  const int64_t budget_ms = ever_open_ ? o_.reconnect_for_ms : o_.connect_for_ms;
  const bool refusal_code = code == net::kExitAuth || code == net::kExitVersion || code == net::kExitRefused;
  if (refusal_code) last_refusal_code_ = code;
  // Only the robot's authenticated word ends the attempts now; control taken
  // after a session was open may be our own old session, not yet dropped.
  const bool refusal = authenticated && refusal_code && !(code == net::kExitRefused && ever_open_);
  if (refusal || now - trying_since_ns_ >= budget_ms * int64_t{1000000}) {
    fatal(code, reason);
    return;
  }
  step_timeouts_ = timed_out ? step_timeouts_ + 1 : 0;
  const int64_t delay_ms = std::min(kMaxRetryDelayMs, kFirstRetryDelayMs << std::min<uint32_t>(failures_, 5));
  ++failures_;
  spdlog::info("event=retry reason=\"{}\" retry_in_ms={} attempt={}", net::log_safe(reason), delay_ms, failures_);
  ++attempt_;  // invalidates the old attempt's timers
  timer_.expires_after(std::chrono::milliseconds(delay_ms));
  timer_.async_wait([this](const asio::error_code& ec) {
    if (!ec) connect();
  });
}

void OperatorClient::on_handshake_frame(uint64_t attempt, std::span<const uint8_t> payload) {
  if (attempt != attempt_ || !hs_) return;
  const net::HandshakeStep step = hs_->on_frame(payload);
  switch (step.kind) {
    case net::HandshakeStep::Kind::kContinue:
      // The Challenge came: that took one round trip. After the Proof the
      // robot's frames are sealed; the handshake opens them itself (and
      // also reads a refusal sent in clear).
      measured_rtt_ms_ = (net::steady_now_ns() - hello_sent_ns_) / 1'000'000;
      if (!step.reply.empty()) conn_->send_raw(step.reply);
      arm_step_timer(attempt);  // the Welcome within one step of the Proof
      return;
    case net::HandshakeStep::Kind::kOpen: on_open(); return;
    case net::HandshakeStep::Kind::kAuthenticated: return;  // server-only
    case net::HandshakeStep::Kind::kFailed: {
      if (!step.reply.empty()) conn_->send_raw(step.reply);
      conn_->close_after_send();
      conn_.reset();
      const int code = exit_code_for(step.error);
      spdlog::error("event=handshake_failed code={} authenticated={} reason=\"{}\"", wire::ErrorCode_Name(step.error),
                    step.authenticated, net::log_safe(step.reason));
      streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_failed; });
      retry_or_fail(code, step.reason, false, step.authenticated);
      return;
    }
  }
}

void OperatorClient::on_open() {
  timer_.cancel();
  failures_ = 0;
  step_timeouts_ = 0;
  const wire::Welcome w = hs_->welcome();
  net::SessionSecrets secrets = hs_->take_secrets();
  hs_.reset();
  const uint32_t port = o_.stream_port != 0 ? o_.stream_port : w.stream_port();
  if (port == 0 || port > 65535) {
    fatal(net::kExitPeerLost, "robot announced no usable stream port");
    return;
  }
  const uint64_t sid = secrets.session_id;
  const net::Key tx = secrets.keys.udp_c2s;
  const net::Key rx = secrets.keys.udp_s2c;
  conn_->secure(std::move(secrets));
  open_ = true;
  ever_open_ = true;
  has_control_.store(w.has_control(), std::memory_order_release);
  streams_.update_stats([](net::LinkStatistics& s) { ++s.sessions_opened; });
  spdlog::info("event=session_open session={} has_control={} stream_endpoint={}:{} robot_heartbeat_ms={} "
               "robot_link_timeout_ms={}",
               net::hex_id(sid), w.has_control(), o_.robot_address, port, w.heartbeat_period_ms(), w.link_timeout_ms());
  streams_.open_session(sid, tx, rx, asio::ip::udp::endpoint(robot_addr_, static_cast<uint16_t>(port)));
}

void OperatorClient::on_session_frame_in(const wire::SessionFrame& f) {
  if (!open_) return;
  if (frame_tap_) frame_tap_(f);
  switch (f.body_case()) {
    case wire::SessionFrame::kBye:
      spdlog::warn("event=peer_bye reason=\"{}\"", net::log_safe(f.bye().reason()));
      session_lost("robot said bye");
      return;
    case wire::SessionFrame::kError:
      spdlog::error("event=peer_error code={} reason=\"{}\"", wire::ErrorCode_Name(f.error().code()),
                    net::log_safe(f.error().reason()));
      session_lost("robot reported an error");
      return;
    default: break;
  }
  auto it = handlers_.find(f.body_case());
  if (it != handlers_.end() && it->second) it->second(f);
}

void OperatorClient::send_session_frame(const wire::SessionFrame& f) {
  if (conn_ && open_) conn_->send(f);
}

void OperatorClient::session_lost(const std::string& reason) {
  if (stopped_ || !open_) return;
  open_ = false;
  has_control_.store(false, std::memory_order_release);
  if (conn_) conn_->close();
  conn_.reset();
  streams_.close_session();
  spdlog::warn("event=session_lost reason=\"{}\" reconnect_for_ms={}", net::log_safe(reason), o_.reconnect_for_ms);
  if (o_.reconnect_for_ms == 0) {
    fatal(net::kExitPeerLost, "session lost: " + reason);
    return;
  }
  trying_since_ns_ = net::steady_now_ns();
  ++attempt_;
  connect();
}

void OperatorClient::fatal(int code, const std::string& reason) {
  if (stopped_) return;
  spdlog::error("event=giving_up exit_code={} reason=\"{}\"", code, net::log_safe(reason));
  stop(reason);
  if (on_fatal_) on_fatal_(code, net::log_safe(reason));  // the reason may quote the robot
}

}  // namespace hemm::op
