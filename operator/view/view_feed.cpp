#include "operator/view/view_feed.h"

#include <algorithm>

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
double quantile_ms(const std::vector<std::uint64_t>& bins, std::uint64_t total, double q) {
  if (total == 0) return 0.0;
  const auto target = static_cast<std::uint64_t>(q * static_cast<double>(total - 1)) + 1;
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    seen += bins[i];
    if (seen >= target) return (static_cast<double>(i) + 0.5) * 1e-3;
  }
  return static_cast<double>(bins.size()) * 1e-3;
}
}  // namespace

ServoHealth ServoHealthMeter::update(const servo::TimingStats& t, std::int64_t now_ns) {
  constexpr int kBins = servo::LatencyHistogram::kBins + 1;
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
  h.window_ticks = h.ticks - std::min(h.ticks, prev_ticks_);
  h.window_misses = h.misses - std::min(h.misses, prev_misses_);
  h.window_s = prev_ns_ != 0 ? static_cast<double>(now_ns - prev_ns_) * 1e-9 : 0.0;
  prev_ticks_ = h.ticks;
  prev_misses_ = h.misses;
  prev_ns_ = now_ns;
  return h;
}

}  // namespace hemm::op
