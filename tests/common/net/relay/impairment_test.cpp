// Statistical and exact tests of the simulated impairment model (no sockets, no clocks).
#include "common/net/relay/impairment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace hemm::net::relay {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kStart = 5'000 * kMs;  // arbitrary non-zero model start

struct Trace {
  std::vector<ImpairmentDecision> decisions;
  ImpairmentCounters counters;
};

// n packets of `size` bytes arriving every `spacing_ns` from the model start.
Trace simulate(const DirectionImpairment& cfg, Transport tr, std::uint64_t seed, int n,
        std::int64_t spacing_ns, std::size_t size = 100) {
  EXPECT_EQ(validate(cfg), "");
  ImpairmentData data;
  impairment_reset(cfg, data, seed, kStart);
  Trace r;
  r.decisions.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    r.decisions.push_back(impairment_decide(cfg, tr, data, kStart + i * spacing_ns, size));
  }
  r.counters = data.counters;
  return r;
}

void expect_conservation(const ImpairmentCounters& c) {
  // Every packet is dropped for exactly one reason or forwarded (plus its duplicate).
  EXPECT_EQ(c.received + c.duplicated, c.forwarded + c.dropped());
}

TEST(Impairment, NoImpairmentForwardsEverythingAtArrival) {
  const DirectionImpairment cfg;
  const Trace r = simulate(cfg, Transport::kDatagram, 1, 1000, kMs);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    ASSERT_EQ(r.decisions[i].copies, 1);
    EXPECT_EQ(r.decisions[i].release_ns[0], kStart + static_cast<std::int64_t>(i) * kMs);
  }
  EXPECT_EQ(r.counters.forwarded, 1000u);
  EXPECT_EQ(r.counters.bytes_forwarded, 100'000u);
  EXPECT_EQ(r.counters.reordered, 0u);
}

TEST(Impairment, RandomLossRateWithinThreeSigma) {
  DirectionImpairment cfg;
  cfg.loss = 0.1;
  const int n = 100'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 42, n, kMs);
  const double rate = static_cast<double>(r.counters.dropped_random) / n;
  const double sigma = std::sqrt(0.1 * 0.9 / n);
  EXPECT_NEAR(rate, 0.1, 3 * sigma);
  EXPECT_EQ(r.counters.dropped(), r.counters.dropped_random);
  expect_conservation(r.counters);
  for (const auto& d : r.decisions) {
    EXPECT_EQ(d.copies == 0, d.drop == DropReason::kRandom);
  }
}

// Loss indicator sequence of a run (true = dropped).
std::vector<bool> losses(const Trace& r) {
  std::vector<bool> out;
  for (const auto& d : r.decisions) out.push_back(d.copies == 0);
  return out;
}

TEST(Impairment, GilbertElliottStationaryLossAndMeanBurstMatchClosedForms) {
  // Simple Gilbert model (k = 1, h = 0): loss exactly in the bad state, so the loss rate
  // is p / (p + r) and loss bursts are geometric with mean 1 / r.
  DirectionImpairment cfg;
  cfg.gilbert_elliott = {true, 0.05, 0.3, 1.0, 0.0};
  const int n = 200'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 7, n, kMs);
  const std::vector<bool> lost = losses(r);
  const double pi_b = 0.05 / 0.35;
  EXPECT_DOUBLE_EQ(gilbert_elliott_loss_rate(cfg.gilbert_elliott), pi_b);
  const double rate = static_cast<double>(r.counters.dropped_burst) / n;
  // Markov-correlated samples: variance inflated by (1 + lambda) / (1 - lambda),
  // lambda = 1 - p - r the chain's second eigenvalue.
  const double lambda = 1.0 - 0.05 - 0.3;
  const double sigma_rate = std::sqrt(pi_b * (1 - pi_b) * (1 + lambda) / (1 - lambda) / n);
  EXPECT_NEAR(rate, pi_b, 4 * sigma_rate);

  std::vector<int> bursts;
  int run_len = 0;
  for (bool l : lost) {
    if (l) {
      ++run_len;
    } else if (run_len > 0) {
      bursts.push_back(run_len);
      run_len = 0;
    }
  }
  ASSERT_GT(bursts.size(), 1000u);
  double mean = 0;
  for (int b : bursts) mean += b;
  mean /= static_cast<double>(bursts.size());
  const double sigma_burst = std::sqrt((1 - 0.3) / (0.3 * 0.3) / static_cast<double>(bursts.size()));
  EXPECT_NEAR(mean, 1.0 / 0.3, 4 * sigma_burst);
  EXPECT_EQ(r.counters.dropped(), r.counters.dropped_burst);
}

