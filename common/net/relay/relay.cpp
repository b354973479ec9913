#include "common/net/relay/relay.h"

#include <algorithm>
#include <array>
#include <asio.hpp>
#include <charconv>
#include <chrono>
#include <cmath>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/config/config.h"
#include "report.pb.h"

namespace hemm::net::relay {
namespace {

using asio::ip::tcp;
using asio::ip::udp;
using Bytes = std::vector<std::uint8_t>;


asio::ip::address to_address(const HostPort& hp) {
  if (hp.host == "localhost") return asio::ip::address_v4::loopback();
  return asio::ip::make_address(hp.host);
}

// Min-heap of due callbacks driven by one steady_timer. Equal due times run in the order
// they were scheduled (sequence number), which keeps TCP chunks in order.
class Scheduler {
 public:
  using Lateness = std::function<void(std::int64_t)>;
  Scheduler(asio::io_context& io, Lateness on_lateness)
      : timer_(io), on_lateness_(std::move(on_lateness)) {}

  void at(std::int64_t due_ns, std::function<void()> fn) {
    heap_.push_back(Item{due_ns, seq_++, std::move(fn)});
    std::push_heap(heap_.begin(), heap_.end(), Later{});
    arm();
  }

  void clear() {
    heap_.clear();
    timer_.cancel();
    armed_ns_ = kNever;
  }

 private:
  static constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::max();
  struct Item {
    std::int64_t due;
    std::uint64_t seq;
    std::function<void()> fn;
  };
  struct Later {
    bool operator()(const Item& a, const Item& b) const {
      return a.due != b.due ? a.due > b.due : a.seq > b.seq;
    }
  };

  void arm() {
    if (heap_.empty() || heap_.front().due >= armed_ns_) return;
    armed_ns_ = heap_.front().due;
    timer_.expires_at(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(armed_ns_)));
    timer_.async_wait([this](const asio::error_code& ec) {
      if (ec == asio::error::operation_aborted) return;
      armed_ns_ = kNever;
      fire();
    });
  }

  void fire() {
    for (;;) {
      if (heap_.empty()) break;
      const std::int64_t now = steady_now_ns();
      if (heap_.front().due > now) break;
      std::pop_heap(heap_.begin(), heap_.end(), Later{});
      Item item = std::move(heap_.back());
      heap_.pop_back();
      on_lateness_(now - item.due);
      item.fn();
    }
    arm();
  }

  asio::steady_timer timer_;
  Lateness on_lateness_;
  std::vector<Item> heap_;
  std::uint64_t seq_ = 0;
  std::int64_t armed_ns_ = kNever;
};

void fill(report::RelayDirection* r, const ImpairmentCounters& c) {
  r->set_received(c.received);
  r->set_forwarded(c.forwarded);
  r->set_dropped_random(c.dropped_random);
  r->set_dropped_burst(c.dropped_burst);
  r->set_dropped_outage(c.dropped_outage);
  r->set_dropped_rate(c.dropped_rate);
  r->set_duplicated(c.duplicated);
  r->set_reordered(c.reordered);
  r->set_held_outage(c.held_outage);
  r->set_bytes_received(c.bytes_received);
  r->set_bytes_forwarded(c.bytes_forwarded);
}

void text_counters(std::ostringstream& os, const char* name, const ImpairmentCounters& c) {
  os << name << ": received " << c.received << ", forwarded " << c.forwarded << ", dropped random "
     << c.dropped_random << " burst " << c.dropped_burst << " outage " << c.dropped_outage
     << " rate " << c.dropped_rate << ", duplicated " << c.duplicated << ", reordered "
     << c.reordered << ", held by outage " << c.held_outage << ", bytes " << c.bytes_received
     << " in / " << c.bytes_forwarded << " out\n";
}

}  // namespace

// ------------------------------------------------------------------------- parsing

