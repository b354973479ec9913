#include "operator/view/view_feed.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hemm::op {

void ViewFeed::on_snapshot(const OperatorModelSnapshot& s) {
  std::unique_lock<std::mutex> lk(mu_, std::try_to_lock);
  if (!lk.owns_lock()) {
    busy_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  slot_.version = s.version;
  slot_.stamp_ns = s.stamp_ns;
  slot_.have_state = s.have_state;
  slot_.T_W_R = s.T_W_R;
  slot_.state = s.state;
  const std::size_t n = std::min(s.map.segments.size(), max_segments_);
  slot_.segments.assign(s.map.segments.begin(), s.map.segments.begin() + static_cast<std::ptrdiff_t>(n));
  slot_.pieces_total = s.map.segments.size();
  slot_.map_segments = s.segments;
  slot_.voxmap = s.voxmap;  // shared, not copied: the view only reads it
  slot_.voxmap_builds = s.voxmap_builds;
  fresh_ = true;
  copies_.fetch_add(1, std::memory_order_relaxed);
}

bool ViewFeed::take_model(ViewModel& out) {
  std::lock_guard<std::mutex> lk(mu_);
  if (!fresh_) return false;
  std::swap(out, slot_);
  fresh_ = false;
  return true;
}

void update_voxmap_cubes(ViewModel& model, std::size_t budget) {
  if (!model.voxmap) {
    model.voxmap_cubes = VoxmapCubes{};
    model.voxmap_cubes_of = 0;
    return;
  }
  if (model.voxmap_cubes_of == model.voxmap_builds && !model.voxmap_cubes.centres.empty()) return;
  model.voxmap_cubes = surface_cubes(*model.voxmap, budget);
  model.voxmap_cubes_of = model.voxmap_builds;
}

namespace {
// The q-quantile of a histogram given as per-bin counts (bin i = [i, i+1) us),
// as the bin's centre in ms.
// The centre of the bin holding the q-quantile of a window's counts, in ms
// (the overflow bin: its lower edge).
double quantile_ms(const std::vector<std::uint64_t>& bins, std::uint64_t total, double q) {
  using H = servo::LatencyHistogram;
  if (total == 0) return 0.0;
  const auto target = static_cast<std::uint64_t>(q * static_cast<double>(total - 1)) + 1;
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    seen += bins[i];
    const int b = static_cast<int>(i);
    if (seen >= target) return (b == H::kBins - 1 ? H::lower_ns(b) : 0.5 * (H::lower_ns(b) + H::upper_ns(b))) * 1e-6;
  }
  return H::lower_ns(H::kBins - 1) * 1e-6;
}
}  // namespace

ServoHealth ServoHealthMeter::update(const servo::TimingStats& t, std::int64_t now_ns) {
  constexpr int kBins = servo::LatencyHistogram::kBins;
  if (prev_bins_.empty()) prev_bins_.assign(kBins, 0);
  ServoHealth h;
  h.ticks = t.ticks.load(std::memory_order_relaxed);
  h.misses = t.misses.load(std::memory_order_relaxed);
  std::vector<std::uint64_t> delta(kBins);
  std::uint64_t total = 0;
  for (int i = 0; i < kBins; ++i) {
    const std::uint64_t b = t.period.bin(i);
    delta[i] = b >= prev_bins_[i] ? b - prev_bins_[i] : 0;
    prev_bins_[i] = b;
    total += delta[i];
  }
  h.period_median_ms = quantile_ms(delta, total, 0.5);
  h.period_p99_ms = quantile_ms(delta, total, 0.99);
  h.compute_median_us = t.compute.quantile_ns(0.5) * 1e-3;
  h.compute_p99_us = t.compute.quantile_ns(0.99) * 1e-3;
  h.compute_max_us = static_cast<double>(t.compute.max_ns()) * 1e-3;
  h.wake_p99_us = t.wake_latency.quantile_ns(0.99) * 1e-3;
  h.wake_max_us = static_cast<double>(t.wake_latency.max_ns()) * 1e-3;
  h.histogram = servo_histogram_plot(t);
  h.window_ticks = h.ticks - std::min(h.ticks, prev_ticks_);
  h.window_misses = h.misses - std::min(h.misses, prev_misses_);
  h.window_s = prev_ns_ != 0 ? static_cast<double>(now_ns - prev_ns_) * 1e-9 : 0.0;
  prev_ticks_ = h.ticks;
  prev_misses_ = h.misses;
  prev_ns_ = now_ns;
  return h;
}

view::OverlayPlot servo_histogram_plot(const servo::TimingStats& t) {
  using H = servo::LatencyHistogram;
  view::OverlayPlot p;
  p.title = "servo: log10(1+ticks)";
  p.xlabel = "log10 us (3: 1 ms)";
  p.x_min = 0.0f;  // 1 us .. 10 ms
  p.x_max = 4.0f;
  struct Curve {
    const H* h;
    const char* name;
    view::Rgba colour;
  };
  const Curve curves[3] = {{&t.compute, "compute", {0.3f, 0.6f, 1.0f, 1.0f}},
                           {&t.wake_latency, "wake", {1.0f, 0.4f, 0.3f, 1.0f}},
                           {&t.period, "period", {0.4f, 0.9f, 0.4f, 1.0f}}};
  for (const Curve& c : curves) {
    int first = -1, last = -1;
    for (int i = 0; i < H::kBins; ++i) {
      if (c.h->bin(i) == 0) continue;
      if (first < 0) first = i;
      last = i;
    }
    view::PlotLine l;
    l.name = c.name;
    l.colour = c.colour;
    for (int i = first; first >= 0 && i <= last; ++i) {
      const double centre_us = i == H::kBins - 1 ? H::lower_ns(i) * 1e-3 : 0.5e-3 * (H::lower_ns(i) + H::upper_ns(i));
      l.x.push_back(static_cast<float>(std::log10(centre_us)));
      l.y.push_back(static_cast<float>(std::log10(1.0 + static_cast<double>(c.h->bin(i)))));
    }
    p.lines.push_back(std::move(l));
  }
  return p;
}

std::string servo_figures_text(const ServoHealth& h) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "compute median %.1f  p99 %.1f  max %.0f us   wake p99 %.1f  max %.0f us",
                h.compute_median_us, h.compute_p99_us, h.compute_max_us, h.wake_p99_us, h.wake_max_us);
  return buf;
}

}  // namespace hemm::op
