// Simulated network impairment: a pure, seeded model of one direction of a link.
//
// No sockets, no clocks: the caller passes each packet's arrival time (int64 ns of a
// steady clock) and size, and the model decides whether the packet is dropped and when
// each copy of it is released. The Asio forwarders in relay.h apply these decisions to
// real traffic; everything here is reproducible from the seed.
//
// Datagram (UDP) semantics, in the order applied to each packet:
//   1. scheduled outage: a packet arriving in [start, start + duration) (relative to the
//      model's start time) is dropped (dropped_outage); nothing else advances.
//   2. Gilbert–Elliott burst loss: the packet is lost with probability 1-k in the good
//      state and 1-h in the bad state (dropped_burst); then the chain steps
//      good->bad with probability p, bad->good with probability r.
//   3. random (Bernoulli) loss with probability `loss` (dropped_random).
//   4. rate limit: a serialising bottleneck of `rate_bytes_per_s`; a packet that would
//      make the backlog exceed `queue_bytes` is dropped (dropped_rate).
//   5. propagation delay + jitter (uniform on [-j, +j] or normal with std j, truncated
//      so the delay is never negative), measured from the end of serialisation.
//   6. reordering: with probability `reorder`, extra delay `reorder_extra_ns` so later
//      packets overtake it. When reorder is 0 and `keep_order` is set, release times are
//      made monotonic (jitter then never reorders).
//   7. duplication with probability `duplicate`: a second copy with its own delay+jitter.
//
// Stream (TCP chunk) semantics: TCP cannot lose bytes, so loss, bursts, duplication and
// reordering do not apply. Bytes arriving during an outage are held until it ends; then
// rate limit (no queue drops: the forwarder applies backpressure instead), delay and
// jitter; release times are always monotonic so the byte stream stays in order.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace hemm::net::relay {

enum class JitterDistribution { kUniform, kNormal };

// Gilbert–Elliott two-state burst-loss chain (parameters in the usual notation).
struct GilbertElliott {
  bool enabled = false;
  double p = 0.0;  // P(good -> bad) per packet
  double r = 1.0;  // P(bad -> good) per packet
  double k = 1.0;  // P(delivered | good): loss in good = 1 - k
  double h = 0.0;  // P(delivered | bad):  loss in bad  = 1 - h
};

// Closed forms of the chain above, for tests and documentation.
// Stationary probability of the bad state: p / (p + r).
double gilbert_elliott_bad_fraction(const GilbertElliott& ge);
// Stationary loss rate: pi_G (1 - k) + pi_B (1 - h).
double gilbert_elliott_loss_rate(const GilbertElliott& ge);

// Scheduled outage, relative to the model's start time.
struct Outage {
  std::int64_t start_ns = 0;
  std::int64_t duration_ns = 0;
};

// Impairment of one direction (up = client->server, down = server->client).
struct DirectionImpairment {
  std::int64_t delay_ns = 0;
  std::int64_t jitter_ns = 0;  // uniform: half-width; normal: standard deviation
  JitterDistribution jitter_distribution = JitterDistribution::kUniform;
  double loss = 0.0;
  GilbertElliott gilbert_elliott;
  double duplicate = 0.0;
  double reorder = 0.0;
  std::int64_t reorder_extra_ns = 0;
  bool keep_order = true;             // monotonic release times when reorder == 0
  double rate_bytes_per_s = 0.0;      // 0: unlimited
  std::int64_t queue_bytes = 0;       // 0: unlimited backlog
  std::vector<Outage> outages;
};

// Empty string when valid, else a clear error naming the field (prefixed by `what`).
std::string validate(const DirectionImpairment& cfg, const std::string& what = "impairment");

enum class Transport { kDatagram, kStream };

struct ImpairmentCounters {
  std::uint64_t received = 0;
  std::uint64_t forwarded = 0;  // copies released, duplicates included
  std::uint64_t dropped_random = 0;
  std::uint64_t dropped_burst = 0;
  std::uint64_t dropped_outage = 0;
  std::uint64_t dropped_rate = 0;
  std::uint64_t duplicated = 0;
  std::uint64_t reordered = 0;  // released before some earlier-arrived packet
  std::uint64_t held_outage = 0;  // stream chunks held back by an outage
  std::uint64_t bytes_received = 0;
  std::uint64_t bytes_forwarded = 0;  // duplicates included

  std::uint64_t dropped() const {
    return dropped_random + dropped_burst + dropped_outage + dropped_rate;
  }
  ImpairmentCounters& operator+=(const ImpairmentCounters& o);
};

enum class DropReason { kNone, kRandom, kBurst, kOutage, kRate };

struct ImpairmentDecision {
  DropReason drop = DropReason::kNone;
  int copies = 0;  // 0 (dropped), 1, or 2 (duplicated)
  std::array<std::int64_t, 2> release_ns{};  // valid for the first `copies` entries
  std::int64_t delay_ns = 0;  // sampled delay+jitter of the first copy (before ordering)
  bool reorder_delayed = false;
};

// Mutable state of one direction; reset with impairment_reset().
struct ImpairmentData {
  std::mt19937_64 rng;
  std::int64_t start_ns = 0;
  bool ge_bad = false;
  std::int64_t link_free_ns = 0;     // when the rate-limited link finishes its backlog
  std::int64_t last_release_ns = 0;  // for monotonic release
  std::int64_t max_release_ns = 0;   // latest release of any earlier packet
  bool any_released = false;
  ImpairmentCounters counters;
};

void impairment_reset(const DirectionImpairment& cfg, ImpairmentData& data, std::uint64_t seed,
                      std::int64_t start_ns);

// Decides the fate of one packet of `size` bytes arriving at `t_ns`. Arrival times must be
// non-decreasing per direction (the forwarders guarantee it).
ImpairmentDecision impairment_decide(const DirectionImpairment& cfg, Transport transport,
                                     ImpairmentData& data, std::int64_t t_ns, std::size_t size);

// Deterministic seed mixing (splitmix64), used to give each direction its own stream.
std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t stream);

}  // namespace hemm::net::relay