std::string parse_host_port(const std::string& text, HostPort& out) {
  std::string host;
  std::string port;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string::npos || close + 1 >= text.size() || text[close + 1] != ':') {
      return "endpoint '" + text + "': expected [IPv6]:PORT";
    }
    host = text.substr(1, close - 1);
    port = text.substr(close + 2);
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos) return "endpoint '" + text + "': expected HOST:PORT";
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
    if (host.find(':') != std::string::npos) {
      return "endpoint '" + text + "': write IPv6 addresses as [ADDR]:PORT";
    }
  }
  unsigned value = 0;
  const auto [ptr, ec] = std::from_chars(port.data(), port.data() + port.size(), value);
  if (port.empty() || ec != std::errc() || ptr != port.data() + port.size() || value > 65535) {
    return "endpoint '" + text + "': port must be an integer in [0, 65535]";
  }
  if (host != "localhost") {
    asio::error_code aec;
    asio::ip::make_address(host, aec);
    if (aec) return "endpoint '" + text + "': '" + host + "' is not a numeric IP address";
  }
  out.host = host;
  out.port = static_cast<std::uint16_t>(value);
  return {};
}

std::string to_string(const HostPort& hp) {
  if (hp.host.find(':') != std::string::npos) {
    return "[" + hp.host + "]:" + std::to_string(hp.port);
  }
  return hp.host + ":" + std::to_string(hp.port);
}

std::string validate(const RelayConfig& cfg) {
  if (cfg.tcp_listen.has_value() != cfg.tcp_forward.has_value()) {
    return "TCP needs both a listen and a forward endpoint";
  }
  if (cfg.udp_listen.has_value() != cfg.udp_forward.has_value()) {
    return "UDP needs both a listen and a forward endpoint";
  }
  if (!cfg.tcp_listen && !cfg.udp_listen) {
    return "nothing to relay: configure a TCP pair, a UDP pair, or both";
  }
  if (cfg.tcp_forward && cfg.tcp_forward->port == 0) return "TCP forward port must not be 0";
  if (cfg.udp_forward && cfg.udp_forward->port == 0) return "UDP forward port must not be 0";
  if (cfg.max_udp_clients == 0 || cfg.max_tcp_connections == 0 || cfg.tcp_max_pending_bytes == 0) {
    return "client/connection/backlog limits must be > 0";
  }
  if (std::string e = validate(cfg.up, "up"); !e.empty()) return e;
  if (std::string e = validate(cfg.down, "down"); !e.empty()) return e;
  return {};
}

report::Relay to_report(const RelayStats& s) {
  report::Relay r;
  fill(r.mutable_tcp()->mutable_up(), s.tcp_up);
  fill(r.mutable_tcp()->mutable_down(), s.tcp_down);
  fill(r.mutable_udp()->mutable_up(), s.udp_up);
  fill(r.mutable_udp()->mutable_down(), s.udp_down);
  report::RelayCounters& c = *r.mutable_relay();
  c.set_tcp_connections(s.tcp_connections);
  c.set_tcp_connections_rejected(s.tcp_connections_rejected);
  c.set_tcp_connect_failures(s.tcp_connect_failures);
  c.set_udp_clients(s.udp_clients);
  c.set_udp_clients_rejected(s.udp_clients_rejected);
  c.set_send_errors(s.send_errors);
  report::RelayTiming& t = *r.mutable_timing();
  t.set_samples(s.timing.samples);
  t.set_median_us(s.timing.median_us);
  t.set_p99_us(s.timing.p99_us);
  t.set_max_us(s.timing.max_us);
  return r;
}

std::string stats_to_json(const RelayStats& s) {
  return config::to_json(to_report(s), config::JsonLayout::kOneLine);
}

