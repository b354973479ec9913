// The force error the time-critical VPS costs (issue 22; docs/realtime.md,
// "Work budgets"), on the shipped VPS configs' own poses.
//
// For each config (deploy/configs/operator_vps_*.pbtxt) its device runs in
// lock step with the VPS servo task at the full three-pair cycle (no budget)
// for the config's default duration (the scripted hands' path and hold; the
// SIMULATED Omni's waypoints): the SIMULATED rigid scripted hands, the
// SIMULATED bimanual device whose humans follow the same paths, or the
// SIMULATED Omni. Each tick's object poses are kept. Then on those poses:
//   * the full cycle (the reference: each tick's wrench on every object);
//   * the time-critical cycle (coarse to fine, all pairs per level) at work
//     budgets from 128 units up to beyond the largest tick's work;
//   * the task's own time budget (work_budget.h: calibrated on the model,
//     updated every tick) at 50-500 us per tick (120 us: the shipped configs');
// each with its own pair state, tick after tick, as a live run keeps it.
// Per run: the share of ticks that stopped early (before some pair's finest
// level), the force and torque error against the full cycle on the same
// tick (RMS and max over the ticks where the full cycle has a contact, of
// |F - F_full| for every held object; also as a share of the RMS contact
// force), and the time per tick: the thread's CPU time (median, p99: what
// the work costs, meaningful beside other load) and wall time (steady
// clock: median, p99, max; what the budget spends, preemptions included).
//
// Usage: vps_budget_bench [--out DIR] [CONFIG.pbtxt ...]
//   default: the five shipped VPS configs, CSV to ./vps_budget.csv
//   (deploy/plots/plot_vps_budget.py CSV draws docs/img/vps_budget.png).
// The meshes come from deploy/vps/make_scenes.sh BUILD_DIR (out/vps).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/config/config.h"
#include "common/haptics/vps/work_budget.h"
#include "operator/vps/vps_config.h"
#include "operator/vps/vps_session.h"