TEST(Impairment, GilbertElliottGeneralLossRateMatchesClosedForm) {
  DirectionImpairment cfg;
  cfg.gilbert_elliott = {true, 0.02, 0.2, 0.99, 0.3};
  const int n = 400'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 11, n, kMs);
  const double expected = gilbert_elliott_loss_rate(cfg.gilbert_elliott);
  const double pi_b = 0.02 / 0.22;
  EXPECT_NEAR(expected, (1 - pi_b) * 0.01 + pi_b * 0.7, 1e-15);
  const double lambda = 1.0 - 0.02 - 0.2;
  const double sigma =
      std::sqrt(expected * (1 - expected) * (1 + lambda) / (1 - lambda) / n);
  EXPECT_NEAR(static_cast<double>(r.counters.dropped_burst) / n, expected, 4 * sigma);
}

struct Moments {
  double mean = 0, stddev = 0, min = 1e300, max = -1e300;
};
Moments moments(const Trace& r) {
  Moments m;
  double s = 0, s2 = 0;
  for (const auto& d : r.decisions) {
    const double v = static_cast<double>(d.delay_ns);
    s += v;
    s2 += v * v;
    m.min = std::min(m.min, v);
    m.max = std::max(m.max, v);
  }
  const double n = static_cast<double>(r.decisions.size());
  m.mean = s / n;
  m.stddev = std::sqrt(std::max(0.0, s2 / n - m.mean * m.mean));
  return m;
}

TEST(Impairment, UniformJitterMeanStdAndSupport) {
  DirectionImpairment cfg;
  cfg.delay_ns = 50 * kMs;
  cfg.jitter_ns = 10 * kMs;
  cfg.keep_order = false;  // raw samples, no monotonic correction
  const int n = 100'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 3, n, kMs);
  const Moments m = moments(r);
  const double sd = 10.0 * kMs / std::sqrt(3.0);  // U(-j, j)
  EXPECT_NEAR(m.mean, 50.0 * kMs, 4 * sd / std::sqrt(n));
  EXPECT_NEAR(m.stddev, sd, 0.02 * sd);
  EXPECT_GE(m.min, 40.0 * kMs);
  EXPECT_LE(m.max, 60.0 * kMs);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    EXPECT_EQ(r.decisions[i].release_ns[0],
              kStart + static_cast<std::int64_t>(i) * kMs + r.decisions[i].delay_ns);
  }
}

TEST(Impairment, NormalJitterMeanAndStd) {
  DirectionImpairment cfg;
  cfg.delay_ns = 50 * kMs;
  cfg.jitter_ns = 5 * kMs;
  cfg.jitter_distribution = JitterDistribution::kNormal;
  cfg.keep_order = false;
  const int n = 100'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 4, n, kMs);
  const Moments m = moments(r);
  const double sd = 5.0 * kMs;
  EXPECT_NEAR(m.mean, 50.0 * kMs, 4 * sd / std::sqrt(n));
  // std of the sample std of a normal: sd / sqrt(2n).
  EXPECT_NEAR(m.stddev, sd, 5 * sd / std::sqrt(2.0 * n));
  // A normal has ~0.27 % beyond 3 sigma; check the tails are present but not fat.
  int beyond3 = 0;
  for (const auto& d : r.decisions) {
    if (std::abs(static_cast<double>(d.delay_ns) - 50.0 * kMs) > 3 * sd) ++beyond3;
  }
  EXPECT_NEAR(beyond3 / static_cast<double>(n), 0.0027, 0.001);
}

TEST(Impairment, DelayNeverNegativeWhenJitterExceedsDelay) {
  for (auto dist : {JitterDistribution::kUniform, JitterDistribution::kNormal}) {
    DirectionImpairment cfg;
    cfg.delay_ns = 1 * kMs;
    cfg.jitter_ns = 5 * kMs;
    cfg.jitter_distribution = dist;
    cfg.keep_order = false;
    const Trace r = simulate(cfg, Transport::kDatagram, 5, 50'000, kMs);
    int zeroish = 0;
    for (std::size_t i = 0; i < r.decisions.size(); ++i) {
      const auto& d = r.decisions[i];
      ASSERT_GE(d.delay_ns, 0);
      ASSERT_GE(d.release_ns[0], kStart + static_cast<std::int64_t>(i) * kMs);
      if (d.delay_ns < kMs / 2) ++zeroish;
    }
    // Truncation keeps the small delays (the distribution is conditioned, not clamped
    // to the delay): some samples fall below half the fixed delay.
    EXPECT_GT(zeroish, 100);
  }
}

TEST(Impairment, OutageDropsExactlyThePacketsInTheWindow) {
  DirectionImpairment cfg;
  cfg.outages = {{100 * kMs, 50 * kMs}, {400 * kMs, 1 * kMs}};
  const Trace r = simulate(cfg, Transport::kDatagram, 6, 1000, kMs);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    const std::int64_t rel = static_cast<std::int64_t>(i) * kMs;
    const bool in = (rel >= 100 * kMs && rel < 150 * kMs) || rel == 400 * kMs;
    EXPECT_EQ(r.decisions[i].drop == DropReason::kOutage, in) << "packet at " << rel << " ns";
    EXPECT_EQ(r.decisions[i].copies, in ? 0 : 1);
  }
  EXPECT_EQ(r.counters.dropped_outage, 51u);
  expect_conservation(r.counters);
}

