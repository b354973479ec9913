// One run of a 6-DoF probe tool script ("explore-block" or "explore-table")
// on the live voxmap over real loopback sockets (robot and operator stations
// in one process), and its SIMULATION-ONLY truth: the logged goal path
// replayed with the same tool, contact and coupling against the scene's
// geometry voxelised exactly at 2.5 mm (robot_side/truth/tool6_truth.h).
// Shared by the tests of each device that holds the tool (sim-hand6,
// sim-bimanual).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "config_operator.pb.h"
#include "operator/client/operator_client.h"
#include "operator/station/explore_route.h"
#include "operator/station/operator_station.h"
#include "robot_side/truth/tool6_truth.h"
#include "tests/integration/probe3d/table_scene.h"
#include "tests/operator/client/loopback_client.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/robot_side/station/robot_side.h"

namespace hemm::test {

struct Explore3dRun {
  op::OperatorStationSummary sum;
  std::uint64_t servo_allocs = 0;
  std::vector<robot::Tool6Tick> ticks;  // row i: the hand's script at i ms
  vps::ProbeToolGeometry geometry;
  vps::ToolParams params;  // from the log's sidecar (the live tool's)
  robot::Tool6Truth truth;
  // Resting pressed on the block's top (t 7.5-8 s of the script, before the
  // slide): the tool tip centre's median z, live and true.
  double rest_live_z = 0, rest_true_z = 0;
  std::size_t rest_ticks = 0;
};

inline constexpr double kBlockTop_m = 0.85;

// Runs `script` for `ms` with probe_3d from `ocfg` (tool "pointshell");
// `device` picks the station's device. Both scripts press the block's top
// first (t 7.5-8 s: the rest above). With min_ticks, on until the servo has
// ticked that often (the script runs one period per tick, and a loaded
// machine drops periods), for at most max_ms.
inline void run_explore(const std::string& log, config::OperatorConfig ocfg,
                        const std::function<void(op::OperatorStationOptions&)>& device, const std::string& script,
                        int ms, Explore3dRun* out, std::uint64_t min_ticks = 0, int max_ms = 0) {
  RobotSide robot(robot_before_table(), table_test_key(11, 3), kHomeScene);
  robot.start();
  asio::io_context io;
  op::OperatorClientOptions co =
      loopback_client_options("explore3d-test", robot.server->session_port(), table_test_key(11, 3));
  op::OperatorClient client(io, co);
  op::OperatorStationOptions so = loopback_station_options(log);
  so.task.initial_mode = math::Mode::kExploration;
  auto* p3 = ocfg.mutable_probe_3d();
  p3->set_enabled(true);
  p3->set_tool("pointshell");
  p3->set_tool_hand_script(script);
  op::apply_probe3d_config(ocfg.probe_3d(), &so);
  so.hand6_route_file = kHomeScene;
  device(so);
  op::OperatorStation station(io, client, so);
  station.task().set_servo_thread_hook(&count_allocations_on_this_thread);
  ASSERT_NE(station.task().tool6(), nullptr);

  std::string err;
  ASSERT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  const auto started = std::chrono::steady_clock::now();
  out->servo_allocs = run_station_until(
      io, client, station, ms,
      [&] {
        return station.servo_stats().ticks.load(std::memory_order_relaxed) >= min_ticks ||
               std::chrono::steady_clock::now() - started > std::chrono::milliseconds(max_ms);
      },
      [] {});
  out->sum = station.summary();
  const op::OperatorStationSummary& sum = out->sum;
  const op::VoxmapStats& vs = sum.model.voxmap;
  std::printf("voxmap: chunks %llu, builds %llu, occupied cells %zu; servo: %llu ticks, period median %.1f us p99 "
              "%.1f us, misses %llu, compute median %.1f us p99 %.1f us; allocations on the servo thread %llu\n",
              static_cast<unsigned long long>(vs.stream.accepted), static_cast<unsigned long long>(vs.builds),
              vs.occupied_cells, static_cast<unsigned long long>(sum.timing.ticks), sum.timing.period.median_us,
              sum.timing.period.p99_us, static_cast<unsigned long long>(sum.timing.misses),
              sum.timing.compute.median_us, sum.timing.compute.p99_us,
              static_cast<unsigned long long>(out->servo_allocs));
  EXPECT_GT(vs.builds, 5u);
  ASSERT_EQ(sum.world_log_dropped, 0u);  // one row per tick: row i is the hand's script at i ms

  // Simulation truth.
  ASSERT_TRUE(robot::read_tool6_world_log(so.log_path + ".world.csv", &out->ticks, &err)) << err;
  ASSERT_GT(out->ticks.size(), 15000u);
  ASSERT_TRUE(robot::read_tool6_params(so.log_path + ".tool6.txt", &out->geometry, &out->params, &err)) << err;
  EXPECT_EQ(out->params.coupling.k_lin, station.task().tool6()->tool_params().coupling.k_lin);  // the live tool's
  vps::ProbeTool tool;
  ASSERT_FALSE(vps::make_probe_tool(out->geometry, &tool));
  vps::Voxmap truth;
  std::vector<std::string> parts;
  // "explore-block": around the block (the script's reach: W x 1.6-1.9, y
  // 1.65-2.0) and the table top under it; "explore-table": the whole table
  // top and what stands on it (hemm-truth --tool6's default region).
  const bool block_only = script == "explore-block";
  const Eigen::AlignedBox3d region(block_only ? Eigen::Vector3d(1.55, 1.6, 0.7) : Eigen::Vector3d(0.8, 1.5, 0.6),
                                   block_only ? Eigen::Vector3d(1.95, 2.05, 1.1) : Eigen::Vector3d(2.2, 2.5, 1.0));
  ASSERT_TRUE(robot::build_truth_voxmap(kHomeScene, region, 0.0025, &truth, &parts, &err)) << err;
  ASSERT_NE(std::find(parts.begin(), parts.end(), "table_block"), parts.end());
  if (!block_only) {
    ASSERT_NE(std::find(parts.begin(), parts.end(), "table_book"), parts.end());
    ASSERT_NE(std::find(parts.begin(), parts.end(), "table_mug"), parts.end());
  }
  vps::ToolParams tp = out->params;
  tp.budget = vps::kUnlimitedWork;  // the reference: every point
  const auto t0 = std::chrono::steady_clock::now();
  out->truth = robot::evaluate_tool6(out->ticks, tool, tp, truth);
  std::printf("truth replay %.2f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());

  std::vector<double> rest_live, rest_true;
  for (std::size_t i = 0; i < out->ticks.size(); ++i) {
    const double ts = static_cast<double>(i) * 1e-3;  // the hand's script time: one period per tick (not wall time)
    if (ts > 7.5 && ts < 8.0) {
      rest_live.push_back(out->ticks[i].tool.z());
      rest_true.push_back(out->truth.replay.tool_W[i].z());
    }
  }
  ASSERT_GT(rest_live.size(), 300u);
  out->rest_ticks = rest_live.size();
  out->rest_live_z = median(rest_live);
  out->rest_true_z = median(rest_true);
  const robot::Tool6Truth& t = out->truth;
  std::printf("rest on the block top: live tip centre z %.4f m, truth %.4f m, true top + radius %.4f m\n",
              out->rest_live_z, out->rest_true_z, kBlockTop_m + out->geometry.tip_radius);
  std::printf("force error over %zu contact ticks: rms %.3f N, max %.3f N (true peak %.3f N); torque rms %.4f N m, "
              "max %.4f N m (true peak %.4f N m)\n",
              t.contact_ticks, t.force_rms, t.force_max, t.true_force_peak, t.torque_rms, t.torque_max,
              t.true_torque_peak);
}

// The force error over one feature of a route: the ticks in [t0, t1] of
// the hand's script time where the live or the true tool touches.
struct FeatureError {
  std::string name;
  double t0, t1;
  std::size_t ticks = 0;
  double rms = 0, true_peak = 0;  // |live - true| RMS; the true force's peak there (N)
  double with_model = 0;          // fraction of the feature's ticks that had a live voxmap
};

// The features of home.xml's route `route` (its header's explore6 keys,
// operator/station/explore_route.h; deploy/explore3d.sh's table takes the same).
inline std::vector<FeatureError> table_feature_errors(const Explore3dRun& r, const std::string& route = "explore-table") {
  op::SceneExploration x;
  const auto err = op::load_scene_exploration(kHomeScene, &x);
  EXPECT_FALSE(err) << *err;
  std::vector<FeatureError> f;
  if (err || x.find(route) == nullptr) return f;
  for (const op::RouteFeature& g : op::route_features(*x.find(route))) f.push_back({g.name, g.t0_s, g.t1_s});
  for (FeatureError& e : f) {
    double e2 = 0;
    std::size_t in = 0, modelled = 0;
    for (std::size_t i = 0; i < r.ticks.size() && i < r.truth.replay.wrench.size(); ++i) {
      const double ts = static_cast<double>(i) * 1e-3;  // one script period per tick
      if (ts < e.t0 || ts > e.t1) continue;
      ++in;
      modelled += r.ticks[i].model ? 1 : 0;
      if (r.ticks[i].contacts == 0 && r.truth.replay.contacts[i] == 0) continue;
      const Eigen::Vector3d& ft = r.truth.replay.wrench[i].force;
      e2 += (r.ticks[i].force - ft).squaredNorm();
      ++e.ticks;
      e.true_peak = std::max(e.true_peak, ft.norm());
    }
    if (e.ticks > 0) e.rms = std::sqrt(e2 / static_cast<double>(e.ticks));
    if (in > 0) e.with_model = static_cast<double>(modelled) / static_cast<double>(in);
    std::printf("  %-16s %6zu contact ticks, force error RMS %6.2f N of a true peak %5.1f N (live voxmap on %.0f %%)\n",
                e.name.c_str(), e.ticks, e.rms, e.true_peak, 100 * e.with_model);
  }
  return f;
}

}  // namespace hemm::test
