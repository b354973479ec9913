#include "common/net/stream_link.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "common/net/session_connection.h"

namespace hemm::net {
namespace {

PathAddress to_path_address(const asio::ip::udp::endpoint& ep) {
  PathAddress a;
  const asio::ip::address ip = ep.address();
  const asio::ip::address_v6 v6 =
      ip.is_v4() ? asio::ip::make_address_v6(asio::ip::v4_mapped, ip.to_v4()) : ip.to_v6();
  a.ip = v6.to_bytes();
  a.port = ep.port();
  return a;
}

asio::ip::udp::endpoint to_endpoint(const PathAddress& a) {
  const asio::ip::address_v6 v6(a.ip);
  if (v6.is_v4_mapped()) return {asio::ip::make_address_v4(asio::ip::v4_mapped, v6), a.port};
  return {v6, a.port};
}

}  // namespace

StreamLink::StreamLink(asio::io_context& io, StreamLinkParams p)
    : p_(std::move(p)), socket_(io), timer_(io), rx_(p_.replay_window) {
  stats_.role = p_.role;
  // A validated path that has been silent for half the link timeout (and a
  // few heartbeats) may have moved: only then is another address challenged.
  paths_.params().quiet_ns =
      int64_t{std::max<uint32_t>(p_.link_timeout_ms / 2, 2 * p_.heartbeat_period_ms)} * 1'000'000;
  update_path_timing();
  txbuf_.reserve(kMaxDatagramBytes);
}

// Path challenges follow the round trip: the measured median once there is
// one, else the expected one (config rtt_ms), else guesses. A re-challenge
// waits 2 round trips (at least 200 ms once measured; 250 ms while unknown);
// a token lives 4 round trips (path_validation.h).
void StreamLink::update_path_timing() {
  const ClockEstimate& ce = clock_.estimate();
  const int64_t expected = int64_t{p_.expected_rtt_ms} * 1'000'000;
  PathValidatorParams& pp = paths_.params();
  if (ce.valid) {
    pp.first_retry_ns = std::max<int64_t>(2 * ce.rtt_median_ns, 200'000'000);
  } else {
    pp.first_retry_ns = expected > 0 ? 2 * expected : 250'000'000;
  }
  pp.rtt_ns = ce.valid ? ce.rtt_median_ns : expected;
}

StreamLink::~StreamLink() { stop(); }

bool StreamLink::bind(const asio::ip::udp::endpoint& local, std::string* error) {
  asio::error_code ec;
  socket_.open(local.protocol(), ec);
  if (!ec) socket_.bind(local, ec);
  if (ec) {
    if (error) *error = "cannot bind UDP " + local.address().to_string() + ":" + std::to_string(local.port()) + ": " +
                        ec.message();
    asio::error_code ignore;
    socket_.close(ignore);
    return false;
  }
  receive();
  tick();
  return true;
}

asio::ip::udp::endpoint StreamLink::local_endpoint() const {
  asio::error_code ec;
  return socket_.local_endpoint(ec);
}

void StreamLink::open_session(uint64_t session_id, const Key& tx_key, const Key& rx_key,
                              std::optional<asio::ip::udp::endpoint> peer) {
  session_id_ = session_id;
  tx_key_ = tx_key;
  next_seq_ = 1;
  peer_ = peer;
  paths_.reset();
  clock_.reset();
  update_path_timing();
  rx_.open(session_id, rx_key);
  last_rx_ns_ = steady_now_ns();
  ever_up_ = false;
  last_ping_ns_ = 0;
  last_heartbeat_ns_ = 0;
  session_open_.store(true, std::memory_order_release);
  {
    std::lock_guard<std::mutex> lk(mu_);
    stats_.session_open = true;
    stats_.clock = clock_.estimate();
  }
  // Announce ourselves at once (the robot learns our endpoint from this).
  if (peer_) {
    wire::StreamMessage hb;
    hb.mutable_heartbeat()->set_period_ms(p_.heartbeat_period_ms);
    send(hb);
  }
}

void StreamLink::close_session() {
  if (session_id_ == 0) return;
  session_id_ = 0;
  rx_.close();
  peer_.reset();
  paths_.reset();
  session_open_.store(false, std::memory_order_release);
  set_link(false, steady_now_ns());
  std::lock_guard<std::mutex> lk(mu_);
  stats_.session_open = false;
}

void StreamLink::stop() {
  if (stopped_) return;
  stopped_ = true;
  asio::error_code ec;
  timer_.cancel();
  socket_.close(ec);
}

bool StreamLink::send(const wire::StreamMessage& m) {
  if (!peer_) return false;
  return send_to(m, *peer_);
}

bool StreamLink::send_to(const wire::StreamMessage& m, const asio::ip::udp::endpoint& to) {
  if (session_id_ == 0 || stopped_) return false;
  payload_.clear();
  if (!m.SerializeToString(&payload_)) return false;
  DatagramHeader h;
  h.session_id = session_id_;
  h.seq = next_seq_;
  h.send_time_ns = steady_now_ns();
  if (!encode_datagram(tx_key_, h, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(payload_.data()),
                                                            payload_.size()),
                       &txbuf_)) {
    spdlog::warn("event=send_too_large role={} bytes={} max={}", p_.role, payload_.size(), kMaxDatagramPayloadBytes);
    return false;
  }
  // The sequence number is the AEAD nonce: it is used up whatever happens next.
  ++next_seq_;
  asio::error_code ec;
  // Non-blocking send of a datagram never blocks for long; a full buffer is a drop.
  socket_.send_to(asio::buffer(txbuf_), to, 0, ec);
  std::lock_guard<std::mutex> lk(mu_);
  if (ec) {
    ++stats_.send_errors;
  } else {
    ++stats_.sent;
  }
  return !ec;
}