namespace {

using namespace hemm;

struct Poses {
  std::string name;
  int objects = 0;
  std::vector<std::array<Eigen::Isometry3d, 2>> at;  // per tick: the objects' mesh frames in W
};

// One run over the poses: a budget (work units or time) or the full cycle.
struct Run {
  std::string mode;          // "full", "work", "time"
  std::int64_t units = 0;    // work budget (mode "work")
  double tick_us = 0;        // time budget (mode "time")
  std::vector<vps::Wrench> wrench;  // per tick and object: [2 i + k]
  std::vector<double> ns;           // per tick, wall (steady clock: what the budget spends)
  std::vector<double> cpu_ns;       // per tick, the thread's CPU time (meaningful on a loaded machine)
  std::vector<std::int64_t> work;
  std::vector<char> early, contact;
  std::uint64_t over_time = 0;
  double ns_per_unit = 0;    // measured (mean) at the end
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

// The device and the task in lock step (read, tick, write), full cycle; the
// poses each tick leaves the objects at are the ones the next evaluates.
Poses record_poses(const std::string& path, const config::OperatorConfig& cfg,
                   const std::shared_ptr<const op::VpsLocalModel>& model, op::VpsTaskParams tp) {
  std::unique_ptr<device::HapticDevice> dev = op::make_vps_device(cfg, "");
  tp.budget = vps::kUnlimitedWork;
  tp.tick_budget_ns = 0;
  op::VpsServoTask task(model, dev->limits(), tp);
  double duration = op::vps_default_duration_s(cfg);
  if (duration <= 0 && cfg.vps().omni_waypoints_size() > 0)
    duration = cfg.vps().omni_waypoints(cfg.vps().omni_waypoints_size() - 1).t_s() + 0.5;
  if (duration <= 0) duration = 5.0;
  Poses p;
  p.name = std::filesystem::path(path).stem().string();
  p.objects = model->object_count;
  servo::ModelSnapshot snap;
  const auto ticks = static_cast<std::uint64_t>(std::llround(duration * 1000));
  for (std::uint64_t i = 0; i < ticks; ++i) {
    device::DeviceSample in;
    dev->read(in);
    servo::TickOutput out;
    servo::prepare_tick_output(in, i, out);
    task.tick(in, snap, out);
    dev->write(out.command);
    std::array<Eigen::Isometry3d, 2> a{task.object_pose(0), p.objects == 2 ? task.object_pose(1) : task.object_pose(0)};
    p.at.push_back(a);
  }
  return p;
}

void evaluate(const op::VpsLocalModel& m, const Poses& poses, const op::VpsTaskParams& tp, Run* run) {
  const std::size_t n = poses.at.size();
  const bool two = poses.objects == 2;
  run->wrench.assign(2 * n, vps::Wrench{});
  run->ns.assign(n, 0);
  run->cpu_ns.assign(n, 0);
  run->work.assign(n, 0);
  run->early.assign(n, 0);
  run->contact.assign(n, 0);
  vps::BimanualState bs;
  vps::PairState ps;
  if (two)
    vps::init_bimanual_state(m.bimanual, &bs);
  else
    vps::init_pair_state(m.objects[0].shell, &ps);
  vps::TickWorkBudget budget;
  if (run->mode == "time") {
    vps::TimeBudgetParams tb;
    tb.tick_ns = std::llround(run->tick_us * 1e3);
    std::vector<vps::CalibrationPair> pairs{{&m.scene, &m.objects[0].shell}};
    if (two) {
      pairs.push_back({&m.scene, &m.objects[1].shell});
      pairs.push_back({&m.objects[1].voxmap, &m.objects[0].shell});
    }
    budget = vps::TickWorkBudget(
        tb, vps::calibrate_work_rate(pairs, m.bimanual.params, tb.rate, tp.calibration_poses, &steady_now_ns).rate);
  }
  const int lr = m.objects[0].shell.levels, ll = two ? m.objects[1].shell.levels : 0;
  vps::BimanualData d;
  vps::PairResult r;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Isometry3d& T_W_R = poses.at[i][0];
    const Eigen::Isometry3d& T_W_L = poses.at[i][1];
    const double c0 = thread_cpu_s();
    const std::int64_t t0 = steady_now_ns();
    std::int64_t units = run->mode == "work" ? run->units : vps::kUnlimitedWork;
    if (run->mode == "time") units = budget.begin(t0, 0);
    bool complete = true;
    int levels = 0;
    std::int64_t work = 0;
    if (two) {
      if (units == vps::kUnlimitedWork)
        vps::evaluate_bimanual(m.bimanual, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, &bs, &d);
      else
        vps::evaluate_bimanual_budgeted(m.bimanual, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, units, &bs, &d);
      complete = d.right_scene.levels_completed >= lr && d.left_scene.levels_completed >= ll &&
                 d.right_left.levels_completed >= lr;
      levels = d.levels_completed;
      work = d.work;
      run->wrench[2 * i] = d.right_total;
      run->wrench[2 * i + 1] = d.left_total;
      run->contact[i] = d.right_scene.contacts + d.left_scene.contacts + d.right_left.contacts > 0;
    } else {
      vps::evaluate_pair_budgeted(m.scene, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), m.objects[0].shell,
                                  T_W_R, m.bimanual.params, units, &ps, &r);
      complete = r.levels_completed >= lr;
      levels = r.levels_completed;
      work = r.nodes_visited + r.points_tested;
      run->wrench[2 * i] = r.on_shell;
      run->contact[i] = r.contacts > 0;
    }
    const std::int64_t t1 = steady_now_ns();
    run->cpu_ns[i] = 1e9 * (thread_cpu_s() - c0);
    if (run->mode == "time") budget.end(t1, work, levels, complete);
    run->ns[i] = static_cast<double>(t1 - t0);
    run->work[i] = work;
    run->early[i] = complete ? 0 : 1;
  }
  if (run->mode == "time") {
    run->over_time = budget.stats().over_time;
    run->ns_per_unit = budget.stats().mean_ns_per_unit;
  }
}

struct Row {
  std::uint64_t ticks = 0, contact_ticks = 0;
  double early_share = 0;
  double f_rms = 0, f_max = 0, f_rms_pct = 0, t_rms = 0, t_max = 0, t_rms_pct = 0;
  double ns_med = 0, ns_p99 = 0, ns_max = 0;
  double cpu_med = 0, cpu_p99 = 0;
  double work_med = 0, work_max = 0;
};

