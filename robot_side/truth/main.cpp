// hemm-truth: SIMULATION ONLY. Offline ground-truth evaluation of the
// operator's haptic rendering: along the proxy path the operator logged
// (hemm-operator --log RUN.csv writes RUN.csv.world.csv), the force rendered
// from its local model against the force from the simulated scene's true
// geometry, as RMS and maximum error (robot frame), plus the pose error
// between the operator's predicted robot pose and the simulation's true one.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <optional>
#include <vector>

#include "common/config/config.h"
#include "common/haptics/vps/cache.h"
#include "common/haptics/proxy/virtual_proxy.h"
#include "common/math/workspace_maps.h"
#include "config_operator.pb.h"
#include "robot_side/truth/probe3_truth.h"
#include "robot_side/truth/scene_slice.h"
#include "robot_side/truth/tool6_truth.h"
#include "robot_side/truth/truth_eval.h"
#include "report.pb.h"

namespace {

using namespace hemm;

constexpr int kExitOk = 0;
constexpr int kExitUsage = 2;

int usage_error(const std::string& msg) {
  std::cerr << "hemm-truth: " << msg << "\n";
  return kExitUsage;
}

void print_entries(const char* title, const std::vector<robot::SliceEntry>& v) {
  std::printf("%s (%zu):\n", title, v.size());
  for (const auto& e : v) std::printf("  %-16s %-9s %s\n", e.name.c_str(), e.kind.c_str(), e.detail.c_str());
}

// What a replay (--tool6, --probe3) runs against: the scene's true geometry
// in region voxelised at `voxel`, or (diagnosis, `against`) a saved live
// voxmap (RUN.csv.voxmap.vps); false with *error.
bool replay_voxmap(const std::string& scene, const std::vector<double>& region, double voxel, const std::string& against,
                   vps::Voxmap* vm, std::vector<std::string>* parts, std::string* error) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(region[0], region[1], region[2]),
                                Eigen::Vector3d(region[3], region[4], region[5]));
  if (box.isEmpty()) {
    *error = "--region: min must be below max";
    return false;
  }
  if (against.empty()) return robot::build_truth_voxmap(scene, box, voxel, vm, parts, error);
  std::ifstream f(against, std::ios::binary);
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  vps::PointShell ps;
  if (auto e = vps::deserialize_vps(bytes.data(), bytes.size(), vm, &ps)) {
    *error = against + ": " + e->message;
    return false;
  }
  parts->push_back(against);
  return true;
}

