// The live views (issue 14) under Xvfb with the real stations on loopback:
// hemm-robot (SIMULATED robot at the scene's start pose) and hemm-operator
// (SIMULATED Omni, script probe-cylinder: the robot stays still, the probe
// slides round the bin), twice back to back -- without the view, then with
// the operator's window (--view) writing PNGs of it and the robot station's
// view writing PNGs, both with a fixed top-down camera.
//
// Pixels: in each operator picture, the W points where things must be are
// projected with a pinhole camera built here from the picture's camera text
// (lookat, distance, azimuth, elevation, fovy): the robot's footprint (blue)
// at the pose the servo task rendered with on the picture's tick (the 1 kHz
// world log's row of that tick), the proxy (green) at that row's proxy,
// and the map (orange walls) along surfaces of the scene file that the laser
// sees from the start (MuJoCo's own geometry of deploy/scenes/home.xml), with
// free floor between them. The robot station's picture has the robot's chassis
// at the scene's start pose.
//
// Timing: the servo loop's misses and period with the view on are compared
// with the run without it (wide margins: a shared 2-core VM); software
// OpenGL (llvmpipe, one thread) renders at a lowered priority.
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <numbers>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <thread>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "common/sim/mujoco_owner.h"
#include "common/view/png_io.h"
#include "tests/integration/view/view_test_support.h"
#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

