// The 3D probe end to end over real loopback sockets (issue 13's slice): the
// SIMULATED robot station (MuJoCo home scene, real time) stands 0.6 m before
// the table with its SIMULATED mast depth camera streaming DepthChunks; the
// real operator station (client, model thread building the live voxmap,
// 1 kHz servo with the 3-DoF point probe, SIMULATED Omni with a scripted
// hand) explores with the robot standing still: the hand holds the probe
// above the table while the voxmap fills, presses it onto the table top,
// slides along it and lifts off.
//
// Asserted against simulation truth (the MJCF's table_top box, meshed from
// MuJoCo's own model and voxelised exactly, probed along the very goal path
// the servo logged): the resting proxy sits on the true top + the probe
// radius, the force the live model rendered matches the truth's along the
// path, the servo held its period, no heap allocation on the servo thread,
// and the simulation thread was not made late by the depth camera.
// Timing assertions use wide margins: the VM is shared and stalls for ms.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/point_probe.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mesh/triangle_mesh.h"
#include "common/net/relay/relay.h"
#include "config_operator.pb.h"
#include "config_robot.pb.h"
#include "operator/client/operator_client.h"
#include "operator/station/operator_station.h"
#include "robot_side/server/robot_server.h"
#include "robot_side/station/robot_station.h"
#include "robot_side/truth/scene_slice.h"
#include "tests/operator/client/loopback_client.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/integration/probe3d/table_scene.h"
#include "tests/operator/station/world_log.h"
#include "tests/robot_side/station/robot_side.h"

namespace hr = hemm::robot;
namespace ho = hemm::op;
namespace hn = hemm::net;
using hemm::test::median;
using hemm::test::read_world_log;
namespace vps = hemm::vps;

namespace {

const std::string& kScene = hemm::test::kHomeScene;
hn::Key test_key() { return hemm::test::table_test_key(13, 5); }
constexpr auto servo_hook = &hemm::test::count_allocations_on_this_thread;

}  // namespace

// Round trip (ms, through hemm-relay's impairment in-process: half each way)
// and datagram loss each way.
struct Link {
  int rtt_ms;
  double loss;
};
class Probe3dLoopback : public ::testing::TestWithParam<Link> {};