std::string stats_to_text(const RelayStats& s) {
  std::ostringstream os;
  text_counters(os, "tcp up  ", s.tcp_up);
  text_counters(os, "tcp down", s.tcp_down);
  text_counters(os, "udp up  ", s.udp_up);
  text_counters(os, "udp down", s.udp_down);
  os << "tcp connections " << s.tcp_connections << " (rejected " << s.tcp_connections_rejected
     << ", connect failures " << s.tcp_connect_failures << "), udp clients " << s.udp_clients
     << " (rejected " << s.udp_clients_rejected << "), send errors " << s.send_errors << "\n";
  os.precision(1);
  os << std::fixed << "send timing error: median " << s.timing.median_us << " us, p99 "
     << s.timing.p99_us << " us, max " << s.timing.max_us << " us over " << s.timing.samples
     << " sends\n";
  return os.str();
}

// ------------------------------------------------------------------------- relay

struct Relay::Impl {
  struct TcpConn;
  struct UdpClient;

  // Declared first so it is destroyed last: sockets below must go before it.
  asio::io_context io;
  RelayConfig cfg;
  std::int64_t start_ns = 0;

  mutable std::mutex mu;  // guards the models, counters and timing samples below
  ImpairmentData tcp_up, tcp_down, udp_up, udp_down;
  RelayStats extra;  // only the relay-level counters are used
  std::vector<std::int64_t> lateness;  // ring of the most recent send errors
  std::size_t lateness_next = 0;
  std::uint64_t lateness_total = 0;

  Scheduler sched{io, [this](std::int64_t late) { record_lateness(late); }};
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work;
  std::optional<tcp::acceptor> acceptor;
  asio::steady_timer accept_retry{io};
  tcp::endpoint tcp_fwd;
  std::optional<udp::socket> udp_listen;
  udp::endpoint udp_fwd;
  udp::endpoint udp_sender;
  std::array<std::uint8_t, 65536> udp_buf{};
  std::map<udp::endpoint, std::shared_ptr<UdpClient>> udp_clients;
  std::vector<std::weak_ptr<TcpConn>> conns;
  std::thread thread;
  bool stopped = false;

  static constexpr std::size_t kLatenessWindow = 1u << 17;

  void record_lateness(std::int64_t late) {
    std::lock_guard lock(mu);
    if (lateness.size() < kLatenessWindow) {
      lateness.push_back(late);
    } else {
      lateness[lateness_next] = late;
      lateness_next = (lateness_next + 1) % kLatenessWindow;
    }
    ++lateness_total;
  }

  ImpairmentDecision decide(const DirectionImpairment& d, Transport tr, ImpairmentData& data,
                            std::int64_t t, std::size_t n) {
    std::lock_guard lock(mu);
    return impairment_decide(d, tr, data, t, n);
  }

  void count(std::uint64_t RelayStats::*field) {
    std::lock_guard lock(mu);
    ++(extra.*field);
  }

  // ---------------------------------------------------------------- TCP
  struct Pipe {
    tcp::socket* from = nullptr;
    tcp::socket* to = nullptr;
    const DirectionImpairment* cfg = nullptr;
    ImpairmentData* model = nullptr;
    std::array<std::uint8_t, 65536> buf{};
    std::deque<std::shared_ptr<Bytes>> ready;  // nullptr: end of stream
    std::size_t pending_bytes = 0;  // read but not yet written
    std::int64_t last_release_ns = 0;
    bool reading = false;
    bool writing = false;
    bool read_done = false;
    bool shut = false;
  };

  struct TcpConn : std::enable_shared_from_this<TcpConn> {
    Impl& relay;
    tcp::socket client;
    tcp::socket server;
    Pipe up, down;
    bool closed = false;

    TcpConn(Impl& r, tcp::socket c) : relay(r), client(std::move(c)), server(r.io) {
      up.from = &client;
      up.to = &server;
      up.cfg = &relay.cfg.up;
      up.model = &relay.tcp_up;
      down.from = &server;
      down.to = &client;
      down.cfg = &relay.cfg.down;
      down.model = &relay.tcp_down;
    }