Row compare(const Run& run, const Run& full, int objects) {
  Row row;
  const std::size_t n = run.ns.size();
  row.ticks = n;
  double f2 = 0, t2 = 0, ref_f2 = 0, ref_t2 = 0;
  std::uint64_t samples = 0, early = 0;
  std::vector<double> work(run.work.begin(), run.work.end());
  for (std::size_t i = 0; i < n; ++i) {
    early += run.early[i] != 0;
    if (full.contact[i] == 0) continue;
    ++row.contact_ticks;
    for (int k = 0; k < objects; ++k) {
      const vps::Wrench& a = run.wrench[2 * i + static_cast<std::size_t>(k)];
      const vps::Wrench& b = full.wrench[2 * i + static_cast<std::size_t>(k)];
      const double df = (a.force - b.force).norm(), dt = (a.torque - b.torque).norm();
      f2 += df * df;
      t2 += dt * dt;
      ref_f2 += b.force.squaredNorm();
      ref_t2 += b.torque.squaredNorm();
      row.f_max = std::max(row.f_max, df);
      row.t_max = std::max(row.t_max, dt);
      ++samples;
    }
  }
  if (samples > 0) {
    const double s = static_cast<double>(samples);
    row.f_rms = std::sqrt(f2 / s);
    row.t_rms = std::sqrt(t2 / s);
    row.f_rms_pct = ref_f2 > 0 ? 100 * std::sqrt(f2 / ref_f2) : 0;
    row.t_rms_pct = ref_t2 > 0 ? 100 * std::sqrt(t2 / ref_t2) : 0;
  }
  row.early_share = n > 0 ? static_cast<double>(early) / static_cast<double>(n) : 0;
  row.ns_med = quantile(run.ns, 0.5);
  row.ns_p99 = quantile(run.ns, 0.99);
  row.ns_max = quantile(run.ns, 1.0);
  row.cpu_med = quantile(run.cpu_ns, 0.5);
  row.cpu_p99 = quantile(run.cpu_ns, 0.99);
  row.work_med = quantile(work, 0.5);
  row.work_max = quantile(work, 1.0);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = ".";
  std::vector<std::string> configs;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) {
      out_dir = argv[++i];
    } else if (a == "--help" || a == "-h") {
      std::printf("usage: vps_budget_bench [--out DIR] [CONFIG.pbtxt ...]\n");
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "vps_budget_bench: unknown option %s\n", a.c_str());
      return 2;
    } else {
      configs.push_back(a);
    }
  }
  if (configs.empty())
    for (const char* c : {"operator_vps_peg", "operator_vps_assembly", "operator_vps_omni", "operator_vps_peg_bimanual",
                          "operator_vps_assembly_bimanual"})
      configs.push_back(std::string(HEMM_SOURCE_DIR) + "/deploy/configs/" + c + ".pbtxt");
  const std::string csv_path = out_dir + "/vps_budget.csv";
  std::FILE* csv = std::fopen(csv_path.c_str(), "w");
  if (csv == nullptr) {
    std::fprintf(stderr, "vps_budget_bench: cannot write %s\n", csv_path.c_str());
    return 2;
  }
  std::fprintf(csv,
               "config,mode,budget_units,budget_us,ticks,contact_ticks,stopped_early_share,f_rms_N,f_max_N,f_rms_pct,"
               "t_rms_Nm,t_max_Nm,t_rms_pct,cpu_median_us,cpu_p99_us,time_median_us,time_p99_us,time_max_us,work_median,"
               "work_max,over_time,ns_per_unit\n");
  int done = 0;
  for (const std::string& path : configs) {
    config::OperatorConfig cfg;
    if (auto e = config::load_operator_config(path, &cfg)) {
      std::fprintf(stderr, "vps_budget_bench: %s: %s\n", path.c_str(), e->to_string().c_str());
      return 2;
    }
    std::shared_ptr<op::VpsLocalModel> model;
    op::VpsTaskParams tp;
    try {
      const op::VpsSetup setup = op::vps_setup(cfg, path);
      tp = setup.task;
      model = op::load_vps_model(setup.model);
    } catch (const std::exception& e) {
      std::printf("%s: skipped (%s; deploy/vps/make_scenes.sh BUILD_DIR writes the meshes)\n", path.c_str(), e.what());
      continue;
    }
    const Poses poses = record_poses(path, cfg, model, tp);
    Run full;
    full.mode = "full";
    evaluate(*model, poses, tp, &full);
    const Row ref = compare(full, full, poses.objects);
    std::printf("\n%s: %zu ticks (%llu in contact), %d object(s); full cycle: work median %.0f max %.0f units, "
                "CPU time median %.1f us p99 %.1f us; wall time median %.1f us p99 %.1f us max %.1f us\n",
                poses.name.c_str(), poses.at.size(), static_cast<unsigned long long>(ref.contact_ticks), poses.objects,
                ref.work_med, ref.work_max, ref.cpu_med * 1e-3, ref.cpu_p99 * 1e-3, ref.ns_med * 1e-3,
                ref.ns_p99 * 1e-3, ref.ns_max * 1e-3);
    std::printf("  %-6s %9s %10s | %6s | %8s %8s %7s | %8s %8s %7s | %7s %7s | %7s %7s %8s | %5s\n", "mode", "budget",
                "", "early", "F rms N", "F max N", "F rms%", "T rms Nm", "T max Nm", "T rms%", "cpu med", "cpu p99",
                "med us", "p99 us", "max us", "over");
    std::vector<Run> runs;
    for (std::int64_t u = 128; u < 2 * static_cast<std::int64_t>(ref.work_max) + 256; u *= 2) {
      Run r;
      r.mode = "work";
      r.units = u;
      runs.push_back(r);
    }
    for (double us : {50.0, 100.0, 120.0, 150.0, 200.0, 300.0, 500.0}) {
      Run r;
      r.mode = "time";
      r.tick_us = us;
      runs.push_back(r);
    }
    runs.push_back(full);
    for (Run& r : runs) {
      if (r.mode != "full") evaluate(*model, poses, tp, &r);
      const Row row = compare(r, full, poses.objects);
      char budget[32] = "";
      if (r.mode == "work") std::snprintf(budget, sizeof budget, "%lld u", static_cast<long long>(r.units));
      if (r.mode == "time") std::snprintf(budget, sizeof budget, "%.0f us", r.tick_us);
      char rate[32] = "";
      if (r.mode == "time") std::snprintf(rate, sizeof rate, "%.1f ns/u", r.ns_per_unit);
      std::printf("  %-6s %9s %10s | %5.1f%% | %8.3f %8.3f %6.2f%% | %8.5f %8.5f %6.2f%% | %7.1f %7.1f | %7.1f %7.1f %8.1f | "
                  "%5llu\n",
                  r.mode.c_str(), budget, rate, 100 * row.early_share, row.f_rms, row.f_max, row.f_rms_pct, row.t_rms,
                  row.t_max, row.t_rms_pct, row.cpu_med * 1e-3, row.cpu_p99 * 1e-3, row.ns_med * 1e-3,
                  row.ns_p99 * 1e-3, row.ns_max * 1e-3, static_cast<unsigned long long>(r.over_time));
      std::fprintf(csv,
                   "%s,%s,%lld,%.1f,%llu,%llu,%.6f,%.6g,%.6g,%.4f,%.6g,%.6g,%.4f,%.2f,%.2f,%.2f,%.2f,%.2f,%.0f,%.0f,%llu,"
                   "%.3f\n",
                   poses.name.c_str(), r.mode.c_str(), static_cast<long long>(r.mode == "work" ? r.units : 0), r.tick_us,
                   static_cast<unsigned long long>(row.ticks), static_cast<unsigned long long>(row.contact_ticks),
                   row.early_share, row.f_rms, row.f_max, row.f_rms_pct, row.t_rms, row.t_max, row.t_rms_pct,
                   row.cpu_med * 1e-3, row.cpu_p99 * 1e-3, row.ns_med * 1e-3, row.ns_p99 * 1e-3, row.ns_max * 1e-3,
                   row.work_med, row.work_max, static_cast<unsigned long long>(r.over_time), r.ns_per_unit);
    }
    ++done;
  }
  std::fclose(csv);
  std::printf("\n%d config(s); CSV %s\n", done, csv_path.c_str());
  return 0;
}