TEST_P(Probe3dLoopback, ProbeRestsOnTheTrueTableTopAndTheServoHoldsItsPeriod) {
  const Link link = GetParam();
  // Robot: before the table (top 1.2 x 0.8 m at z 0.75, centre (1.5, 2.0)),
  // facing it, its front 0.38 m from the table's edge.
  hemm::test::RobotSide robot(hemm::test::robot_before_table(), test_key(), kScene);
  robot.start();

  asio::io_context io;
  ho::OperatorClientOptions co =
      hemm::test::loopback_client_options("probe3d-test", robot.server->session_port(), test_key());
  std::unique_ptr<hemm::net::relay::Relay> relay;
  if (link.rtt_ms > 0 || link.loss > 0) {
    hemm::net::relay::RelayConfig rc;
    rc.tcp_listen = hemm::net::relay::HostPort{"127.0.0.1", 0};
    rc.tcp_forward = hemm::net::relay::HostPort{"127.0.0.1", robot.server->session_port()};
    rc.udp_listen = hemm::net::relay::HostPort{"127.0.0.1", 0};
    rc.udp_forward = hemm::net::relay::HostPort{"127.0.0.1", robot.server->stream_port()};
    for (auto* d : {&rc.up, &rc.down}) {
      d->delay_ns = static_cast<std::int64_t>(link.rtt_ms) * 500'000;
      d->loss = link.loss;
    }
    rc.seed = 7;
    relay = std::make_unique<hemm::net::relay::Relay>(rc);
    co.session_port = relay->tcp_listen_port();
    co.stream_port = relay->udp_listen_port();
  }
  ho::OperatorClient client(io, co);
  const std::string log_name = "probe3d_loopback_test_" + std::to_string(link.rtt_ms) + "ms.csv";
  ho::OperatorStationOptions so = hemm::test::loopback_station_options(log_name);
  so.task.initial_mode = hemm::math::Mode::kExploration;
  hemm::config::OperatorConfig ocfg;
  ocfg.mutable_probe_3d()->set_enabled(true);
  ho::apply_probe3d_config(ocfg.probe_3d(), &so);
  // The hand: stylus centred (the probe 10 cm above the top) while the
  // voxmap fills, pressed 1.5 cm (W) below the top, held, slid 0.15 m along
  // it (B -x: toward the robot, W -y; across the view it ended 1.5 cm from
  // the book's edge-on side, which the model cannot render), held, lifted.
  const double scale = so.task.probe3d_range / hemm::math::horizontal_half_extent(so.task.workspace);
  const Eigen::Matrix3d R_H_B = ho::R_B_H().transpose();
  const Eigen::Vector3d c_H = R_H_B * so.task.workspace.centre_B;
  const double z_top_nominal = 0.75, press_W = 0.015;
  const double down_B = (so.task.probe3d_origin_R.z() - (z_top_nominal - press_W)) / scale;
  const Eigen::Vector3d pressed_H = c_H + R_H_B * Eigen::Vector3d(0, 0, -down_B);
  const Eigen::Vector3d slid_H = pressed_H + R_H_B * Eigen::Vector3d(-0.15 / scale, 0, 0);
  so.hand = std::make_shared<hemm::device::WaypointScript>(std::vector<hemm::device::Waypoint>{
      {0.0, c_H, 0}, {4.0, c_H, 0}, {5.0, pressed_H, 0}, {6.0, pressed_H, 0}, {8.0, slid_H, 0}, {8.5, slid_H, 0},
      {9.0, c_H, 0}});
  ho::OperatorStation station(io, client, so);
  station.task().set_servo_thread_hook(servo_hook);

  std::string err;
  ASSERT_TRUE(client.start([](int, const std::string& why) { ADD_FAILURE() << "fatal: " << why; }, &err)) << err;
  hr::RobotStationStatistics rs;
  const std::uint64_t servo_allocs =
      hemm::test::run_station_for(io, client, station, 9500, [&] { rs = robot.station->statistics(); });

  const ho::OperatorStationSummary sum = station.summary();
  const ho::VoxmapStats& vs = sum.model.voxmap;
  std::printf("robot: %llu sim steps, %llu late, max lateness %.2f ms; depth frames sent %llu, skipped %llu, "
              "chunks %llu, %llu bytes\n",
              static_cast<unsigned long long>(rs.sim_steps), static_cast<unsigned long long>(rs.late_steps),
              static_cast<double>(rs.max_lateness_ns) * 1e-6, static_cast<unsigned long long>(rs.depth_frames_sent),
              static_cast<unsigned long long>(rs.depth_frames_skipped),
              static_cast<unsigned long long>(rs.depth_chunks_sent), static_cast<unsigned long long>(rs.depth_bytes_sent));
  std::printf("voxmap: chunks accepted %llu stale %llu dup %llu malformed %llu dropped %llu; cells %zu occupied %zu, "
              "%.1f kB cells, %.1f kB snapshot; builds %llu (last %.1f ms, max %.1f ms); integrate max %.1f ms\n",
              static_cast<unsigned long long>(vs.stream.accepted), static_cast<unsigned long long>(vs.stream.stale),
              static_cast<unsigned long long>(vs.stream.duplicate), static_cast<unsigned long long>(vs.stream.malformed),
              static_cast<unsigned long long>(vs.chunks_dropped), vs.cells, vs.occupied_cells, vs.memory_bytes / 1e3,
              vs.snapshot_bytes / 1e3, static_cast<unsigned long long>(vs.builds), vs.last_build_ms, vs.max_build_ms,
              vs.max_integrate_ms);
  std::printf("servo: %llu ticks, period median %.1f us p99 %.1f us, misses %llu, compute median %.1f us; "
              "allocations on the servo thread %llu\n",
              static_cast<unsigned long long>(sum.timing.ticks), sum.timing.period.median_us, sum.timing.period.p99_us,
              static_cast<unsigned long long>(sum.timing.misses), sum.timing.compute.median_us,
              static_cast<unsigned long long>(servo_allocs));

  // The stream and the voxmap.
  EXPECT_GT(rs.depth_frames_sent, 60u);  // 15 Hz over ~8 s, wide margin
  EXPECT_EQ(vs.stream.malformed, 0u);
  EXPECT_GT(vs.builds, 5u);
  EXPECT_GT(vs.occupied_cells, 1000u);
  // The simulation thread kept stepping (the camera casts on its worker;
  // depth_voxmap_test times the capture steps; here both stations and the
  // voxmap share the 2 cores, so late steps are the machine's, wide margin).
  EXPECT_LT(static_cast<double>(rs.late_steps), 0.3 * static_cast<double>(rs.sim_steps));
  // The servo.
  EXPECT_EQ(servo_allocs, 0u);
  EXPECT_GT(sum.timing.ticks, 7000u);
  if (relay) {
    const auto st = relay->stats();
    std::printf("relay: udp down %llu delivered %llu dropped; up %llu delivered %llu dropped\n",
                static_cast<unsigned long long>(st.udp_down.forwarded), static_cast<unsigned long long>(st.udp_down.dropped_random),
                static_cast<unsigned long long>(st.udp_up.forwarded), static_cast<unsigned long long>(st.udp_up.dropped_random));
    relay->stop();
  }
  EXPECT_NEAR(sum.timing.period.median_us, 1000.0, 100.0);

  // Simulation truth: the table and the objects on it from the MJCF, meshed
  // and voxelised exactly (the slide ends 1 cm from the book's side).
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.8, 1.5, 0.6), Eigen::Vector3d(2.2, 2.5, 0.9));
  hr::SceneMeshes truth_meshes;
  ASSERT_TRUE(hr::load_scene_meshes(kScene, region, &truth_meshes, &err)) << err;
  const hr::SceneMeshPart* top = nullptr;
  for (const auto& p : truth_meshes.parts)
    if (p.name == "table_top") top = &p;
  ASSERT_NE(top, nullptr);
  double z_top = -1e9;
  for (const Eigen::Vector3d& v : top->mesh.vertices) z_top = std::max(z_top, v.z());
  ASSERT_NEAR(z_top, z_top_nominal, 1e-9);
  vps::VoxmapParams vp;
  vp.voxel_size = 0.0025;
  vp.layers_out = vp.layers_in = 8;
  hemm::mesh::TriangleMesh scene;
  for (const auto& p : truth_meshes.parts) hemm::mesh::append_mesh(&scene, p.mesh);
  vps::Voxmap truth;
  ASSERT_FALSE(vps::build_voxmap(scene, vp, &truth, nullptr));

  const auto rows = read_world_log(so.log_path + ".world.csv");
  ASSERT_GT(rows.size(), 5000u);
  const vps::PointProbeParams pp = station.task().params().probe3d;
  const double rho = so.task.probe3d.force.probe_radius;
  vps::PointProbeData td;
  std::vector<double> rest_z, err2, contact_err2;
  double peak = 0.0, max_err = 0.0;
  // Per tick: the true force and proxy (for plots beside the world log).
  std::FILE* dbg = std::fopen((so.log_path + ".truth.csv").c_str(), "w");
  for (const auto& r : rows) {
    const Eigen::Vector3d goal(r.at("goal_x"), r.at("goal_y"), r.at("goal_z"));
    if (!td.initialized) vps::point_probe_reset(td, goal);
    vps::point_probe_tick(pp, &truth, td, goal, scale);
    const Eigen::Vector3d F(r.at("fw_x"), r.at("fw_y"), r.at("fw_z"));
    const Eigen::Vector3d F_true = r.at("force_gain") * td.force_W;
    const double e = (F - F_true).norm();
    err2.push_back(e * e);
    if (td.contact) contact_err2.push_back(e * e);
    max_err = std::max(max_err, e);
    peak = std::max(peak, F_true.norm());
    // At rest pressed on the top, before the slide (goal straight below the
    // stylus's centred lateral position, pressed down).
    if (r.at("probe3_contact") > 0.5 && goal.z() < z_top + rho - 0.003 && std::abs(goal.x() - 1.5) < 0.002 &&
        std::abs(goal.y() - 1.9) < 0.002)
      rest_z.push_back(r.at("proxy3_z"));
    if (dbg) std::fprintf(dbg, "%.0f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d\n", r.at("t_ns"), F_true.x(), F_true.y(), F_true.z(),
                          td.proxy_W.x(), td.proxy_W.y(), td.proxy_W.z(), td.contact ? 1 : 0);
  }
  if (dbg) std::fclose(dbg);
  auto rms = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? NAN : std::sqrt(s / static_cast<double>(v.size()));
  };
  const double rest = median(rest_z);
  std::printf("rtt %d ms, loss %.0f %%: ", link.rtt_ms, 100 * link.loss);
  std::printf("truth: rest proxy z %.4f m (true top + rho %.4f m, %zu ticks); force error rms %.3f N (contact %.3f N, "
              "%zu ticks), max %.3f N, true peak %.3f N\n",
              rest, z_top + rho, rest_z.size(), rms(err2), rms(contact_err2), contact_err2.size(), max_err, peak);
  ASSERT_GT(rest_z.size(), 300u);
  EXPECT_NEAR(rest, z_top + rho, 0.005);
  ASSERT_GT(contact_err2.size(), 1500u);
  EXPECT_GT(peak, 0.3);
  EXPECT_LT(rms(contact_err2), 0.15 * peak);
}

INSTANTIATE_TEST_SUITE_P(Links, Probe3dLoopback, ::testing::Values(Link{0, 0.0}, Link{300, 0.05}),
                         [](const ::testing::TestParamInfo<Link>& i) {
                           return "Rtt" + std::to_string(i.param.rtt_ms) + "ms";
                         });
