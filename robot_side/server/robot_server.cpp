#include "robot_side/server/robot_server.h"

#include <spdlog/spdlog.h>

#include <cinttypes>

namespace hemm::robot {
namespace {

std::string hex_id(uint64_t v) {
  char b[17];
  std::snprintf(b, sizeof b, "%016" PRIx64, v);
  return b;
}

// Peer-chosen text goes into logs: keep it printable and short.
std::string sanitize(const std::string& s) {
  std::string out;
  for (char c : net::truncate_text(s, net::kMaxStationNameBytes)) {
    out.push_back((c >= 0x21 && c <= 0x7e && c != '"') ? c : '_');
  }
  return out;
}

std::string printable(const std::string& s) {
  std::string out;
  for (char c : net::truncate_text(s, net::kMaxReasonBytes)) out.push_back((c >= 0x20 && c <= 0x7e && c != '"') ? c : '_');
  return out;
}

}  // namespace

RobotServer::RobotServer(asio::io_context& io, RobotServerOptions o)
    : io_(io),
      o_(std::move(o)),
      acceptor_(io),
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
  for (auto& [id, p] : pending_) {
    p.timer->cancel();
    p.conn->close();
  }
  pending_.clear();
  end_active(reason, true);
  streams_.stop();
}

void RobotServer::accept() {
  acceptor_.async_accept([this](const asio::error_code& ec, asio::ip::tcp::socket sock) {
    if (stopped_ || ec == asio::error::operation_aborted) return;
    if (!ec) {
      if (pending_.size() >= o_.max_pending_handshakes) {
        spdlog::warn("event=connection_dropped why=too_many_pending_handshakes");
        asio::error_code ignore;
        sock.close(ignore);
      } else {
        const uint64_t id = next_pending_id_++;
        Pending p;
        p.conn = std::make_shared<net::SessionConnection>(std::move(sock), o_.max_frame_bytes);
        net::ServerHandshake::Params hp;
        hp.psk = o_.psk;
        hp.protocol_version = o_.protocol_version;
        p.hs = std::make_unique<net::ServerHandshake>(hp);
        p.timer = std::make_unique<asio::steady_timer>(io_, std::chrono::milliseconds(o_.handshake_timeout_ms));
        spdlog::info("event=connection peer={}", p.conn->peer());
        p.timer->async_wait([this, id](const asio::error_code& tec) {
          if (tec) return;
          auto it = pending_.find(id);
          if (it == pending_.end()) return;
          spdlog::warn("event=handshake_failed peer={} code=ERROR_TIMEOUT reason=\"handshake timed out\"",
                       it->second.conn->peer());
          streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_failed; });
          it->second.conn->send_raw(net::make_error_frame(wire::ERROR_TIMEOUT, "handshake timed out"));
          it->second.conn->close_after_send();
          drop_pending(id);
        });
        auto conn = p.conn;
        pending_.emplace(id, std::move(p));
        conn->start([this, id](std::span<const uint8_t> payload) { on_pending_frame(id, payload); },
                    [](const wire::SessionFrame&) {},
                    [this, id](const std::string& reason) {
                      auto it = pending_.find(id);
                      if (it == pending_.end()) return;
                      spdlog::info("event=handshake_aborted peer={} reason=\"{}\"", it->second.conn->peer(), reason);
                      drop_pending(id);
                    });
      }
    }
    accept();
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
      if (!step.reply.empty()) p.conn->send_raw(step.reply);
      return;
    case net::HandshakeStep::Kind::kFailed:
      spdlog::warn("event=handshake_failed peer={} code={} reason=\"{}\"", p.conn->peer(),
                   wire::ErrorCode_Name(step.error), step.reason);
      streams_.update_stats([](net::LinkStatistics& s) { ++s.handshakes_failed; });
      if (!step.reply.empty()) p.conn->send_raw(step.reply);
      p.conn->close_after_send();
      drop_pending(id);
      return;
    case net::HandshakeStep::Kind::kOpen: return;  // client-only
    case net::HandshakeStep::Kind::kAuthenticated: break;
  }
  Pending taken = std::move(p);
  taken.timer->cancel();
  drop_pending(id);
  const std::string name = sanitize(taken.hs->hello().station_name());
  // A held session whose link has been silent past the timeout (and past a
  // grace period after opening) no longer blocks a new operator.
  const int64_t now = net::steady_now_ns();
  const int64_t grace = int64_t{o_.link_timeout_ms + o_.handshake_timeout_ms} * 1000000;
  const bool active_alive = active_ && (streams_.link_up() || now - active_since_ns_ < grace);
  if (active_alive) {
    const std::string reason = "control taken: operator '" + active_name_ + "' at " + active_->peer() +
                               " already controls this robot";
    spdlog::warn("event=session_refused peer={} name={} code=ERROR_CONTROL_TAKEN reason=\"{}\"", taken.conn->peer(),
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
  active_name_ = sanitize(p.hs->hello().station_name());
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
  spdlog::info("event=session_open peer={} name={} session={} has_control={}", active_->peer(), active_name_,
               hex_id(sid), control);
}

void RobotServer::on_active_frame(const wire::SessionFrame& f) {
  switch (f.body_case()) {
    case wire::SessionFrame::kBye:
      spdlog::info("event=peer_bye session={} reason=\"{}\"", hex_id(active_session_),
                   printable(f.bye().reason()));
      end_active("operator said bye", false);
      return;
    case wire::SessionFrame::kError:
      spdlog::warn("event=peer_error session={} code={} reason=\"{}\"", hex_id(active_session_),
                   wire::ErrorCode_Name(f.error().code()), printable(f.error().reason()));
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
  spdlog::info("event=session_closed session={} reason=\"{}\"", hex_id(active_session_), reason);
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
