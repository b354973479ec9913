#include "common/net/relay/impairment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace hemm::net::relay {
namespace {

// Own conversions (not std::*_distribution) so decisions are identical across standard
// libraries: 53 random bits -> [0, 1).
double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
}

bool bernoulli(std::mt19937_64& rng, double prob) {
  if (prob <= 0.0) return false;
  if (prob >= 1.0) return true;
  return uniform01(rng) < prob;
}

// Box–Muller, one variate per call (keeps the stream simple to reason about).
double standard_normal(std::mt19937_64& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0, 1]
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

// Times are clamped here so that sums of a few of them never overflow int64, whatever
// the configuration or traffic (e.g. a 1 B/s link flooded forever).
constexpr std::int64_t kFarFuture = std::int64_t{1} << 61;

std::int64_t to_ns(double v) {
  if (!(v > 0.0)) return 0;
  if (v >= static_cast<double>(kFarFuture)) return kFarFuture;
  return static_cast<std::int64_t>(std::llround(v));
}

std::int64_t clamp_time(std::int64_t v) { return std::min(v, kFarFuture); }

// Delay + jitter, truncated at zero (truncation = conditioning on delay >= 0).
std::int64_t sample_delay(const DirectionImpairment& cfg, std::mt19937_64& rng) {
  if (cfg.jitter_ns <= 0) return cfg.delay_ns;
  const double d = static_cast<double>(cfg.delay_ns);
  const double j = static_cast<double>(cfg.jitter_ns);
  if (cfg.jitter_distribution == JitterDistribution::kUniform) {
    // Uniform on [max(-d, -j), j] is the truncated uniform.
    const double lo = std::max(-d, -j);
    return to_ns(d + lo + (j - lo) * uniform01(rng));
  }
  // Rejection sampling of the truncated normal; after many tries (delay << jitter,
  // essentially impossible for sane settings) fall back to a zero delay.
  for (int i = 0; i < 64; ++i) {
    const double v = d + j * standard_normal(rng);
    if (v >= 0.0) return to_ns(v);
  }
  return 0;
}

bool in_outage(const DirectionImpairment& cfg, std::int64_t rel_ns) {
  for (const Outage& o : cfg.outages) {
    if (rel_ns >= o.start_ns && rel_ns - o.start_ns < o.duration_ns) return true;
  }
  return false;
}

// End of the (possibly chained) outage covering rel_ns, or rel_ns if none.
std::int64_t outage_end(const DirectionImpairment& cfg, std::int64_t rel_ns) {
  bool moved = true;
  // Each pass moves past at least one outage; bounded by their number.
  for (std::size_t pass = 0; moved && pass <= cfg.outages.size(); ++pass) {
    moved = false;
    for (const Outage& o : cfg.outages) {
      if (rel_ns >= o.start_ns && rel_ns - o.start_ns < o.duration_ns) {
        rel_ns = o.start_ns + o.duration_ns;
        moved = true;
      }
    }
  }
  return rel_ns;
}

bool is_probability(double v) { return v >= 0.0 && v <= 1.0; }  // false for NaN

}  // namespace

double gilbert_elliott_bad_fraction(const GilbertElliott& ge) {
  const double s = ge.p + ge.r;
  return s > 0.0 ? ge.p / s : 0.0;
}

double gilbert_elliott_loss_rate(const GilbertElliott& ge) {
  const double pb = gilbert_elliott_bad_fraction(ge);
  return (1.0 - pb) * (1.0 - ge.k) + pb * (1.0 - ge.h);
}

std::string validate(const DirectionImpairment& cfg, const std::string& what) {
  std::ostringstream err;
  auto prob = [&](const char* name, double v) {
    if (!is_probability(v) && err.tellp() == 0) {
      err << what << ": " << name << " must be a probability in [0, 1], got " << v;
    }
  };
  auto nonneg = [&](const char* name, std::int64_t v) {
    if (v < 0 && err.tellp() == 0) err << what << ": " << name << " must be >= 0, got " << v;
  };
  nonneg("delay", cfg.delay_ns);
  nonneg("jitter", cfg.jitter_ns);
  prob("loss", cfg.loss);
  prob("duplicate", cfg.duplicate);
  prob("reorder", cfg.reorder);
  nonneg("reorder extra delay", cfg.reorder_extra_ns);
  if (cfg.gilbert_elliott.enabled) {
    prob("Gilbert-Elliott p", cfg.gilbert_elliott.p);
    prob("Gilbert-Elliott r", cfg.gilbert_elliott.r);
    prob("Gilbert-Elliott k", cfg.gilbert_elliott.k);
    prob("Gilbert-Elliott h", cfg.gilbert_elliott.h);
  }
  if (err.tellp() == 0 && !(std::isfinite(cfg.rate_bytes_per_s) &&
                            (cfg.rate_bytes_per_s == 0.0 || cfg.rate_bytes_per_s >= 1.0))) {
    err << what << ": rate must be 0 (unlimited) or a finite value >= 1 byte/s, got "
        << cfg.rate_bytes_per_s;
  }
  nonneg("queue bytes", cfg.queue_bytes);
  // Keep every sum of times far from int64 overflow (~292 years).
  constexpr std::int64_t kMaxTime = std::int64_t{1} << 60;
  if (err.tellp() == 0 &&
      (cfg.delay_ns > kMaxTime || cfg.jitter_ns > kMaxTime || cfg.reorder_extra_ns > kMaxTime)) {
    err << what << ": delay, jitter and reorder extra delay must be below 2^60 ns";
  }
  for (std::size_t i = 0; i < cfg.outages.size() && err.tellp() == 0; ++i) {
    const Outage& o = cfg.outages[i];
    if (o.start_ns < 0 || o.duration_ns < 0 || o.start_ns > kMaxTime || o.duration_ns > kMaxTime) {
      err << what << ": outage " << i << " must have 0 <= start, duration < 2^60 ns (got start "
          << o.start_ns << ", duration " << o.duration_ns << ")";
    }
  }
  return err.str();
}

