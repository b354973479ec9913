// The stream channel of one station over Asio: a UDP socket, the sealed
// datagram codec, the replay window and counters (StreamReceiver),
// heartbeats, ping/pong with the clock-offset estimator, link-loss
// detection, and path validation (path_validation.h): the robot sends to an
// operator address only after a PathChallenge sent there was answered; the
// operator answers every PathChallenge it receives. All methods except
// statistics(), link_up() and session_open() must be called on the
// io_context's (network) thread; those three are safe from any thread.
//
// Other StreamMessage kinds are added by registering a handler with on();
// a handler can publish into a NewestMailbox (common/concurrency/newest_mailbox.h) for another thread.
#pragma once

#include <array>
#include <asio.hpp>
#include <atomic>
#include <functional>
#include <mutex>
#include <optional>
#include <string>

#include "common/net/clock_sync.h"
#include "common/net/link_stats.h"
#include "common/net/path_validation.h"
#include "common/net/stream_receiver.h"

namespace hemm::net {

struct StreamLinkParams {
  std::string role = "station";        // for logs and statistics
  uint32_t heartbeat_period_ms = 50;
  uint32_t ping_period_ms = 50;
  uint32_t link_timeout_ms = 500;
  uint32_t replay_window = 1024;
  // Robot: the peer's endpoint is learned from authenticated datagrams and
  // validated by a path challenge (so a relay can sit in between, and a copy
  // sent from elsewhere diverts nothing). Operator: fixed endpoint.
  bool learn_peer_from_source = false;
  // Expected round trip (0: unknown): the first path-challenge retry waits
  // 2 round trips (250 ms while unknown); the measured one replaces it.
  uint32_t expected_rtt_ms = 0;
};

class StreamLink {
 public:
  using Handler = std::function<void(const DatagramHeader& h, int64_t recv_ns, const wire::StreamMessage& m)>;
  using LinkHandler = std::function<void(bool up)>;

  StreamLink(asio::io_context& io, StreamLinkParams p);
  ~StreamLink();

  // Binds the UDP socket. False with *error on failure.
  bool bind(const asio::ip::udp::endpoint& local, std::string* error);
  asio::ip::udp::endpoint local_endpoint() const;

  // Starts a session: datagrams are sealed with tx_key, accepted with rx_key.
  // peer: where to send (empty: learn from the first authenticated datagram).
  // Everything of the previous session is forgotten: sequence numbers, the
  // replay window, the path, and the clock estimate (a new session may be a
  // new host: until its first pong there is no estimate, and every message
  // age is unknown).
  void open_session(uint64_t session_id, const Key& tx_key, const Key& rx_key,
                    std::optional<asio::ip::udp::endpoint> peer);
  void close_session();
  void stop();  // closes the socket and timers

  // Sends one message (stamped with the next sequence number and now). False
  // if there is no session/peer or it does not fit in one datagram.
  bool send(const wire::StreamMessage& m);

  void on(wire::StreamMessage::BodyCase kind, Handler h);
  void on_link_change(LinkHandler h) { on_link_change_ = std::move(h); }

  bool link_up() const { return link_up_.load(std::memory_order_acquire); }
  bool session_open() const { return session_open_.load(std::memory_order_acquire); }
  LinkStatistics statistics() const;
  // The clock-offset / round-trip estimate (network thread only; no lock).
  const ClockEstimate& clock() const { return clock_.estimate(); }
  // Lets the owner fold its own session counters into the snapshot.
  template <class F>
  void update_stats(F&& f) {
    std::lock_guard<std::mutex> lk(mu_);
    f(stats_);
  }

 private:
  void receive();
  bool send_to(const wire::StreamMessage& m, const asio::ip::udp::endpoint& to);
  void handle(std::span<const uint8_t> d, const asio::ip::udp::endpoint& from, int64_t now);
  void on_path_message(const wire::StreamMessage& m, const asio::ip::udp::endpoint& from, int64_t now);
  void tick();
  void update_path_timing();
  void set_link(bool up, int64_t now);
  void sync_stats();

  StreamLinkParams p_;
  asio::ip::udp::socket socket_;
  asio::steady_timer timer_;
  std::array<uint8_t, 2048> rbuf_{};
  asio::ip::udp::endpoint from_;
  std::optional<asio::ip::udp::endpoint> peer_;

  StreamReceiver rx_;
  ClockOffsetEstimator clock_;
  PathValidator paths_;
  uint64_t challenges_ignored_ = 0;  // operator: challenges not from its peer
  uint64_t session_id_ = 0;
  Key tx_key_{};
  uint64_t next_seq_ = 1;
  uint64_t next_ping_id_ = 1;
  int64_t last_rx_ns_ = 0;
  int64_t last_ping_ns_ = 0;
  int64_t last_heartbeat_ns_ = 0;
  bool ever_up_ = false;
  std::array<Handler, 16> handlers_{};
  LinkHandler on_link_change_;
  std::vector<uint8_t> txbuf_;
  std::string payload_;

  std::atomic<bool> link_up_{false};
  std::atomic<bool> session_open_{false};
  mutable std::mutex mu_;  // guards stats_ (snapshots for other threads)
  LinkStatistics stats_;
  bool stopped_ = false;
};

}  // namespace hemm::net
