#include "robot_side/server/robot_server.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/net/session_id.h"

namespace hemm::robot {
namespace {

// Per-source limits: an IPv4 address, or an IPv6 /64 (one host's share of
// addresses; counting each IPv6 address alone would give one host millions).
std::string source_of(const asio::ip::address& a) {
  if (a.is_v4()) return a.to_string();
  const asio::ip::address_v6 v6 = a.to_v6();
  if (v6.is_v4_mapped()) return asio::ip::make_address_v4(asio::ip::v4_mapped, v6).to_string();
  auto b = v6.to_bytes();
  std::fill(b.begin() + 8, b.end(), 0);
  return asio::ip::address_v6(b).to_string() + "/64";
}

}  // namespace

RobotServer::RobotServer(asio::io_context& io, RobotServerOptions o)
    : io_(io),
      o_(std::move(o)),
      acceptor_(io),
      accept_timer_(io),
      streams_(io, net::StreamLinkParams{"robot", o_.heartbeat_period_ms, o_.ping_period_ms, o_.link_timeout_ms,
                                         o_.replay_window, /*learn_peer_from_source=*/true, o_.rtt_ms}) {
  streams_.on_link_change([this](bool up) {
    // The controlling operator is only in control while its link is up.
    in_control_.store(up && active_ != nullptr && active_control_, std::memory_order_release);
  });
}

RobotServer::~RobotServer() {
  for (auto& [id, p] : pending_) p.conn->close();
  pending_.clear();
  if (active_) active_->close();
  streams_.stop();
}

bool RobotServer::start(std::string* error) {
  asio::error_code ec;
  const auto addr = asio::ip::make_address(o_.listen_address, ec);
  if (ec) {
    *error = "bad listen address '" + o_.listen_address + "': " + ec.message();
    return false;
  }
  const asio::ip::tcp::endpoint tep(addr, o_.session_port);
  acceptor_.open(tep.protocol(), ec);
  if (!ec) acceptor_.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) acceptor_.bind(tep, ec);
  if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) {
    *error = "cannot listen on TCP " + o_.listen_address + ":" + std::to_string(o_.session_port) + ": " + ec.message();
    return false;
  }
  session_port_ = acceptor_.local_endpoint().port();
  if (!streams_.bind(asio::ip::udp::endpoint(addr, o_.stream_port), error)) return false;
  stream_port_ = streams_.local_endpoint().port();
  spdlog::info("event=listening address={} session_port={} stream_port={}", o_.listen_address, session_port_,
               stream_port_);
  accept();
  return true;
}

void RobotServer::stop(const std::string& reason) {
  if (stopped_) return;
  stopped_ = true;
  asio::error_code ec;
  acceptor_.close(ec);
  accept_timer_.cancel();
  for (auto& [id, p] : pending_) {
    p.timer->cancel();
    p.conn->close();
  }
  pending_.clear();
  end_active(reason, true);
  streams_.stop();
}

bool RobotServer::log_allowed(uint64_t* suppressed) { return peer_log_.allow(net::steady_now_ns(), suppressed); }

void RobotServer::accept() {
  acceptor_.async_accept([this](const asio::error_code& ec, asio::ip::tcp::socket sock) {
    if (stopped_ || ec == asio::error::operation_aborted) return;
    if (ec) {
      accept_failed(ec);
      return;
    }
    accept_backoff_ms_ = 0;
    admit(std::move(sock));
    accept();
  });
}

void RobotServer::accept_failed(const asio::error_code& ec) {
  // E.g. out of file descriptors: retrying at once would spin (and log) at
  // full speed while nothing can change. Back off, then accept again.
  accept_backoff_ms_ = std::clamp(2 * accept_backoff_ms_, 10, 1000);
  streams_.update_stats([](net::LinkStatistics& s) { ++s.accept_errors; });
  uint64_t suppressed = 0;
  if (log_allowed(&suppressed)) {
    spdlog::warn("event=accept_failed error=\"{}\" retry_ms={} suppressed={}", net::log_safe(ec.message()),
                 accept_backoff_ms_, suppressed);
  }
  accept_timer_.expires_after(std::chrono::milliseconds(accept_backoff_ms_));
  accept_timer_.async_wait([this](const asio::error_code& tec) {
    if (!tec && !stopped_) accept();
  });
}

void RobotServer::evict_oldest(const std::string& source, const char* why) {
  // The oldest idle (no Hello yet) connection of the source, else its oldest.
  // Ids grow with time, so the map's order is the age order.
  auto victim = pending_.end();
  for (auto it = pending_.begin(); it != pending_.end(); ++it) {
    if (it->second.source != source) continue;
    if (victim == pending_.end()) victim = it;
    if (!it->second.got_hello) {
      victim = it;
      break;
    }
  }
  if (victim == pending_.end()) return;
  streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_evicted; });
  uint64_t suppressed = 0;
  if (log_allowed(&suppressed)) {
    spdlog::warn("event=handshake_evicted peer={} why={} suppressed={}", victim->second.conn->peer(), why,
                 suppressed);
  }
  victim->second.conn->close();
  drop_pending(victim->first);
}