// --tool6: the 6-DoF probe tool's goal path (issue 13) against the scene's
// true geometry in --region, voxelised at --voxel.
int run_tool6(const std::string& scene, const std::string& log_path, const std::string& params_path,
              const std::vector<double>& region, double voxel, const std::string& against,
              const std::string& csv_path, const std::string& json_path) {
  std::string error;
  std::vector<robot::Tool6Tick> ticks;
  if (!robot::read_tool6_world_log(log_path, &ticks, &error)) return usage_error(error);
  if (ticks.empty()) return usage_error(log_path + ": no data rows");
  vps::ProbeToolGeometry g;
  vps::ToolParams p;
  if (!robot::read_tool6_params(params_path, &g, &p, &error)) return usage_error(error);
  vps::ProbeTool tool;
  if (auto e = vps::make_probe_tool(g, &tool)) return usage_error(params_path + ": " + e->message);
  vps::Voxmap vm;
  std::vector<std::string> parts;
  if (!replay_voxmap(scene, region, voxel, against, &vm, &parts, &error)) return usage_error(error);
  p.budget = vps::kUnlimitedWork;  // the reference: every point at full resolution
  const robot::Tool6Truth t = robot::evaluate_tool6(ticks, tool, p, vm);
  std::printf("hemm-truth --tool6 (SIMULATION ONLY): %zu parts (", parts.size());
  for (std::size_t i = 0; i < parts.size(); ++i) std::printf("%s%s", i ? " " : "", parts[i].c_str());
  std::printf("), voxel %.4f m, %.1f MB; %zu ticks\n", voxel, vm.memory_bytes() / 1e6, ticks.size());
  std::printf("contact ticks %zu: force error RMS %.4f N, max %.4f N (true peak %.4f N); torque error RMS %.5f N m, "
              "max %.5f N m (true peak %.5f N m)\n",
              t.contact_ticks, t.force_rms, t.force_max, t.true_force_peak, t.torque_rms, t.torque_max,
              t.true_torque_peak);
  if (!csv_path.empty()) {
    std::FILE* f = std::fopen(csv_path.c_str(), "w");
    if (f == nullptr) return usage_error(csv_path + ": cannot write");
    std::fprintf(f, "tick,t_s,f_x,f_y,f_z,ft_x,ft_y,ft_z,tau_x,tau_y,tau_z,taut_x,taut_y,taut_z,tool_x,tool_y,tool_z,"
                    "toolt_x,toolt_y,toolt_z,goal_x,goal_y,goal_z,contacts,contacts_true,model\n");
    for (std::size_t i = 0; i < ticks.size(); ++i) {
      const robot::Tool6Tick& k = ticks[i];
      const vps::Wrench& w = t.replay.wrench[i];
      const Eigen::Vector3d& tt = t.replay.tool_W[i];
      std::fprintf(f, "%zu,%.6f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,"
                      "%.5f,%.5f,%.5f,%d,%d,%d\n",
                   i, k.t_s, k.force.x(), k.force.y(), k.force.z(), w.force.x(), w.force.y(), w.force.z(), k.torque.x(),
                   k.torque.y(), k.torque.z(), w.torque.x(), w.torque.y(), w.torque.z(), k.tool.x(), k.tool.y(),
                   k.tool.z(), tt.x(), tt.y(), tt.z(), k.goal.translation().x(), k.goal.translation().y(),
                   k.goal.translation().z(), k.contacts, t.replay.contacts[i], k.model ? 1 : 0);
    }
    if (std::fclose(f) != 0) return usage_error(csv_path + ": write failed");
  }
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    report::Tool6Truth j;
    j.set_ticks(ticks.size());
    j.set_contact_ticks(static_cast<std::uint64_t>(t.contact_ticks));
    j.set_force_rms_n(t.force_rms);
    j.set_force_max_n(t.force_max);
    j.set_true_force_peak_n(t.true_force_peak);
    j.set_torque_rms_nm(t.torque_rms);
    j.set_torque_max_nm(t.torque_max);
    j.set_true_torque_peak_nm(t.true_torque_peak);
    j.set_voxel_m(voxel);
    f << config::to_json(j);
    if (!f) return usage_error(json_path + ": write failed");
  }
  return kExitOk;
}

// The point probe's contact model as the operator config sets it up
// (operator_station.cpp apply_probe3d_config, station_runner.cpp): the
// proxy's force law at its defaults with the servo's period and probe_3d's
// radius, the scale probe_3d.range_m over the device's horizontal half
// extent (the task's default workspace).
bool probe3_params_from_config(const std::string& path, vps::PointProbeParams* p, double* scale, std::string* error) {
  config::OperatorConfig c;
  if (auto e = config::load_operator_config(path, &c)) {
    *error = e->file + ":" + std::to_string(e->line) + ": " + (e->field.empty() ? "" : e->field + ": ") + e->message;
    return false;
  }
  if (!c.probe_3d().enabled() || c.probe_3d().tool() != "point") {
    *error = path + ": not a 3-DoF point probe config (probe_3d { enabled: true tool: \"point\" })";
    return false;
  }
  vps::PointProbeParams q;
  q.force.period = 1.0 / static_cast<double>(c.servo().rate_hz());
  q.force.probe_radius = c.probe_3d().probe_radius_m();
  if (std::string e = vps::validate(q); !e.empty()) {
    *error = path + ": point probe: " + e;
    return false;
  }
  *p = q;
  *scale = c.probe_3d().range_m() / math::horizontal_half_extent(math::DeviceWorkspace{});
  return true;
}

