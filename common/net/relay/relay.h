// The impairment relay: Asio forwarders that push TCP and UDP traffic between two
// stations through the simulated impairment model of impairment.h, per direction
// (up = client->server, down = server->client). Protocol-agnostic: bytes and datagrams
// are forwarded, never parsed. Kernel netem is not available on the test machines; this
// is how the loopback latency-injection tests inject delay, loss and outages.
//
// TCP: accepts on the listen endpoint; each accepted connection gets its own upstream
// connection to the forward endpoint; each direction is read in chunks, each chunk is
// released by the stream model (delay, in-order jitter, rate limit, outages hold bytes;
// never loss/duplication/reordering, TCP cannot lose bytes). An end of stream is passed
// on (shutdown of the send side) after the data before it; an error closes both sides.
// When more than the TCP backlog limit is waiting, reading pauses (backpressure).
//
// UDP: one listen socket; each client endpoint gets its own upstream socket connected to
// the forward endpoint; replies from upstream go back to that client from the listen
// socket, so the client talks to one address. Loss, bursts, duplication and reordering
// apply here.
//
// Scheduled sends use a min-heap of due times and one steady_timer; the lateness of each
// send (actual - scheduled) is measured and reported in RelayStats::timing.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "common/net/relay/impairment.h"

namespace hemm::report {
class Relay;  // report.pb.h
}

namespace hemm::net::relay {

struct HostPort {
  std::string host;  // numeric IPv4/IPv6 address, or "localhost"
  std::uint16_t port = 0;
};

// Parses "127.0.0.1:9000", "[::1]:9000" or "localhost:9000". Empty string on success,
// else an error text; `out` is unchanged on error.
std::string parse_host_port(const std::string& text, HostPort& out);
std::string to_string(const HostPort& hp);

struct RelayConfig {
  std::optional<HostPort> tcp_listen, tcp_forward;  // both or neither
  std::optional<HostPort> udp_listen, udp_forward;  // both or neither
  DirectionImpairment up;    // client -> server
  DirectionImpairment down;  // server -> client
  std::uint64_t seed = 1;
  std::size_t max_udp_clients = 1024;      // further client endpoints are ignored
  std::size_t max_tcp_connections = 256;   // further connections are closed at once
  std::size_t tcp_max_pending_bytes = 4u << 20;  // per direction and connection
};

// Empty string when valid, else a clear error.
std::string validate(const RelayConfig& cfg);

struct TimingStats {
  std::uint64_t samples = 0;  // sends measured (a bounded window of the most recent ones)
  double median_us = 0.0;     // actual - scheduled send time
  double p99_us = 0.0;
  double max_us = 0.0;
};

struct RelayStats {
  ImpairmentCounters tcp_up, tcp_down, udp_up, udp_down;
  std::uint64_t tcp_connections = 0;
  std::uint64_t tcp_connections_rejected = 0;
  std::uint64_t tcp_connect_failures = 0;
  std::uint64_t udp_clients = 0;
  std::uint64_t udp_clients_rejected = 0;
  std::uint64_t send_errors = 0;
  TimingStats timing;
};

// The statistics as proto/report.proto's Relay, and that printed on one line
// (config::to_json): {"tcp":{"up":{...},"down":{...}},"udp":{...},"relay":{...},"timing":{...}}
report::Relay to_report(const RelayStats& stats);
std::string stats_to_json(const RelayStats& stats);
// Human-readable multi-line summary.
std::string stats_to_text(const RelayStats& stats);

class Relay {
 public:
  // Validates (std::invalid_argument), binds the listen endpoints (std::system_error) and
  // starts the relay's io thread. Outage times count from here.
  explicit Relay(const RelayConfig& cfg);
  ~Relay();
  Relay(const Relay&) = delete;
  Relay& operator=(const Relay&) = delete;

  // Bound ports (useful with port 0); 0 when that transport is not configured.
  std::uint16_t tcp_listen_port() const;
  std::uint16_t udp_listen_port() const;

  RelayStats stats() const;  // thread-safe snapshot
  void stop();               // idempotent; closes everything and joins the io thread

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hemm::net::relay