void RobotServer::admit(asio::ip::tcp::socket sock) {
  asio::error_code ec;
  const auto remote = sock.remote_endpoint(ec);
  if (ec) return;  // already gone
  const std::string source = source_of(remote.address());
  size_t same = 0;
  for (const auto& [id, p] : pending_) same += p.source == source;
  if (same >= std::max<size_t>(1, o_.max_pending_per_source)) evict_oldest(source, "too_many_from_source");
  if (pending_.size() >= std::max<size_t>(1, o_.max_pending_handshakes)) {
    // Full: take room from the source that holds the most.
    std::map<std::string, size_t> per_source;
    for (const auto& [id, p] : pending_) ++per_source[p.source];
    const auto busiest = std::max_element(per_source.begin(), per_source.end(),
                                          [](const auto& a, const auto& b) { return a.second < b.second; });
    evict_oldest(busiest->first, "too_many_pending");
  }
  const uint64_t id = next_pending_id_++;
  Pending p;
  p.conn = std::make_shared<net::SessionConnection>(std::move(sock), o_.max_frame_bytes);
  p.source = source;
  net::ServerHandshake::Params hp;
  hp.psk = o_.psk;
  hp.protocol_version = o_.protocol_version;
  p.hs = std::make_unique<net::ServerHandshake>(hp);
  p.timer = std::make_unique<asio::steady_timer>(io_);
  uint64_t suppressed = 0;
  if (log_allowed(&suppressed)) spdlog::info("event=connection peer={} suppressed={}", p.conn->peer(), suppressed);
  auto conn = p.conn;
  pending_.emplace(id, std::move(p));
  arm_step_timer(id);
  conn->start([this, id](std::span<const uint8_t> payload) { on_pending_frame(id, payload); },
              [](const wire::SessionFrame&) {},
              [this, id](const std::string& reason) {
                auto it = pending_.find(id);
                if (it == pending_.end()) return;
                uint64_t n = 0;
                if (log_allowed(&n)) {
                  spdlog::info("event=handshake_aborted peer={} reason=\"{}\" suppressed={}", it->second.conn->peer(),
                               net::log_safe(reason), n);
                }
                drop_pending(id);
              });
}

void RobotServer::arm_step_timer(uint64_t id) {
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  // Each step waits for one frame from the operator: about one round trip.
  it->second.timer->expires_after(std::chrono::milliseconds(int64_t{o_.handshake_timeout_ms} + o_.rtt_ms));
  it->second.timer->async_wait([this, id](const asio::error_code& tec) {
    if (tec) return;
    auto p = pending_.find(id);
    if (p == pending_.end()) return;
    streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_failed; });
    uint64_t suppressed = 0;
    if (log_allowed(&suppressed)) {
      spdlog::warn("event=handshake_failed peer={} code=ERROR_TIMEOUT reason=\"handshake step timed out\" "
                   "suppressed={}",
                   p->second.conn->peer(), suppressed);
    }
    p->second.conn->send_raw(net::make_error_frame(wire::ERROR_TIMEOUT, "handshake timed out"));
    p->second.conn->close_after_send();
    drop_pending(id);
  });
}

void RobotServer::drop_pending(uint64_t id) {
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  if (it->second.timer) it->second.timer->cancel();
  pending_.erase(it);
}