// --probe3: the 3-DoF point probe's logged device path (issue 24 part 4)
// against the scene's true geometry in --region, voxelised at --voxel.
int run_probe3(const std::string& scene, const std::string& log_path, const std::string& config_path,
               const std::vector<double>& region, double voxel, const std::string& against,
               const std::string& csv_path, const std::string& json_path) {
  std::string error;
  std::vector<robot::Probe3Tick> ticks;
  if (!robot::read_probe3_world_log(log_path, &ticks, &error)) return usage_error(error);
  if (ticks.empty()) return usage_error(log_path + ": no data rows");
  vps::PointProbeParams p;
  double scale = 0;
  if (!probe3_params_from_config(config_path, &p, &scale, &error)) return usage_error(error);
  vps::Voxmap vm;
  std::vector<std::string> parts;
  if (!replay_voxmap(scene, region, voxel, against, &vm, &parts, &error)) return usage_error(error);
  const robot::Probe3Truth t = robot::evaluate_probe3(ticks, p, scale, vm);
  std::printf("hemm-truth --probe3 (SIMULATION ONLY): %zu parts (", parts.size());
  for (std::size_t i = 0; i < parts.size(); ++i) std::printf("%s%s", i ? " " : "", parts[i].c_str());
  std::printf("), voxel %.4f m, %.1f MB; probe radius %.4f m, scale %.3f; %zu ticks\n", voxel, vm.memory_bytes() / 1e6,
              p.force.probe_radius, scale, ticks.size());
  std::printf("contact ticks %zu: force error RMS %.4f N, max %.4f N (true peak %.4f N)\n", t.contact_ticks, t.force_rms,
              t.force_max, t.true_force_peak);
  if (!csv_path.empty()) {
    std::FILE* f = std::fopen(csv_path.c_str(), "w");
    if (f == nullptr) return usage_error(csv_path + ": cannot write");
    // The columns deploy/report_tables.py explore3d-features reads (f_*, ft_*, contacts*), as --tool6 writes them.
    std::fprintf(f, "tick,t_s,f_x,f_y,f_z,ft_x,ft_y,ft_z,goal_x,goal_y,goal_z,proxy_x,proxy_y,proxy_z,proxyt_x,proxyt_y,"
                    "proxyt_z,contacts,contacts_true,model\n");
    for (std::size_t i = 0; i < ticks.size(); ++i) {
      const robot::Probe3Tick& k = ticks[i];
      const Eigen::Vector3d& ft = t.force_W[i];
      const Eigen::Vector3d& pt = t.proxy_W[i];
      std::fprintf(f, "%zu,%.6f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%.5f,%d,%d,%d\n", i,
                   k.t_s, k.force_W.x(), k.force_W.y(), k.force_W.z(), ft.x(), ft.y(), ft.z(), k.goal_W.x(),
                   k.goal_W.y(), k.goal_W.z(), k.proxy_W.x(), k.proxy_W.y(), k.proxy_W.z(), pt.x(), pt.y(), pt.z(),
                   k.contact ? 1 : 0, t.contact[i], k.model ? 1 : 0);
    }
    if (std::fclose(f) != 0) return usage_error(csv_path + ": write failed");
  }
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    report::Probe3Truth j;
    j.set_ticks(ticks.size());
    j.set_contact_ticks(static_cast<std::uint64_t>(t.contact_ticks));
    j.set_force_rms_n(t.force_rms);
    j.set_force_max_n(t.force_max);
    j.set_true_force_peak_n(t.true_force_peak);
    j.set_voxel_m(voxel);
    j.set_probe_radius_m(p.force.probe_radius);
    j.set_scale(scale);
    f << config::to_json(j);
    if (!f) return usage_error(json_path + ": write failed");
  }
  return kExitOk;
}

