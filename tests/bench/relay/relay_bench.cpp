// Benchmarks of the impairment relay: cost of one model decision, and the timing accuracy
// of scheduled sends on loopback (scheduled vs actual send time inside the relay, and the
// end-to-end one-way delay error seen by a receiver). Numbers are reported, not asserted.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <benchmark/benchmark.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/net/relay/relay.h"

namespace {

using namespace hemm::net::relay;
constexpr std::int64_t kMs = 1'000'000;


DirectionImpairment everything() {
  DirectionImpairment cfg;
  cfg.delay_ns = 30 * kMs;
  cfg.jitter_ns = 10 * kMs;
  cfg.jitter_distribution = JitterDistribution::kNormal;
  cfg.loss = 0.05;
  cfg.gilbert_elliott = {true, 0.01, 0.4, 1.0, 0.2};
  cfg.duplicate = 0.02;
  cfg.reorder = 0.03;
  cfg.reorder_extra_ns = 15 * kMs;
  cfg.rate_bytes_per_s = 1e7;
  cfg.queue_bytes = 100'000;
  cfg.outages = {{2'000 * kMs, 300 * kMs}};
  return cfg;
}

void BM_ImpairmentDecide(benchmark::State& state) {
  const DirectionImpairment cfg = everything();
  ImpairmentData data;
  impairment_reset(cfg, data, 1, 0);
  std::int64_t t = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(impairment_decide(cfg, Transport::kDatagram, data, t, 200));
    t += 100'000;
  }
}
BENCHMARK(BM_ImpairmentDecide);

double percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(i), v.end());
  return static_cast<double>(v[i]);
}

// UDP through the relay at `rate` datagrams/s with 20 ms delay and `jitter` ms uniform jitter;
// the sink records one-way delays. Reports the relay's send-time error and the end-to-end
// delay error (one-way - scheduled one-way is not known per packet with jitter, so the
// end-to-end error is reported for jitter 0 only).
void BM_RelayUdpTimingAccuracy(benchmark::State& state) {
  const int per_second = static_cast<int>(state.range(0));
  const std::int64_t jitter_ms = state.range(1);
  for (auto _ : state) {
    int sink = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(sink, reinterpret_cast<sockaddr*>(&a), sizeof(a));
    socklen_t len = sizeof(a);
    ::getsockname(sink, reinterpret_cast<sockaddr*>(&a), &len);
    RelayConfig cfg;
    cfg.udp_listen = HostPort{"127.0.0.1", 0};
    cfg.udp_forward = HostPort{"127.0.0.1", ntohs(a.sin_port)};
    cfg.up.delay_ns = 20 * kMs;
    cfg.up.jitter_ns = jitter_ms * kMs;
    Relay relay(cfg);
    std::atomic<bool> stop{false};
    std::vector<std::int64_t> one_way_error;
    std::thread rx([&] {
      char buf[256];
      while (!stop) {
        pollfd p{sink, POLLIN, 0};
        if (::poll(&p, 1, 20) <= 0) continue;
        const ssize_t n = ::recv(sink, buf, sizeof(buf), 0);
        if (n < 8) continue;
        std::int64_t sent = 0;
        std::memcpy(&sent, buf, 8);
        one_way_error.push_back(hemm::steady_now_ns() - sent - 20 * kMs);
      }
    });
    int client = ::socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in r{};
    r.sin_family = AF_INET;
    r.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    r.sin_port = htons(relay.udp_listen_port());
    const int n = per_second * 2;  // two seconds of traffic
    const std::int64_t period = 1'000'000'000 / per_second;
    const std::int64_t t0 = hemm::steady_now_ns();
    for (int i = 0; i < n; ++i) {
      std::this_thread::sleep_until(std::chrono::steady_clock::time_point(
          std::chrono::nanoseconds(t0 + i * period)));
      char buf[64] = {};
      const std::int64_t t = hemm::steady_now_ns();
      std::memcpy(buf, &t, 8);
      ::sendto(client, buf, sizeof(buf), 0, reinterpret_cast<sockaddr*>(&r), sizeof(r));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100 + 3 * jitter_ms));
    stop = true;
    rx.join();
    const RelayStats s = relay.stats();
    relay.stop();
    ::close(client);
    ::close(sink);
    state.counters["sends"] = static_cast<double>(s.timing.samples);
    state.counters["relay_err_med_us"] = s.timing.median_us;
    state.counters["relay_err_p99_us"] = s.timing.p99_us;
    state.counters["relay_err_max_us"] = s.timing.max_us;
    if (jitter_ms == 0) {
      state.counters["e2e_err_med_us"] = percentile(one_way_error, 0.5) * 1e-3;
      state.counters["e2e_err_p99_us"] = percentile(one_way_error, 0.99) * 1e-3;
    }
  }
}
BENCHMARK(BM_RelayUdpTimingAccuracy)
    ->Args({1000, 0})
    ->Args({1000, 5})
    ->Args({100, 0})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