void RobotServer::on_pending_frame(uint64_t id, std::span<const uint8_t> payload) {
  auto it = pending_.find(id);
  if (it == pending_.end()) return;
  Pending& p = it->second;
  const net::HandshakeStep step = p.hs->on_frame(payload);
  switch (step.kind) {
    case net::HandshakeStep::Kind::kContinue:
      p.got_hello = true;
      if (!step.reply.empty()) p.conn->send_raw(step.reply);
      arm_step_timer(id);  // the next step has its own time
      return;
    case net::HandshakeStep::Kind::kFailed: {
      uint64_t suppressed = 0;
      if (log_allowed(&suppressed)) {
        spdlog::warn("event=handshake_failed peer={} code={} reason=\"{}\" suppressed={}", p.conn->peer(),
                     wire::ErrorCode_Name(step.error), net::log_safe(step.reason), suppressed);
      }
      streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_failed; });
      if (!step.reply.empty()) p.conn->send_raw(step.reply);
      p.conn->close_after_send();
      drop_pending(id);
      return;
    }
    case net::HandshakeStep::Kind::kOpen: return;  // client-only
    case net::HandshakeStep::Kind::kAuthenticated: break;
  }
  Pending taken = std::move(p);
  taken.timer->cancel();
  drop_pending(id);
  const std::string name = net::log_safe(taken.hs->hello().station_name(), net::kMaxStationNameBytes);
  // A held session whose link has been silent past the timeout (and past a
  // grace period after opening) no longer blocks a new operator.
  const int64_t now = net::steady_now_ns();
  const int64_t grace = int64_t{o_.link_timeout_ms + o_.handshake_timeout_ms} * 1000000;
  const bool active_alive = active_ && (streams_.link_up() || now - active_since_ns_ < grace);
  if (active_alive) {
    const std::string reason = "control taken: operator '" + active_name_ + "' at " + active_->peer() +
                               " already controls this robot";
    spdlog::warn("event=session_refused peer={} name=\"{}\" code=ERROR_CONTROL_TAKEN reason=\"{}\"", taken.conn->peer(),
                 name, reason);
    streams_.update_stats([](net::LinkStatistics& s) { ++s.sessions_refused; });
    taken.conn->secure(taken.hs->take_secrets());
    wire::SessionFrame f;
    f.mutable_error()->set_code(wire::ERROR_CONTROL_TAKEN);
    f.mutable_error()->set_reason(reason);
    taken.conn->send(f);
    taken.conn->close_after_send();
    return;
  }
  if (active_) end_active("replaced by a new session (link was lost)", true);
  activate(std::move(taken));
}

void RobotServer::activate(Pending p) {
  net::SessionSecrets secrets = p.hs->take_secrets();
  const uint64_t sid = secrets.session_id;
  const net::Key udp_tx = secrets.keys.udp_s2c;
  const net::Key udp_rx = secrets.keys.udp_c2s;
  active_ = p.conn;
  active_session_ = sid;
  active_since_ns_ = net::steady_now_ns();
  active_name_ = net::log_safe(p.hs->hello().station_name(), net::kMaxStationNameBytes);
  const bool control = p.hs->hello().want_control();
  active_control_ = control;
  active_->secure(std::move(secrets));
  auto conn = active_;
  // Frames now arrive through the sealed path; the close handler must see this session only.
  conn->set_handlers([](std::span<const uint8_t>) {},
                       [this](const wire::SessionFrame& f) { on_active_frame(f); },
                       [this, sid](const std::string& reason) {
                         if (active_session_ == sid) end_active("session connection lost: " + reason, false);
                       });
  wire::SessionFrame w;
  auto* wm = w.mutable_welcome();
  wm->set_session_id(sid);
  wm->set_stream_port(stream_port_);
  wm->set_has_control(control);
  wm->set_robot_time_ns(net::steady_now_ns());
  wm->set_heartbeat_period_ms(o_.heartbeat_period_ms);
  wm->set_link_timeout_ms(o_.link_timeout_ms);
  active_->send(w);
  streams_.open_session(sid, udp_tx, udp_rx, std::nullopt);
  streams_.update_stats([](net::LinkStatistics& s) { ++s.sessions_opened; });
  spdlog::info("event=session_open peer={} name=\"{}\" session={} has_control={}", active_->peer(), active_name_,
               net::hex_id(sid), control);
}

void RobotServer::on_active_frame(const wire::SessionFrame& f) {
  switch (f.body_case()) {
    case wire::SessionFrame::kBye:
      spdlog::info("event=peer_bye session={} reason=\"{}\"", net::hex_id(active_session_),
                   net::log_safe(f.bye().reason()));
      end_active("operator said bye", false);
      return;
    case wire::SessionFrame::kError:
      spdlog::warn("event=peer_error session={} code={} reason=\"{}\"", net::hex_id(active_session_),
                   wire::ErrorCode_Name(f.error().code()), net::log_safe(f.error().reason()));
      end_active("operator reported an error", false);
      return;
    default: break;
  }
  auto it = handlers_.find(f.body_case());
  if (it != handlers_.end() && it->second) {
    it->second(f);
  } else {
    spdlog::debug("event=session_frame_ignored kind={}", static_cast<int>(f.body_case()));
  }
}

void RobotServer::send_session_frame(const wire::SessionFrame& f) {
  if (active_) active_->send(f);
}

void RobotServer::end_active(const std::string& reason, bool send_bye) {
  if (!active_) return;
  spdlog::info("event=session_closed session={} reason=\"{}\"", net::hex_id(active_session_), reason);
  if (send_bye && active_->is_open()) {
    wire::SessionFrame b;
    b.mutable_bye()->set_reason(reason);
    active_->send(b);
    active_->close_after_send();
  } else {
    active_->close();
  }
  active_.reset();
  active_session_ = 0;
  in_control_.store(false, std::memory_order_release);
  streams_.close_session();
}

}  // namespace hemm::robot