int run(int argc, char** argv) {
  CLI::App app{
      "hemm-truth: SIMULATION ONLY ground-truth check of the operator's haptic rendering.\n"
      "Replays the servo ticks of an operator world log (hemm-operator --log RUN.csv writes\n"
      "RUN.csv.world.csv) against the exact geometry of the simulated scene: the robot's TRUE pose is\n"
      "interpolated from the true poses the simulation sent, the robot-relative interaction point is\n"
      "carried onto it, and the same virtual proxy runs against the scene's static geoms sliced at\n"
      "--height. Rendered and true forces are compared in the robot frame R; prints RMS and max\n"
      "|dF| (all ticks and contact ticks), mean contact forces, and the predicted-vs-true pose error."};
  app.footer(
      "--height: the range sensors scan a horizontal plane and the local model is built from it, so\n"
      "  the truth is the scene cut at the laser's height: LaserConfig.mount_z_m = 0.30 m above the\n"
      "  floor (frame R has its origin on the ground). In deploy/scenes/home.xml every obstacle has a\n"
      "  part spanning 0.30 m (and 0.35 m): walls, partition, bin, crate, sofa; the table only as its\n"
      "  four legs, the chairs only as their leg blocks (table top, seats and backs are above it).\n"
      "Exit codes: 0 ok, 2 bad command line, scene or log file.");
  std::string scene_path, log_path, csv_path, json_path;
  double height = 0.30;
  std::optional<double> from_s, to_s;
  double contact_threshold = 0.05;
  bool list_geoms = false;
  app.add_option("--scene", scene_path, "MJCF scene the robot simulated (e.g. deploy/scenes/home.xml)")->required();
  app.add_option("--log", log_path, "operator world log (RUN.csv.world.csv)")->required();
  app.add_option("--height", height, "slice height in m above the floor (default 0.30: the laser plane; see below)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--from", from_s, "evaluate from this many seconds after the first tick");
  app.add_option("--to", to_s, "evaluate up to this many seconds after the first tick");
  app.add_option("--contact-threshold", contact_threshold,
                 "N; a tick is a contact tick when either force exceeds this (default 0.05)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--csv", csv_path,
                 "write per-tick rows: t_s, t_ns, rendered and true force in R, |dF|, both proxies in W, "
                 "true pose, pose error, held");
  app.add_option("--json", json_path, "write the summary numbers as one flat JSON object");
  app.add_flag("--list-geoms", list_geoms, "list the static geoms sliced, skipped and off the slice");
  std::string tool6_params;
  std::vector<double> region{0.8, 1.5, 0.6, 2.2, 2.5, 1.0};
  double voxel = 0.0025;
  app.add_option("--tool6", tool6_params,
                 "the 6-DoF probe tool's run (issue 13): RUN.csv.tool6.txt (the tool as the station wrote it); "
                 "replays the logged goal path against the scene's static geometry in --region, voxelised at "
                 "--voxel, with the same tool, contact and coupling; --csv gets per-tick live and true wrenches");
  std::string against;
  app.add_option("--against", against,
                 "with --tool6 or --probe3 (diagnosis): replay against this saved voxmap (RUN.csv.voxmap.vps: the final live "
                 "voxmap) instead of the scene's truth");
  std::string probe3_config;
  app.add_option("--probe3", probe3_config,
                 "the 3-DoF point probe's run (issue 24): the operator config it ran with (probe_3d.tool point: "
                 "its probe radius, range and servo rate); replays the logged device path (--log) against the "
                 "scene's static geometry in --region, voxelised at --voxel, with the same point-probe contact "
                 "model; --csv gets per-tick live and true forces");
  app.add_option("--region", region,
                 "with --tool6 or --probe3: xmin ymin zmin xmax ymax zmax in W (default: the home table)")
      ->expected(6);
  app.add_option("--voxel", voxel, "with --tool6 or --probe3: truth voxel size in m (default 0.0025)")->check(CLI::Range(0.0005, 0.02));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? kExitOk : kExitUsage;
  }
  if (from_s && to_s && *to_s < *from_s) return usage_error("--to must not be before --from");
  if ((from_s && !std::isfinite(*from_s)) || (to_s && !std::isfinite(*to_s)))
    return usage_error("--from/--to must be finite");

  // Output paths are checked before anything is written, so a bad one leaves no partial output.
  for (const std::string* out : {&csv_path, &json_path}) {
    if (out->empty()) continue;
    std::error_code ec;
    const std::filesystem::path parent = std::filesystem::absolute(*out, ec).parent_path();
    if (ec || !std::filesystem::is_directory(parent, ec) || std::filesystem::is_directory(*out, ec))
      return usage_error(*out + ": cannot write (no such directory, or it is a directory)");
  }

  if (!tool6_params.empty() && !probe3_config.empty()) return usage_error("--tool6 and --probe3: one run at a time");
  if (!probe3_config.empty())
    return run_probe3(scene_path, log_path, probe3_config, region, voxel, against, csv_path, json_path);
  if (!tool6_params.empty()) return run_tool6(scene_path, log_path, tool6_params, region, voxel, against, csv_path, json_path);

  robot::SceneSlice slice;
  std::string error;
  if (!robot::load_scene_slice(scene_path, height, &slice, &error)) return usage_error(error);
  robot::WorldLog log;
  if (!robot::read_world_log(log_path, &log, &error)) return usage_error(error);
  if (log.rows.empty()) return usage_error(log_path + ": no data rows");

  // What the operator runs (OperatorTaskParams::proxy defaults, 1 kHz).
  haptics::ProxyModel proxy;
  proxy.period = 1e-3;
  robot::TruthOptions opt;
  opt.from_s = from_s;
  opt.to_s = to_s;
  opt.contact_threshold_n = contact_threshold;
  opt.per_tick = !csv_path.empty();
  const robot::TruthReport r = robot::evaluate_against_truth(log.rows, slice.scene, proxy, opt);

  if (list_geoms) {
    print_entries("sliced", slice.included);
    print_entries("skipped", slice.skipped);
    print_entries("off the slice", slice.off_slice);
  }
  std::printf("hemm-truth (SIMULATION ONLY): scene %s at z = %.3f m: %zu geoms sliced, %zu skipped, %zu moving "
              "excluded\n",
              scene_path.c_str(), height, slice.included.size(), slice.skipped.size(), slice.moving_geoms);
  for (const auto& e : slice.skipped)
    std::printf("  skipped %s (%s): %s\n", e.name.c_str(), e.kind.c_str(), e.detail.c_str());
  std::printf("log %s: %zu rows%s, %zu true-pose samples (max gap %.3f s)\n", log_path.c_str(), r.rows,
              log.truncated_lines ? " (+1 truncated last line dropped)" : "", r.truth_samples, r.truth_max_gap_s);
  std::printf("ticks evaluated %zu of %zu in window (skipped: %zu before the first true pose, %zu invalid; %zu "
              "held after the last)\n",
              r.ticks, r.window_rows, r.skipped_before_truth, r.skipped_invalid, r.held_after_truth);
  if (r.ticks > 0) {
    std::printf("force error |dF| (R): RMS %.4f N, max %.4f N at t = %.3f s\n", r.rms_n, r.max_n, r.max_t_s);
    if (r.contact_ticks > 0)
      std::printf("contact ticks %zu: RMS %.4f N, max %.4f N; mean |F| rendered %.4f N, true %.4f N\n",
                  r.contact_ticks, r.contact_rms_n, r.contact_max_n, r.mean_force_rendered_n, r.mean_force_truth_n);
    else
      std::printf("contact ticks 0 (neither force above %.3f N)\n", contact_threshold);
    std::printf("pose error (predicted vs true): mean %.4f m, max %.4f m, heading max %.4f rad\n",
                r.pose_error_mean_m, r.pose_error_max_m, r.heading_error_max_rad);
  }

  if (!csv_path.empty()) {
    std::ofstream f(csv_path);
    if (!f) return usage_error(csv_path + ": cannot write");
    f << "t_s,t_ns,fr_x,fr_y,ft_x,ft_y,df,proxy_x,proxy_y,proxy_true_x,proxy_true_y,true_x,true_y,true_theta,"
         "pose_error_m,held\n";
    char buf[512];
    for (const auto& k : r.per_tick) {
      std::snprintf(buf, sizeof buf, "%.6f,%lld,%.5f,%.5f,%.5f,%.5f,%.5f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n",
                    k.t_s, static_cast<long long>(k.t_ns), k.f_rendered_R.x(), k.f_rendered_R.y(), k.f_truth_R.x(),
                    k.f_truth_R.y(), k.df, k.proxy_rendered_W.x(), k.proxy_rendered_W.y(), k.proxy_true_W.x(),
                    k.proxy_true_W.y(), k.true_x, k.true_y, k.true_theta, k.pose_error_m, k.held ? 1 : 0);
      f << buf;
    }
    if (!f) return usage_error(csv_path + ": write failed");
  }
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    if (!f) return usage_error(json_path + ": cannot write");
    report::Truth j = robot::to_report(r);
    j.set_height_m(height);
    j.set_geoms_sliced(slice.included.size());
    j.set_geoms_skipped(slice.skipped.size());
    j.set_truncated_lines(log.truncated_lines);
    j.set_contact_threshold_n(contact_threshold);
    if (from_s) j.set_from_s(*from_s);
    if (to_s) j.set_to_s(*to_s);
    f << config::to_json(j);
    if (!f) return usage_error(json_path + ": write failed");
  }
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "hemm-truth: internal error: " << e.what() << "\n";
    return 1;
  }
}