    void start() {
      auto self = shared_from_this();
      server.async_connect(relay.tcp_fwd, [self](const asio::error_code& ec) {
        if (self->closed) return;
        if (ec) {
          self->relay.count(&RelayStats::tcp_connect_failures);
          self->close();
          return;
        }
        asio::error_code ignored;
        self->client.set_option(tcp::no_delay(true), ignored);
        self->server.set_option(tcp::no_delay(true), ignored);
        self->read(self->up);
        self->read(self->down);
      });
    }

    void close() {
      if (closed) return;
      closed = true;
      asio::error_code ignored;
      client.close(ignored);
      server.close(ignored);
    }

    void read(Pipe& p) {
      if (closed || p.reading || p.read_done) return;
      if (p.pending_bytes >= relay.cfg.tcp_max_pending_bytes) return;  // resumed by writes
      p.reading = true;
      auto self = shared_from_this();
      p.from->async_read_some(asio::buffer(p.buf), [self, &p](const asio::error_code& ec,
                                                              std::size_t n) {
        p.reading = false;
        if (self->closed) return;
        const std::int64_t t = steady_now_ns();
        if (ec) {
          if (ec != asio::error::eof) {
            self->close();
            return;
          }
          // Pass the end of stream on after the data before it, delayed like data.
          p.read_done = true;
          const std::int64_t at = std::max(t + p.cfg->delay_ns, p.last_release_ns);
          self->relay.sched.at(at, [self, &p] {
            if (self->closed) return;
            p.ready.push_back(nullptr);
            self->write(p);
          });
          return;
        }
        const ImpairmentDecision d =
            self->relay.decide(*p.cfg, Transport::kStream, *p.model, t, n);
        auto chunk = std::make_shared<Bytes>(p.buf.begin(), p.buf.begin() + static_cast<long>(n));
        p.pending_bytes += n;
        p.last_release_ns = std::max(p.last_release_ns, d.release_ns[0]);
        self->relay.sched.at(d.release_ns[0], [self, &p, chunk] {
          if (self->closed) return;
          p.ready.push_back(chunk);
          self->write(p);
        });
        self->read(p);
      });
    }

    void write(Pipe& p) {
      if (closed || p.writing || p.ready.empty()) return;
      if (!p.ready.front()) {
        p.ready.pop_front();
        asio::error_code ignored;
        p.to->shutdown(tcp::socket::shutdown_send, ignored);
        p.shut = true;
        if (up.shut && down.shut) close();
        return;
      }
      p.writing = true;
      auto self = shared_from_this();
      auto chunk = p.ready.front();
      asio::async_write(*p.to, asio::buffer(*chunk),
                        [self, &p, chunk](const asio::error_code& ec, std::size_t) {
                          p.writing = false;
                          if (self->closed) return;
                          if (ec) {
                            self->relay.count(&RelayStats::send_errors);
                            self->close();
                            return;
                          }
                          p.pending_bytes -= chunk->size();
                          p.ready.pop_front();
                          self->write(p);
                          self->read(p);
                        });
    }
  };

  void accept() {
    acceptor->async_accept([this](const asio::error_code& ec, tcp::socket sock) {
      if (ec == asio::error::operation_aborted || stopped) return;
      if (ec) {
        // E.g. out of file descriptors: retry shortly instead of spinning.
        accept_retry.expires_after(std::chrono::milliseconds(10));
        accept_retry.async_wait([this](const asio::error_code& tec) {
          if (!tec && !stopped) accept();
        });
        return;
      }
      conns.erase(std::remove_if(conns.begin(), conns.end(),
                                 [](const std::weak_ptr<TcpConn>& w) { return w.expired(); }),
                  conns.end());
      if (conns.size() >= cfg.max_tcp_connections) {
        count(&RelayStats::tcp_connections_rejected);
        asio::error_code ignored;
        sock.close(ignored);
      } else {
        count(&RelayStats::tcp_connections);
        auto conn = std::make_shared<TcpConn>(*this, std::move(sock));
        conns.push_back(conn);
        conn->start();
      }
      accept();
    });
  }

