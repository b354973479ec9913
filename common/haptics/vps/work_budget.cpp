#include "common/haptics/vps/work_budget.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"

namespace hemm::vps {

void update_work_rate(const WorkRateParams& p, std::int64_t elapsed_ns, std::int64_t work, WorkRate* r) noexcept {
  if (work < 1 || elapsed_ns < 0) return;
  double x = static_cast<double>(elapsed_ns) / static_cast<double>(work);
  if (r->samples == 0) {  // nothing measured yet: this is the mean, half of it the spread
    r->mean_ns = x;
    r->deviation_ns = 0.5 * x;
    r->samples = 1;
    return;
  }
  x = std::min(x, p.outlier * r->mean_ns);
  const double err = x - r->mean_ns;
  r->mean_ns += p.mean_gain * err;
  r->deviation_ns += p.deviation_gain * (std::abs(err) - r->deviation_ns);
  ++r->samples;
}

std::vector<Eigen::Isometry3d> surface_poses(const Voxmap& vm, const PointShell& ps, int count, std::uint32_t seed) {
  std::vector<Eigen::Vector3d> surface;
  const Eigen::Vector3i bd = vm.block_dims;
  for (int bz = 0; bz < bd.z(); ++bz)
    for (int by = 0; by < bd.y(); ++by)
      for (int bx = 0; bx < bd.x(); ++bx) {
        const std::int32_t bi = vm.top[block_linear(vm, Eigen::Vector3i(bx, by, bz))];
        if (bi < 0) continue;
        const VoxelBlock& b = vm.blocks[static_cast<std::size_t>(bi)];
        for (int i = 0; i < kBlockVoxels; ++i) {
          if (b.v[static_cast<std::size_t>(i)].layer != 0) continue;
          const Eigen::Vector3i v(bx * kBlockDim + (i & (kBlockDim - 1)),
                                  by * kBlockDim + ((i >> kBlockShift) & (kBlockDim - 1)),
                                  bz * kBlockDim + (i >> (2 * kBlockShift)));
          surface.push_back(voxel_centre(vm, v));
        }
      }
  std::vector<Eigen::Isometry3d> out;
  if (surface.empty() || count < 1) return out;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double stride = static_cast<double>(surface.size()) / count;
  for (int k = 0; k < count; ++k) {
    const auto at = static_cast<std::size_t>(std::min<double>(std::floor((k + u(rng)) * stride),
                                                              static_cast<double>(surface.size() - 1)));
    // A uniformly random rotation (Shoemake's subgroup algorithm).
    const double u1 = u(rng), u2 = 2 * std::numbers::pi * u(rng), u3 = 2 * std::numbers::pi * u(rng);
    const Eigen::Quaterniond q(std::sqrt(u1) * std::cos(u3), std::sqrt(1 - u1) * std::sin(u2),
                               std::sqrt(1 - u1) * std::cos(u2), std::sqrt(u1) * std::sin(u3));
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.normalized().toRotationMatrix();
    T.translation() = surface[at] - T.linear() * ps.reference_point;
    out.push_back(T);
  }
  return out;
}

WorkRateCalibration calibrate_work_rate(const std::vector<CalibrationPair>& pairs, const ContactParams& params,
                                        const WorkRateParams& rp, int poses_per_pair, std::int64_t (*now_ns)()) {
  std::vector<double> ratio;
  std::vector<std::int64_t> works;
  for (const CalibrationPair& cp : pairs) {
    if (cp.voxmap == nullptr || cp.shell == nullptr || cp.shell->nodes.empty()) continue;
    const std::vector<Eigen::Isometry3d> poses = surface_poses(*cp.voxmap, *cp.shell, poses_per_pair);
    PairState state;
    init_pair_state(*cp.shell, &state);
    PairResult r;
    for (int pass = 0; pass < 2; ++pass) {  // the first warms the caches and is not timed
      for (const Eigen::Isometry3d& T : poses) {
        reset_pair_state(&state);  // each pose on its own, as a first touch
        const std::int64_t t0 = now_ns();
        // A finite budget: the per-level evaluation the time-critical mode runs.
        evaluate_pair_budgeted(*cp.voxmap, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), *cp.shell, T,
                               params, kUnlimitedWork - 1, &state, &r);
        const std::int64_t dt = now_ns() - t0;
        const std::int64_t work = static_cast<std::int64_t>(r.nodes_visited) + r.points_tested;
        if (pass == 0 || work < std::max<std::int64_t>(rp.min_work, 1)) continue;
        ratio.push_back(static_cast<double>(dt) / static_cast<double>(work));
        works.push_back(work);
      }
    }
  }
  WorkRateCalibration c;
  c.samples = static_cast<int>(ratio.size());
  if (ratio.empty()) return c;
  std::vector<double> sorted = ratio;
  std::sort(sorted.begin(), sorted.end());
  c.median_ns_per_unit = sorted[sorted.size() / 2];
  c.p90_ns_per_unit = sorted[std::min(sorted.size() - 1, sorted.size() * 9 / 10)];
  std::sort(works.begin(), works.end());
  c.median_work = works[works.size() / 2];
  // From the median (robust to a preempted call), with the mean deviation
  // from it (each capped at the outlier bound) as the spread.
  double dev = 0.0;
  for (double x : ratio) dev += std::abs(std::min(x, rp.outlier * c.median_ns_per_unit) - c.median_ns_per_unit);
  c.rate.mean_ns = c.median_ns_per_unit;
  c.rate.deviation_ns = dev / static_cast<double>(ratio.size());
  c.rate.samples = ratio.size();
  return c;
}