namespace hemm::test {
namespace {

using namespace std::chrono_literals;

const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";
const std::string kConfigs = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/";
const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";
constexpr double kRunS = 7.0;

// Colour classes of the views' palettes (operator/view/operator_scene.h) as
// they come out lit from above.
bool is_blue(const std::uint8_t* p) { return p[2] > 180 && p[0] < 100 && p[1] < 160; }
bool is_green(const std::uint8_t* p) { return p[1] > 170 && p[0] < 110 && p[2] < 110; }
bool is_orange(const std::uint8_t* p) { return p[0] > 140 && p[1] > 50 && p[1] < 210 && p[2] < 70 && p[0] > p[1] + 40; }
// Fitted map surfaces (shape completion): teal, green above blue (the
// received pose's cyan has blue above green).
bool is_teal(const std::uint8_t* p) { return p[0] < 110 && p[1] > 90 && p[1] >= p[2] && p[2] > p[0] + 40; }
// A map surface: raw laser (orange) or fitted (teal).
bool is_map_surface(const std::uint8_t* p) { return is_orange(p) || is_teal(p); }
bool is_red(const std::uint8_t* p) { return p[0] > 120 && p[1] < 70 && p[2] < 70; }

// The scene's surfaces from MuJoCo (not from hemm's code): a geom's face.
struct SceneFaces {
  double mid_s_west_x = NAN, mid_s_y0 = NAN, mid_s_y1 = NAN;   // wall_mid_s west face
  double sofa_front_y = NAN, sofa_x0 = NAN, sofa_x1 = NAN;     // sofa seat, face toward the robot
  double bin_x = NAN, bin_y = NAN, bin_r = NAN;
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
};
SceneFaces scene_faces() {
  SceneFaces f;
  hemm::sim::MujocoOwner mj;
  try {
    mj = hemm::sim::MujocoOwner::from_file(kScene);
  } catch (const std::exception& e) {
    ADD_FAILURE() << "cannot load the scene: " << e.what();
    return f;
  }
  mjModel* m = mj.m();
  mjData* d = mj.d();
  mj_forward(m, d);
  auto geom = [&](const char* name) {
    const int g = mj_name2id(m, mjOBJ_GEOM, name);
    EXPECT_GE(g, 0) << name;
    return g;
  };
  const int w = geom("wall_mid_s"), s = geom("sofa_seat"), b = geom("bin");
  const int site = mj_name2id(m, mjOBJ_SITE, "robot_start");
  if (w >= 0 && s >= 0 && b >= 0 && site >= 0) {
    f.mid_s_west_x = d->geom_xpos[3 * w] - m->geom_size[3 * w];
    f.mid_s_y0 = d->geom_xpos[3 * w + 1] - m->geom_size[3 * w + 1];
    f.mid_s_y1 = d->geom_xpos[3 * w + 1] + m->geom_size[3 * w + 1];
    f.sofa_front_y = d->geom_xpos[3 * s + 1] + m->geom_size[3 * s + 1];
    f.sofa_x0 = d->geom_xpos[3 * s] - m->geom_size[3 * s];
    f.sofa_x1 = d->geom_xpos[3 * s] + m->geom_size[3 * s];
    f.bin_x = d->geom_xpos[3 * b];
    f.bin_y = d->geom_xpos[3 * b + 1];
    f.bin_r = m->geom_size[3 * b];
    f.start = Eigen::Vector2d(d->site_xpos[3 * site], d->site_xpos[3 * site + 1]);
  }
  return f;
}

struct StationRun {
  bool ok = false;
  std::string dir, logs;
  double ticks = NAN, misses = NAN, period_median_us = NAN, period_p99_us = NAN, wake_p99_us = NAN;
};

StationRun run_stations(const std::string& dir, bool view) {
  StationRun r;
  r.dir = dir;
  const int tcp = free_port(), udp = free_port();
  std::vector<std::string> robot_args = {kBin + "hemm-robot", "--config", kConfigs + "robot.pbtxt", "--listen",
                                         "127.0.0.1", "--session-port", std::to_string(tcp), "--stream-port",
                                         std::to_string(udp), "--duration", std::to_string(kRunS + 15)};
  std::vector<std::string> op_args = {kBin + "hemm-operator", "--config", kConfigs + "operator.pbtxt", "--robot",
                                      "127.0.0.1", "--session-port", std::to_string(tcp), "--duration",
                                      std::to_string(kRunS), "--script", "probe-cylinder", "--log", dir + "/op.csv",
                                      "--station-json", dir + "/station.json"};
  if (view) {
    for (const char* a : {"--view-png", "robot_png", "--view-interval", "2", "--view-top", "0.5,-0.5,5"})
      robot_args.push_back(a == std::string("robot_png") ? dir + "/robot_png" : a);
    for (const char* a : {"--view", "--view-png", "op_png", "--view-interval", "1", "--view-top", "1,-0.5,6"})
      op_args.push_back(a == std::string("op_png") ? dir + "/op_png" : a);
  }
  ChildProcess robot(robot_args, dir + "/robot.out", dir + "/robot.err");
  auto logs = [&] {
    return "--- robot\n" + read_file(dir + "/robot.err") + "--- operator\n" + read_file(dir + "/op.err") +
           read_file(dir + "/op.out");
  };
  if (!wait_for_text(dir + "/robot.err", "event=listening", 15s)) {
    r.logs = logs();
    return r;
  }
  ChildProcess op(op_args, dir + "/op.out", dir + "/op.err");
  const auto rc = op.wait(std::chrono::milliseconds(static_cast<int>((kRunS + 30) * 1000)));
  robot.signal(SIGTERM);
  const auto rrc = robot.wait(20s);
  r.logs = logs();
  if (!rc || *rc != 0 || !rrc || *rrc != 0) {
    ADD_FAILURE() << "operator exit " << (rc ? std::to_string(*rc) : "timeout") << ", robot exit "
                  << (rrc ? std::to_string(*rrc) : "timeout") << "\n"
                  << r.logs;
    return r;
  }
  const std::string sj = read_file(dir + "/station.json");
  auto in = [&](const std::string& section, const std::string& key) {
    const std::size_t at = sj.find("\"" + section + "\"");
    return at == std::string::npos ? std::optional<double>() : json_number(sj.substr(at), key);
  };
  r.ticks = json_number(sj, "ticks").value_or(NAN);
  r.misses = json_number(sj, "misses").value_or(NAN);
  r.period_median_us = in("period_us", "median").value_or(NAN);
  r.period_p99_us = in("period_us", "p99").value_or(NAN);
  r.wake_p99_us = in("wake_latency_us", "p99").value_or(NAN);
  r.ok = std::isfinite(r.ticks) && std::isfinite(r.misses);
  return r;
}

TEST(LiveView, UnderXvfbTheViewShowsRobotMapAndProxyWhereTheyAreAndTheServoKeepsItsTiming) {
  const std::string dir = make_temp_dir();
  std::unique_ptr<Xvfb> xvfb;
  const auto display_error = start_test_display(dir, &xvfb);
  ASSERT_FALSE(display_error) << *display_error;

  std::filesystem::create_directories(dir + "/off");
  std::filesystem::create_directories(dir + "/on");
  const StationRun off = run_stations(dir + "/off", false);
  const StationRun on = run_stations(dir + "/on", true);
  ASSERT_TRUE(off.ok) << off.logs;
  ASSERT_TRUE(on.ok) << on.logs;

  // ---- timing: the view on against the run without it
  std::printf("servo loop   ticks  misses  period median / p99 us  wake p99 us\n");
  std::printf("view off  %8.0f %7.0f  %8.1f / %8.1f  %8.1f\n", off.ticks, off.misses, off.period_median_us,
              off.period_p99_us, off.wake_p99_us);
  std::printf("view on   %8.0f %7.0f  %8.1f / %8.1f  %8.1f\n", on.ticks, on.misses, on.period_median_us,
              on.period_p99_us, on.wake_p99_us);
#ifndef HEMM_SANITIZE  // the instrumentation makes wall-clock bounds meaningless
  for (const StationRun* r : {&off, &on}) {
    EXPECT_GT(r->ticks, 0.8 * kRunS * 1000);
    EXPECT_NEAR(r->period_median_us, 1000.0, 50.0);
  }
  // No more misses with the view than without, within a wide margin for a
  // shared VM: twice the run without it plus 0.5 % of the ticks.
  EXPECT_LE(on.misses, 2.0 * off.misses + 0.005 * on.ticks);
#endif

  // ---- the operator's pictures
  const SceneFaces scene = scene_faces();
  ASSERT_TRUE(std::isfinite(scene.mid_s_west_x));
  const CsvColumns world = read_csv_columns(on.dir + "/op.csv.world.csv");
  ASSERT_TRUE(world.ok) << world.error;
  const std::vector<std::string> pictures = pngs_in(on.dir + "/op_png");
  ASSERT_GE(pictures.size(), 4u) << on.logs;
  int checked = 0, robot_ok = 0, proxy_ok = 0, map_ok = 0;
  for (const std::string& path : pictures) {
    view::Image img;
    view::TextChunks text;
    ASSERT_FALSE(read_png(path, &img, &text)) << path;
    const auto cam_text = view::find_text(text, "hemm:camera");
    const auto tick_text = view::find_text(text, "hemm:tick_ns");
    ASSERT_TRUE(cam_text && tick_text) << path;
    const auto cam = Camera::from_text(*cam_text, img.width, img.height);
    ASSERT_TRUE(cam) << *cam_text;
    const double tick_ns = std::stod(*tick_text);
    // The tick the picture shows, in the servo's world log.
    const auto& t = world["t_ns"];
    const auto it = std::find(t.begin(), t.end(), tick_ns);
    if (tick_ns < 0 || it == t.end()) continue;  // before the first tick / after the log ended
    const std::size_t row = static_cast<std::size_t>(it - t.begin());
    if (world["state_stamp_ns"][row] < 0) continue;  // no robot state yet: nothing to place
    ++checked;
    SCOPED_TRACE(path);

    // Robot: the footprint's top (z 0.26 m) blue at four points inside it
    // (off its centre line, where the heading arrow is), floor beside it.
    const Eigen::Vector2d c(world["robot_x"][row], world["robot_y"][row]);
    const double th = world["robot_theta"][row];
    const Eigen::Rotation2Dd R(th);
    bool robot = true;
    for (const Eigen::Vector2d& q : {Eigen::Vector2d(0.12, 0.13), Eigen::Vector2d(-0.15, 0.13),
                                     Eigen::Vector2d(-0.15, -0.13), Eigen::Vector2d(0.12, -0.13)}) {
      const Eigen::Vector2d p = c + R * q;
      robot = robot && near(img, cam->project(Eigen::Vector3d(p.x(), p.y(), 0.26)), 1, is_blue);
    }
    const Eigen::Vector2d beside = c + R * Eigen::Vector2d(0.0, 0.55);
    robot = robot && !near(img, cam->project(Eigen::Vector3d(beside.x(), beside.y(), 0.0)), 2, is_blue);
    robot_ok += robot;

    // Proxy: a green disc at the logged proxy (drawn at 0.35 m).
    const Eigen::Vector3d proxy(world["proxy_x"][row], world["proxy_y"][row], 0.35);
    proxy_ok += near(img, cam->project(proxy), 2, is_green);

    // Map: orange (raw) or teal (fitted) walls (0.25 m high, 0.04 m thick behind the face) along the
    // west face of wall_mid_s and the sofa's front face, where the laser
    // sees them from the start; free floor half a metre in front of both.
    int hits = 0, samples = 0, false_hits = 0;
    for (double y = -2.0; y <= -0.8; y += 0.2, ++samples) {
      hits += near(img, cam->project(Eigen::Vector3d(scene.mid_s_west_x + 0.02, y, 0.25)), 3, is_map_surface);
      false_hits += near(img, cam->project(Eigen::Vector3d(scene.mid_s_west_x - 0.5, y, 0.0)), 1, is_map_surface);
    }
    for (double x = 0.3; x <= 1.7; x += 0.2, ++samples) {
      hits += near(img, cam->project(Eigen::Vector3d(x, scene.sofa_front_y - 0.02, 0.25)), 3, is_map_surface);
      false_hits += near(img, cam->project(Eigen::Vector3d(x, scene.sofa_front_y + 0.5, 0.0)), 1, is_map_surface);
    }
    const bool map = hits >= 0.8 * samples && false_hits == 0;
    if (!map) std::printf("%s: map %d/%d hits, %d on free floor\n", path.c_str(), hits, samples, false_hits);
    map_ok += map;
  }
  std::printf("operator pictures: %zu, checked %d: robot %d, proxy %d, map %d\n", pictures.size(), checked,
              robot_ok, proxy_ok, map_ok);
  ASSERT_GE(checked, 3);
  EXPECT_EQ(robot_ok, checked);
  EXPECT_EQ(proxy_ok, checked);
  // The map builds up over the first scans: all but the first picture.
  EXPECT_GE(map_ok, checked - 1);

  // ---- the robot station's picture: the chassis at the scene's start pose
  view::Image img;
  view::TextChunks text;
  ASSERT_FALSE(read_png(on.dir + "/robot_png/view_last.png", &img, &text)) << on.logs;
  const auto cam = Camera::from_text(view::find_text(text, "hemm:camera").value_or(""), img.width, img.height);
  ASSERT_TRUE(cam);
  // The rear half of the chassis top (z 0.26; the laser looks forward).
  EXPECT_TRUE(near(img, cam->project(Eigen::Vector3d(scene.start.x() - 0.12, scene.start.y() + 0.06, 0.26)), 1, is_red));
  EXPECT_FALSE(near(img, cam->project(Eigen::Vector3d(scene.start.x() - 0.7, scene.start.y(), 0.0)), 2, is_red));
}

}  // namespace
}  // namespace hemm::test