  // ---------------------------------------------------------------- UDP
  struct UdpClient : std::enable_shared_from_this<UdpClient> {
    Impl& relay;
    udp::endpoint client_ep;
    udp::socket upstream;
    std::array<std::uint8_t, 65536> buf{};

    UdpClient(Impl& r, udp::endpoint ep) : relay(r), client_ep(ep), upstream(r.io) {}

    void receive() {
      auto self = shared_from_this();
      upstream.async_receive(asio::buffer(buf), [self](const asio::error_code& ec, std::size_t n) {
        Impl& r = self->relay;
        if (r.stopped || ec == asio::error::operation_aborted || !self->upstream.is_open()) {
          return;
        }
        if (!ec) {
          const std::int64_t t = steady_now_ns();
          const ImpairmentDecision d =
              r.decide(r.cfg.down, Transport::kDatagram, r.udp_down, t, n);
          if (d.copies > 0) {
            auto data =
                std::make_shared<Bytes>(self->buf.begin(), self->buf.begin() + static_cast<long>(n));
            for (int i = 0; i < d.copies; ++i) {
              r.sched.at(d.release_ns[static_cast<std::size_t>(i)], [self, data] {
                Impl& rr = self->relay;
                if (rr.stopped || !rr.udp_listen) return;
                asio::error_code sec;
                rr.udp_listen->send_to(asio::buffer(*data), self->client_ep, 0, sec);
                if (sec) rr.count(&RelayStats::send_errors);
              });
            }
          }
        }
        // Errors such as connection_refused (ICMP from a missing server) are not fatal.
        self->receive();
      });
    }
  };

  std::shared_ptr<UdpClient> udp_client_for(const udp::endpoint& ep) {
    auto it = udp_clients.find(ep);
    if (it != udp_clients.end()) return it->second;
    if (udp_clients.size() >= cfg.max_udp_clients) {
      count(&RelayStats::udp_clients_rejected);
      return nullptr;
    }
    auto client = std::make_shared<UdpClient>(*this, ep);
    asio::error_code ec;
    client->upstream.open(udp_fwd.protocol(), ec);
    if (!ec) client->upstream.connect(udp_fwd, ec);
    if (!ec) client->upstream.non_blocking(true, ec);
    if (ec) {
      count(&RelayStats::send_errors);
      return nullptr;
    }
    count(&RelayStats::udp_clients);
    udp_clients.emplace(ep, client);
    client->receive();
    return client;
  }

  void udp_receive() {
    udp_listen->async_receive_from(
        asio::buffer(udp_buf), udp_sender, [this](const asio::error_code& ec, std::size_t n) {
          if (stopped || ec == asio::error::operation_aborted) return;
          if (!ec) {
            const std::int64_t t = steady_now_ns();
            if (auto client = udp_client_for(udp_sender)) {
              const ImpairmentDecision d = decide(cfg.up, Transport::kDatagram, udp_up, t, n);
              if (d.copies > 0) {
                auto data =
                    std::make_shared<Bytes>(udp_buf.begin(), udp_buf.begin() + static_cast<long>(n));
                for (int i = 0; i < d.copies; ++i) {
                  sched.at(d.release_ns[static_cast<std::size_t>(i)], [this, client, data] {
                    if (stopped) return;
                    asio::error_code sec;
                    client->upstream.send(asio::buffer(*data), 0, sec);
                    if (sec) count(&RelayStats::send_errors);
                  });
                }
              }
            }
          }
          udp_receive();
        });
  }

  // ---------------------------------------------------------------- lifecycle
  void close_all() {
    stopped = true;
    asio::error_code ignored;
    if (acceptor) acceptor->close(ignored);
    accept_retry.cancel();
    if (udp_listen) udp_listen->close(ignored);
    for (auto& [ep, client] : udp_clients) client->upstream.close(ignored);
    for (auto& w : conns) {
      if (auto c = w.lock()) c->close();
    }
    sched.clear();
    work.reset();
  }
};