void StreamLink::on(wire::StreamMessage::BodyCase kind, Handler h) {
  const auto i = static_cast<size_t>(kind);
  if (i < handlers_.size()) handlers_[i] = std::move(h);
}

void StreamLink::receive() {
  socket_.async_receive_from(asio::buffer(rbuf_), from_, [this](const asio::error_code& ec, size_t n) {
    if (stopped_ || ec == asio::error::operation_aborted) return;
    if (!ec) handle(std::span<const uint8_t>(rbuf_.data(), n), from_, steady_now_ns());
    receive();
  });
}

void StreamLink::handle(std::span<const uint8_t> d, const asio::ip::udp::endpoint& from, int64_t now) {
  DatagramHeader h;
  wire::StreamMessage m;
  const auto v = rx_.receive(d, &h, &m);
  // Rejections are counted; the log line (and its strings) only when asked for.
  if (v == StreamReceiver::Verdict::kRejected && spdlog::should_log(spdlog::level::debug)) {
    spdlog::debug("event=datagram_rejected role={} from={}:{} why=\"{}\"", p_.role, from.address().to_string(),
                  from.port(), rx_.last_error());
  }
  const bool authentic = v == StreamReceiver::Verdict::kDeliver || v == StreamReceiver::Verdict::kLate ||
                         v == StreamReceiver::Verdict::kDuplicate;
  if (authentic && p_.learn_peer_from_source) {
    if (auto token = paths_.on_datagram(to_path_address(from), now)) {
      wire::StreamMessage c;
      c.mutable_path_challenge()->set_token(token->data(), token->size());
      send_to(c, from);
      if (spdlog::should_log(spdlog::level::debug)) {
        spdlog::debug("event=path_challenge role={} to={}:{}", p_.role, from.address().to_string(), from.port());
      }
    }
  }
  // Path probes prove nothing about the streams: a challenge arrives before
  // the robot sends anything else, and must not bring the link up.
  const bool probe = v == StreamReceiver::Verdict::kDeliver && (m.body_case() == wire::StreamMessage::kPathChallenge ||
                                                               m.body_case() == wire::StreamMessage::kPathResponse);
  if ((v == StreamReceiver::Verdict::kDeliver || v == StreamReceiver::Verdict::kLate) && !probe) {
    // Authenticated and fresh: the peer is alive.
    last_rx_ns_ = now;
    // The robot's link is up only once it knows where to send (a validated path).
    if (!link_up() && peer_) set_link(true, now);
  }
  if (v == StreamReceiver::Verdict::kDeliver) {
    switch (m.body_case()) {
      case wire::StreamMessage::kPing: {
        wire::StreamMessage pong;
        auto* p = pong.mutable_pong();
        p->set_id(m.ping().id());
        p->set_t1_ns(m.ping().t1_ns());
        p->set_t2_ns(now);
        p->set_t3_ns(steady_now_ns());
        send(pong);
        break;
      }
      case wire::StreamMessage::kPong: {
        const auto& p = m.pong();
        if (clock_.add(p.t1_ns(), p.t2_ns(), p.t3_ns(), now)) {
          std::lock_guard<std::mutex> lk(mu_);
          ++stats_.pongs_received;
          stats_.clock = clock_.estimate();
        }
        break;
      }
      case wire::StreamMessage::kPathChallenge:
      case wire::StreamMessage::kPathResponse: on_path_message(m, from, now); break;
      default: break;
    }
    const auto i = static_cast<size_t>(m.body_case());
    if (i < handlers_.size() && handlers_[i]) handlers_[i](h, now, m);
  }
  sync_stats();
}