TEST(Impairment, DuplicationRateAndIndependentDelay) {
  DirectionImpairment cfg;
  cfg.duplicate = 0.05;
  cfg.delay_ns = 20 * kMs;
  cfg.jitter_ns = 5 * kMs;
  cfg.keep_order = false;
  const int n = 100'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 8, n, kMs);
  EXPECT_NEAR(static_cast<double>(r.counters.duplicated) / n, 0.05, 3 * std::sqrt(0.05 * 0.95 / n));
  EXPECT_EQ(r.counters.forwarded, static_cast<std::uint64_t>(n) + r.counters.duplicated);
  int different = 0;
  for (const auto& d : r.decisions) {
    if (d.copies == 2) {
      different += d.release_ns[0] != d.release_ns[1];
      EXPECT_GE(d.release_ns[1] - (d.release_ns[0] - d.delay_ns), 15 * kMs);
      EXPECT_LE(d.release_ns[1] - (d.release_ns[0] - d.delay_ns), 25 * kMs);
    }
  }
  EXPECT_GT(different, static_cast<int>(r.counters.duplicated) * 9 / 10);
  expect_conservation(r.counters);
}

TEST(Impairment, RateLimitSerialisesAtTheConfiguredRate) {
  DirectionImpairment cfg;
  cfg.rate_bytes_per_s = 125'000;  // 1 Mbit/s: 1000 B take exactly 8 ms
  // Offered 1000 B every 1 ms (8x the rate), unlimited queue: releases 8 ms apart.
  const Trace r = simulate(cfg, Transport::kDatagram, 9, 100, kMs, 1000);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    EXPECT_EQ(r.decisions[i].release_ns[0], kStart + static_cast<std::int64_t>(i + 1) * 8 * kMs);
  }
  EXPECT_EQ(r.counters.dropped_rate, 0u);

  // Bounded queue: throughput over 10 s equals the rate; the excess is dropped.
  cfg.queue_bytes = 10'000;
  const Trace q = simulate(cfg, Transport::kDatagram, 9, 10'000, kMs, 1000);
  std::int64_t last = 0;
  std::uint64_t in_first_10s = 0;
  for (const auto& d : q.decisions) {
    if (d.copies == 0) {
      EXPECT_EQ(d.drop, DropReason::kRate);
      continue;
    }
    EXPECT_GE(d.release_ns[0] - last, 8 * kMs);  // never faster than the link
    last = d.release_ns[0];
    if (d.release_ns[0] <= kStart + 10'000 * kMs) in_first_10s += 1000;
  }
  EXPECT_NEAR(static_cast<double>(in_first_10s) / 10.0, 125'000.0, 125'000.0 * 0.01);
  EXPECT_GT(q.counters.dropped_rate, 8000u);
  expect_conservation(q.counters);
  // Backlog never exceeds the queue: worst release lag = queue / rate + one packet.
  for (std::size_t i = 0; i < q.decisions.size(); ++i) {
    if (q.decisions[i].copies == 0) continue;
    const std::int64_t lag =
        q.decisions[i].release_ns[0] - (kStart + static_cast<std::int64_t>(i) * kMs);
    EXPECT_LE(lag, 80 * kMs + 8 * kMs);
  }

  // Offered below the rate: nothing dropped, each packet only pays its serialisation.
  const Trace slow = simulate(cfg, Transport::kDatagram, 9, 1000, 10 * kMs, 1000);
  EXPECT_EQ(slow.counters.dropped_rate, 0u);
  for (std::size_t i = 0; i < slow.decisions.size(); ++i) {
    EXPECT_EQ(slow.decisions[i].release_ns[0],
              kStart + static_cast<std::int64_t>(i) * 10 * kMs + 8 * kMs);
  }
}

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
  cfg.rate_bytes_per_s = 200'000;
  cfg.queue_bytes = 20'000;
  cfg.outages = {{2'000 * kMs, 300 * kMs}};
  return cfg;
}

bool same(const Trace& a, const Trace& b) {
  if (a.decisions.size() != b.decisions.size()) return false;
  for (std::size_t i = 0; i < a.decisions.size(); ++i) {
    const auto& x = a.decisions[i];
    const auto& y = b.decisions[i];
    if (x.drop != y.drop || x.copies != y.copies) return false;
    for (int c = 0; c < x.copies; ++c) {
      if (x.release_ns[static_cast<std::size_t>(c)] != y.release_ns[static_cast<std::size_t>(c)]) {
        return false;
      }
    }
  }
  return true;
}

TEST(Impairment, SameSeedSameDecisionsDifferentSeedDifferent) {
  const DirectionImpairment cfg = everything();
  const Trace a = simulate(cfg, Transport::kDatagram, 1234, 20'000, kMs, 500);
  const Trace b = simulate(cfg, Transport::kDatagram, 1234, 20'000, kMs, 500);
  const Trace c = simulate(cfg, Transport::kDatagram, 1235, 20'000, kMs, 500);
  EXPECT_TRUE(same(a, b));
  EXPECT_FALSE(same(a, c));
  EXPECT_EQ(a.counters.dropped_random, b.counters.dropped_random);
  EXPECT_NE(a.counters.dropped_random, c.counters.dropped_random);
  expect_conservation(a.counters);
  expect_conservation(c.counters);
  EXPECT_NE(mix_seed(1, 0), mix_seed(1, 1));
  EXPECT_NE(mix_seed(1, 0), mix_seed(2, 0));
}

// Reference count of "released before an earlier-arrived packet".
std::uint64_t count_overtakers(const Trace& r) {
  std::uint64_t n = 0;
  bool any = false;
  std::int64_t max_rel = 0;
  for (const auto& d : r.decisions) {
    if (d.copies == 0) continue;
    if (any && d.release_ns[0] < max_rel) ++n;
    for (int c = 0; c < d.copies; ++c) {
      max_rel = any ? std::max(max_rel, d.release_ns[static_cast<std::size_t>(c)])
                    : d.release_ns[static_cast<std::size_t>(c)];
      any = true;
    }
  }
  return n;
}

TEST(Impairment, JitterKeepsOrderUnlessAllowed) {
  DirectionImpairment cfg;
  cfg.delay_ns = 20 * kMs;
  cfg.jitter_ns = 10 * kMs;  // >> 1 ms spacing: raw jitter would reorder a lot
  const Trace kept = simulate(cfg, Transport::kDatagram, 10, 10'000, kMs);
  for (std::size_t i = 1; i < kept.decisions.size(); ++i) {
    ASSERT_GE(kept.decisions[i].release_ns[0], kept.decisions[i - 1].release_ns[0]);
  }
  EXPECT_EQ(kept.counters.reordered, 0u);

  cfg.keep_order = false;
  const Trace free = simulate(cfg, Transport::kDatagram, 10, 10'000, kMs);
  EXPECT_GT(free.counters.reordered, 1000u);
  EXPECT_EQ(free.counters.reordered, count_overtakers(free));
}

TEST(Impairment, ReorderDelaysAFractionSoLaterPacketsOvertake) {
  DirectionImpairment cfg;
  cfg.delay_ns = 10 * kMs;
  cfg.reorder = 0.05;
  cfg.reorder_extra_ns = 10 * kMs;
  const int n = 100'000;
  const Trace r = simulate(cfg, Transport::kDatagram, 12, n, kMs);
  int delayed = 0;
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    const auto& d = r.decisions[i];
    delayed += d.reorder_delayed;
    const std::int64_t base = kStart + static_cast<std::int64_t>(i) * kMs + 10 * kMs;
    EXPECT_EQ(d.release_ns[0], base + (d.reorder_delayed ? 10 * kMs : 0));
  }
  EXPECT_NEAR(delayed / static_cast<double>(n), 0.05, 3 * std::sqrt(0.05 * 0.95 / n));
  EXPECT_EQ(r.counters.reordered, count_overtakers(r));
  // Each held packet is overtaken by the (up to 9) packets after it.
  EXPECT_GT(r.counters.reordered, static_cast<std::uint64_t>(delayed) * 5);
}

TEST(Impairment, StreamNeverDropsDuplicatesOrReorders) {
  DirectionImpairment cfg = everything();
  cfg.loss = 1.0;  // would drop every datagram
  cfg.outages.clear();
  const int n = 20'000;
  const Trace r = simulate(cfg, Transport::kStream, 13, n, kMs, 100);
  EXPECT_EQ(r.counters.forwarded, static_cast<std::uint64_t>(n));
  EXPECT_EQ(r.counters.dropped(), 0u);
  EXPECT_EQ(r.counters.duplicated, 0u);
  EXPECT_EQ(r.counters.reordered, 0u);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    ASSERT_EQ(r.decisions[i].copies, 1);
    ASSERT_GE(r.decisions[i].release_ns[0], kStart + static_cast<std::int64_t>(i) * kMs);
    if (i > 0) {
      ASSERT_GE(r.decisions[i].release_ns[0], r.decisions[i - 1].release_ns[0]);
    }
  }
}

TEST(Impairment, StreamOutageHoldsBytesUntilItEnds) {
  DirectionImpairment cfg;
  cfg.delay_ns = 5 * kMs;
  cfg.outages = {{100 * kMs, 50 * kMs}, {150 * kMs, 20 * kMs}};  // chained: [100, 170)
  const Trace r = simulate(cfg, Transport::kStream, 14, 300, kMs);
  for (std::size_t i = 0; i < r.decisions.size(); ++i) {
    const std::int64_t rel = static_cast<std::int64_t>(i) * kMs;
    const bool held = rel >= 100 * kMs && rel < 170 * kMs;
    const std::int64_t expect = kStart + (held ? 170 * kMs : rel) + 5 * kMs;
    EXPECT_EQ(r.decisions[i].release_ns[0], expect) << "chunk at " << rel;
  }
  EXPECT_EQ(r.counters.held_outage, 70u);
  EXPECT_EQ(r.counters.dropped_outage, 0u);
}

TEST(Impairment, ExtremeSettingsNeverOverflowTime) {
  // A 1 B/s link flooded with 64 kB packets and maximal delays: release times saturate
  // far in the future instead of overflowing (UBSan would flag signed overflow).
  DirectionImpairment cfg;
  cfg.rate_bytes_per_s = 1.0;
  cfg.delay_ns = std::int64_t{1} << 60;
  cfg.jitter_ns = std::int64_t{1} << 60;
  cfg.jitter_distribution = JitterDistribution::kNormal;
  cfg.reorder = 0.5;
  cfg.reorder_extra_ns = std::int64_t{1} << 60;
  cfg.duplicate = 0.5;
  for (Transport tr : {Transport::kDatagram, Transport::kStream}) {
    const Trace r = simulate(cfg, tr, 15, 200'000, 1, 65'535);
    for (std::size_t i = 0; i < r.decisions.size(); ++i) {
      const auto& d = r.decisions[i];
      for (int c = 0; c < d.copies; ++c) {
        const std::int64_t rel = d.release_ns[static_cast<std::size_t>(c)];
        ASSERT_GE(rel, kStart + static_cast<std::int64_t>(i));
        ASSERT_LE(rel, std::int64_t{1} << 62);
      }
    }
  }
}

TEST(Impairment, ValidationRejectsBadValuesWithClearText) {
  EXPECT_EQ(validate(DirectionImpairment{}), "");
  EXPECT_EQ(validate(everything()), "");
  auto expect_error = [](DirectionImpairment cfg, const char* field) {
    const std::string err = validate(cfg, "up");
    EXPECT_NE(err.find(field), std::string::npos) << err;
    EXPECT_EQ(err.rfind("up: ", 0), 0u) << err;
  };
  DirectionImpairment c;
  c.loss = 1.5;
  expect_error(c, "loss");
  c = {};
  c.loss = std::nan("");
  expect_error(c, "loss");
  c = {};
  c.delay_ns = -1;
  expect_error(c, "delay");
  c = {};
  c.jitter_ns = -5;
  expect_error(c, "jitter");
  c = {};
  c.duplicate = -0.1;
  expect_error(c, "duplicate");
  c = {};
  c.reorder = 2;
  expect_error(c, "reorder");
  c = {};
  c.gilbert_elliott = {true, 0.1, 1.1, 1, 0};
  expect_error(c, "Gilbert-Elliott r");
  c = {};
  c.rate_bytes_per_s = -1;
  expect_error(c, "rate");
  c = {};
  c.rate_bytes_per_s = 0.5;  // below 1 B/s
  expect_error(c, "rate");
  c = {};
  c.rate_bytes_per_s = INFINITY;
  expect_error(c, "rate");
  c = {};
  c.queue_bytes = -1;
  expect_error(c, "queue");
  c = {};
  c.outages = {{-1, 5}};
  expect_error(c, "outage 0");
  c = {};
  c.outages = {{0, 5}, {10, -5}};
  expect_error(c, "outage 1");
}

}  // namespace
}  // namespace hemm::net::relay