Relay::Relay(const RelayConfig& cfg) : impl_(std::make_unique<Impl>()) {
  if (std::string err = validate(cfg); !err.empty()) throw std::invalid_argument(err);
  Impl& m = *impl_;
  m.cfg = cfg;
  if (cfg.tcp_listen) {
    const tcp::endpoint listen(to_address(*cfg.tcp_listen), cfg.tcp_listen->port);
    m.tcp_fwd = tcp::endpoint(to_address(*cfg.tcp_forward), cfg.tcp_forward->port);
    m.acceptor.emplace(m.io);
    m.acceptor->open(listen.protocol());
    m.acceptor->set_option(tcp::acceptor::reuse_address(true));
    m.acceptor->bind(listen);
    m.acceptor->listen();
  }
  if (cfg.udp_listen) {
    const udp::endpoint listen(to_address(*cfg.udp_listen), cfg.udp_listen->port);
    m.udp_fwd = udp::endpoint(to_address(*cfg.udp_forward), cfg.udp_forward->port);
    m.udp_listen.emplace(m.io);
    m.udp_listen->open(listen.protocol());
    m.udp_listen->bind(listen);
    m.udp_listen->non_blocking(true);
  }
  m.start_ns = steady_now_ns();
  impairment_reset(cfg.up, m.tcp_up, mix_seed(cfg.seed, 0), m.start_ns);
  impairment_reset(cfg.down, m.tcp_down, mix_seed(cfg.seed, 1), m.start_ns);
  impairment_reset(cfg.up, m.udp_up, mix_seed(cfg.seed, 2), m.start_ns);
  impairment_reset(cfg.down, m.udp_down, mix_seed(cfg.seed, 3), m.start_ns);
  m.work.emplace(m.io.get_executor());
  if (m.acceptor) m.accept();
  if (m.udp_listen) m.udp_receive();
  m.thread = std::thread([&m] { m.io.run(); });
}

Relay::~Relay() { stop(); }

void Relay::stop() {
  Impl& m = *impl_;
  if (!m.thread.joinable()) return;
  asio::post(m.io, [&m] {
    m.close_all();
    m.io.stop();
  });
  m.thread.join();
  // Drop the scheduled sends' references to connections before the sockets go.
  m.sched.clear();
  m.conns.clear();
  m.udp_clients.clear();
}

std::uint16_t Relay::tcp_listen_port() const {
  if (!impl_->acceptor) return 0;
  asio::error_code ec;
  const auto ep = impl_->acceptor->local_endpoint(ec);
  return ec ? 0 : ep.port();
}

std::uint16_t Relay::udp_listen_port() const {
  if (!impl_->udp_listen) return 0;
  asio::error_code ec;
  const auto ep = impl_->udp_listen->local_endpoint(ec);
  return ec ? 0 : ep.port();
}

RelayStats Relay::stats() const {
  const Impl& m = *impl_;
  RelayStats s;
  std::vector<std::int64_t> late;
  {
    std::lock_guard lock(m.mu);
    s = m.extra;
    s.tcp_up = m.tcp_up.counters;
    s.tcp_down = m.tcp_down.counters;
    s.udp_up = m.udp_up.counters;
    s.udp_down = m.udp_down.counters;
    late = m.lateness;
  }
  if (!late.empty()) {
    auto pct = [&late](double q) {
      const std::size_t i = std::min(late.size() - 1,
                                     static_cast<std::size_t>(q * static_cast<double>(late.size())));
      std::nth_element(late.begin(), late.begin() + static_cast<long>(i), late.end());
      return static_cast<double>(late[i]) * 1e-3;
    };
    s.timing.samples = late.size();
    s.timing.median_us = pct(0.5);
    s.timing.p99_us = pct(0.99);
    s.timing.max_us = static_cast<double>(*std::max_element(late.begin(), late.end())) * 1e-3;
  }
  return s;
}

}  // namespace hemm::net::relay
