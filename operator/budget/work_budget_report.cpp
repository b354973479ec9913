#include "operator/budget/work_budget_report.h"

#include <iomanip>
#include <sstream>

#include "report.pb.h"

namespace hemm::op {

namespace {
double share(std::uint64_t part, std::uint64_t whole) {
  return whole > 0 ? static_cast<double>(part) / static_cast<double>(whole) : 0.0;
}
}  // namespace

std::string to_string(const WorkBudgetSummary& s) {
  const vps::WorkBudgetStats& st = s.stats;
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  if (s.params.tick_ns > 0)
    o << "time budget " << static_cast<double>(s.params.tick_ns) * 1e-3 << " us/tick";
  else
    o << "no time budget";
  if (s.params.max_work != vps::kUnlimitedWork) o << ", work cap " << s.params.max_work << " units";
  o << ": " << st.stopped_early << " of " << st.ticks << " ticks stopped early (" << 100.0 * share(st.stopped_early, st.ticks)
    << " %), " << st.over_time << " over their time; levels completed";
  for (std::size_t l = 0; l < st.levels.size(); ++l)
    if (st.levels[l] > 0) o << " " << l << ":" << st.levels[l];
  o << "; budgeted ns/unit " << std::setprecision(2) << st.calibrated_ns_per_unit << " at start (calibration median "
    << s.calibration.median_ns_per_unit << ", p90 " << s.calibration.p90_ns_per_unit << " over "
    << s.calibration.samples << " evaluations), " << st.ns_per_unit << " at the end (" << st.min_ns_per_unit << "-"
    << st.max_ns_per_unit << "; mean cost " << st.mean_ns_per_unit << ")";
  if (s.params.tick_ns > 0) o << "; smallest budget " << st.min_work_budget << " units";
  return o.str();
}

void to_report(const WorkBudgetSummary& s, report::WorkBudget* r) {
  const vps::WorkBudgetStats& st = s.stats;
  r->set_tick_budget_us(static_cast<double>(s.params.tick_ns) * 1e-3);
  r->set_tick_margin_us(static_cast<double>(s.params.margin_ns) * 1e-3);
  r->set_work_cap(s.params.max_work == vps::kUnlimitedWork ? 0 : s.params.max_work);
  r->set_ticks(st.ticks);
  r->set_stopped_early(st.stopped_early);
  r->set_stopped_early_share(share(st.stopped_early, st.ticks));
  r->set_over_time(st.over_time);
  for (std::uint64_t n : st.levels) r->add_levels_completed(n);
  r->set_calibrated_ns_per_unit(st.calibrated_ns_per_unit);
  r->set_ns_per_unit(st.ns_per_unit);
  r->set_min_ns_per_unit(st.min_ns_per_unit);
  r->set_max_ns_per_unit(st.max_ns_per_unit);
  r->set_mean_ns_per_unit(st.mean_ns_per_unit);
  r->set_min_work_budget(st.min_work_budget == vps::kUnlimitedWork ? 0 : st.min_work_budget);
  r->set_calibration_samples(s.calibration.samples);
  r->set_calibration_median_ns_per_unit(s.calibration.median_ns_per_unit);
  r->set_calibration_p90_ns_per_unit(s.calibration.p90_ns_per_unit);
}

}  // namespace hemm::op