ImpairmentCounters& ImpairmentCounters::operator+=(const ImpairmentCounters& o) {
  received += o.received;
  forwarded += o.forwarded;
  dropped_random += o.dropped_random;
  dropped_burst += o.dropped_burst;
  dropped_outage += o.dropped_outage;
  dropped_rate += o.dropped_rate;
  duplicated += o.duplicated;
  reordered += o.reordered;
  held_outage += o.held_outage;
  bytes_received += o.bytes_received;
  bytes_forwarded += o.bytes_forwarded;
  return *this;
}

std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t stream) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

void impairment_reset(const DirectionImpairment& /*cfg*/, ImpairmentData& data, std::uint64_t seed,
                      std::int64_t start_ns) {
  data = ImpairmentData{};
  data.rng.seed(seed);
  data.start_ns = start_ns;
  data.link_free_ns = start_ns;
  data.last_release_ns = start_ns;
  data.max_release_ns = start_ns;
}

ImpairmentDecision impairment_decide(const DirectionImpairment& cfg, Transport transport,
                                     ImpairmentData& data, std::int64_t t_ns, std::size_t size) {
  ImpairmentDecision out;
  ImpairmentCounters& c = data.counters;
  c.received += 1;
  c.bytes_received += size;
  const bool datagram = transport == Transport::kDatagram;
  const std::int64_t rel = t_ns - data.start_ns;

  std::int64_t ready_ns = t_ns;  // when the packet may enter the link
  if (datagram) {
    if (in_outage(cfg, rel)) {
      out.drop = DropReason::kOutage;
      c.dropped_outage += 1;
      return out;
    }
    if (cfg.gilbert_elliott.enabled) {
      const GilbertElliott& ge = cfg.gilbert_elliott;
      const bool lost = bernoulli(data.rng, data.ge_bad ? 1.0 - ge.h : 1.0 - ge.k);
      data.ge_bad = data.ge_bad ? !bernoulli(data.rng, ge.r) : bernoulli(data.rng, ge.p);
      if (lost) {
        out.drop = DropReason::kBurst;
        c.dropped_burst += 1;
        return out;
      }
    }
    if (bernoulli(data.rng, cfg.loss)) {
      out.drop = DropReason::kRandom;
      c.dropped_random += 1;
      return out;
    }
  } else {
    const std::int64_t end = outage_end(cfg, rel);
    if (end != rel) {
      c.held_outage += 1;
      ready_ns = data.start_ns + end;
    }
  }

  // Rate limit: a serialising bottleneck; its backlog is what is still to be sent.
  std::int64_t sent_ns = ready_ns;
  if (cfg.rate_bytes_per_s > 0.0) {
    const double ns_per_byte = 1e9 / cfg.rate_bytes_per_s;
    if (datagram && cfg.queue_bytes > 0 && data.link_free_ns > ready_ns) {
      const double backlog =
          static_cast<double>(data.link_free_ns - ready_ns) / ns_per_byte;
      if (backlog + static_cast<double>(size) > static_cast<double>(cfg.queue_bytes)) {
        out.drop = DropReason::kRate;
        c.dropped_rate += 1;
        return out;
      }
    }
    const std::int64_t start = std::max(ready_ns, data.link_free_ns);
    sent_ns = clamp_time(start + to_ns(static_cast<double>(size) * ns_per_byte));
    data.link_free_ns = sent_ns;
  }

  const std::int64_t d = sample_delay(cfg, data.rng);
  out.delay_ns = d;
  std::int64_t release = clamp_time(sent_ns + d);
  const bool reorder_on = datagram && cfg.reorder > 0.0;
  if (reorder_on && bernoulli(data.rng, cfg.reorder)) {
    release = clamp_time(release + cfg.reorder_extra_ns);
    out.reorder_delayed = true;
  }
  const bool monotonic = !datagram || (!reorder_on && cfg.keep_order);
  if (monotonic) release = std::max(release, data.last_release_ns);

  out.copies = 1;
  out.release_ns[0] = release;
  if (datagram && bernoulli(data.rng, cfg.duplicate)) {
    std::int64_t dup = clamp_time(sent_ns + sample_delay(cfg, data.rng));
    if (monotonic) dup = std::max(dup, release);
    out.release_ns[1] = dup;
    out.copies = 2;
    c.duplicated += 1;
  }

  if (data.any_released && release < data.max_release_ns) c.reordered += 1;
  for (int i = 0; i < out.copies; ++i) {
    data.max_release_ns = data.any_released ? std::max(data.max_release_ns, out.release_ns[i])
                                            : out.release_ns[i];
    data.any_released = true;
    data.last_release_ns = std::max(data.last_release_ns, out.release_ns[i]);
  }
  c.forwarded += static_cast<std::uint64_t>(out.copies);
  c.bytes_forwarded += static_cast<std::uint64_t>(out.copies) * size;
  return out;
}

}  // namespace hemm::net::relay