std::string validate(const TimeBudgetParams& p) {
  if (p.tick_ns < 0 || p.tick_ns > 100'000'000) return "tick budget must be in [0, 100 ms]";
  if (p.margin_ns < 0 || p.margin_ns > 100'000'000) return "tick margin must be in [0, 100 ms]";
  if (p.max_work < 1) return "work budget must be >= 1";
  const WorkRateParams& r = p.rate;
  if (!(r.mean_gain > 0 && r.mean_gain <= 1) || !(r.deviation_gain > 0 && r.deviation_gain <= 1))
    return "work rate gains must be in (0, 1]";
  if (!(r.deviations >= 0 && r.deviations <= 100) || !(r.outlier >= 1 && r.outlier <= 1e6) || r.min_work < 1)
    return "work rate: deviations in [0, 100], outlier in [1, 1e6], min_work >= 1";
  return {};
}

TickWorkBudget::TickWorkBudget(const TimeBudgetParams& p, const WorkRate& calibrated) : p_(p), rate_(calibrated) {
  const double c = budgeted_ns_per_unit(p_.rate, rate_);
  stats_.calibrated_ns_per_unit = stats_.ns_per_unit = stats_.min_ns_per_unit = stats_.max_ns_per_unit = c;
  stats_.mean_ns_per_unit = rate_.mean_ns;
  stats_.min_work_budget = p_.max_work;
}

std::int64_t TickWorkBudget::begin(std::int64_t now_ns, std::int64_t deadline_ns) noexcept {
  begin_ns_ = now_ns;
  given_ns_ = 0;
  std::int64_t units = p_.max_work;
  if (timed()) {
    std::int64_t left = p_.tick_ns;
    if (deadline_ns > 0) left = std::min(left, deadline_ns - now_ns - p_.margin_ns);
    given_ns_ = std::max(left, p_.tick_ns / 8);
    const double c = budgeted_ns_per_unit(p_.rate, rate_);
    const double u = static_cast<double>(given_ns_) / std::max(c, 1e-3);
    units = u >= static_cast<double>(p_.max_work) ? p_.max_work : std::max<std::int64_t>(1, static_cast<std::int64_t>(u));
  }
  stats_.min_work_budget = std::min(stats_.min_work_budget, units);
  return units;
}

void TickWorkBudget::end(std::int64_t now_ns, std::int64_t work, int levels_completed, bool complete) noexcept {
  const std::int64_t elapsed = now_ns - begin_ns_;
  ++stats_.ticks;
  if (!complete) ++stats_.stopped_early;
  if (given_ns_ > 0 && elapsed > given_ns_) ++stats_.over_time;
  ++stats_.levels[static_cast<std::size_t>(std::clamp(levels_completed, 0, kMaxShellLevels))];
  // The estimate learns from the ticks the budget bound (stopped early): a
  // run of light ticks (free space: culled nodes, cheap units) must not talk
  // it down before the next contact, whose units cost more. Without a time
  // budget every tick counts (the report says what a unit costs).
  if (timed() ? complete : work < p_.rate.min_work) return;
  update_work_rate(p_.rate, elapsed, work, &rate_);
  if (rate_.samples == 0) return;
  const double c = budgeted_ns_per_unit(p_.rate, rate_);
  stats_.ns_per_unit = c;
  stats_.mean_ns_per_unit = rate_.mean_ns;
  stats_.min_ns_per_unit = stats_.min_ns_per_unit > 0 ? std::min(stats_.min_ns_per_unit, c) : c;
  stats_.max_ns_per_unit = std::max(stats_.max_ns_per_unit, c);
}

WorkRateCalibration calibrate_work_rate_on_box(const Eigen::Vector3d& half, double voxel_size, int layers,
                                               const PointShell& shell, const ContactParams& params,
                                               const WorkRateParams& rp, int poses, std::int64_t (*now_ns)()) {
  VoxmapParams vp;
  vp.voxel_size = voxel_size;
  vp.layers_in = vp.layers_out = layers;
  Voxmap box;
  if (auto e = build_voxmap(mesh::make_box(half, 4), vp, &box, nullptr))
    throw std::invalid_argument("calibration voxmap: " + e->message);
  return calibrate_work_rate({{&box, &shell}}, params, rp, poses, now_ns);
}

}  // namespace hemm::vps