void StreamLink::on_path_message(const wire::StreamMessage& m, const asio::ip::udp::endpoint& from, int64_t now) {
  if (m.has_path_challenge()) {
    // A station with a fixed peer answers; the robot never answers challenges.
    if (p_.learn_peer_from_source || !peer_) return;
    // Only challenges that come from where we send: otherwise whoever sees the
    // robot's challenge to *its* address could forward it here, have us
    // answer, and so get its address validated.
    if (from != *peer_) {
      ++challenges_ignored_;
      return;
    }
    wire::StreamMessage r;
    r.mutable_path_response()->set_token(m.path_challenge().token());
    send(r);
    return;
  }
  if (!p_.learn_peer_from_source) return;
  const std::string& t = m.path_response().token();
  const auto peer = paths_.on_response(std::span(reinterpret_cast<const uint8_t*>(t.data()), t.size()), now);
  if (!peer) return;
  const asio::ip::udp::endpoint ep = to_endpoint(*peer);
  if (peer_ != ep) {
    spdlog::info("event=peer_endpoint role={} endpoint={}:{} validated=true response_from={}:{}", p_.role,
                 ep.address().to_string(), ep.port(), from.address().to_string(), from.port());
  }
  peer_ = ep;
  if (!link_up() && now - last_rx_ns_ <= int64_t{p_.link_timeout_ms} * 1000000) set_link(true, now);
}

void StreamLink::set_link(bool up, int64_t now) {
  const bool was = link_up_.exchange(up, std::memory_order_acq_rel);
  if (was == up) return;
  {
    std::lock_guard<std::mutex> lk(mu_);
    stats_.link_up = up;
    if (up && ever_up_) ++stats_.link_restored_events;
    if (!up && session_id_ != 0) ++stats_.link_lost_events;
  }
  if (up) {
    spdlog::info("event={} role={}", ever_up_ ? "link_restored" : "link_up", p_.role);
    ever_up_ = true;
  } else if (session_id_ != 0) {
    spdlog::warn("event=link_lost role={} silence_ms={}", p_.role, (now - last_rx_ns_) / 1000000);
  }
  if (on_link_change_) on_link_change_(up);
}

void StreamLink::tick() {
  if (stopped_) return;
  const int64_t now = steady_now_ns();
  if (session_id_ != 0) {
    if (link_up() && now - last_rx_ns_ > int64_t{p_.link_timeout_ms} * 1000000) set_link(false, now);
    if (now - last_heartbeat_ns_ >= int64_t{p_.heartbeat_period_ms} * 1000000) {
      wire::StreamMessage hb;
      hb.mutable_heartbeat()->set_period_ms(p_.heartbeat_period_ms);
      if (send(hb)) last_heartbeat_ns_ = now;
    }
    if (p_.ping_period_ms > 0 && now - last_ping_ns_ >= int64_t{p_.ping_period_ms} * 1000000) {
      wire::StreamMessage pm;
      pm.mutable_ping()->set_id(next_ping_id_);
      pm.mutable_ping()->set_t1_ns(steady_now_ns());
      if (send(pm)) {
        ++next_ping_id_;
        last_ping_ns_ = now;
        std::lock_guard<std::mutex> lk(mu_);
        ++stats_.pings_sent;
      }
    }
    update_path_timing();
  }
  sync_stats();
  const uint32_t step = std::max<uint32_t>(1, std::min({p_.heartbeat_period_ms, p_.ping_period_ms > 0 ? p_.ping_period_ms : 1000u,
                                                        p_.link_timeout_ms / 4 + 1, 50u}));
  timer_.expires_after(std::chrono::milliseconds(step));
  timer_.async_wait([this](const asio::error_code& ec) {
    if (!ec) tick();
  });
}

void StreamLink::sync_stats() {
  std::lock_guard<std::mutex> lk(mu_);
  stats_.rx = rx_.counters();
  stats_.path = paths_.counters();
  stats_.path.ignored += challenges_ignored_;
  stats_.since_last_rx_ms = ever_up_ ? (steady_now_ns() - last_rx_ns_) / 1000000 : -1;
}

LinkStatistics StreamLink::statistics() const {
  std::lock_guard<std::mutex> lk(mu_);
  return stats_;
}

}  // namespace hemm::net
