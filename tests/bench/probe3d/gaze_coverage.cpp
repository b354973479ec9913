// Issue 24: the ROI's coverage against time with and without the active
// gaze. SIMULATION ONLY: the robot before the home scene's table (as
// deploy/configs/robot_depth.pbtxt), its SIMULATED depth camera fixed on the
// mast or on the SIMULATED pan-tilt head, and the explore-table script's
// tool path (operator/station/tool6_explorer.cpp: the 6-DoF tool's goal
// origin, key poses interpolated linearly, R frame origin (0.85, 0, 0.95))
// driving the gaze chooser (operator/model/gaze.h, no unseen candidates:
// the free-space record is another helper's) at the command rate, 200 Hz.
// Frames go through the wire encoding into a 1 cm live voxmap with the
// operator's probe ROI (a 0.6 m cube following the tool), optionally
// registered first (common/mapping/depth_registration.h); a snapshot every
// 0.2 s (the operator's 5 Hz rebuild) is scored against the scene's true
// meshes: the share of the true surface within one voxel of a rendered cell
// (robot::surface_coverage), for
//   * roi: every surface sample of the table top around the objects and of
//     the block, book and mug that either head position of the runs could
//     see (faces turned toward it, unoccluded: the same set for every run);
//   * near_tool: those within 0.15 m of the tool's goal at that time;
//   * per feature: block top / front / left side, book top / front, mug top
//     / side.
// Runs (--runs, default all): fixed (the mast camera), active (the head at
// the mast's place), fixed_high_left and active_high_left (the head 0.25 m
// left and 0.30 m higher: 1.40 m), active_reg (active with registration).
// The head's encoders carry their SIMULATED bias and noise; the fixed mast
// is exact (its pose is the odometry's alone), as in the station.
//
// Usage: gaze_coverage [out_dir] [run...]   writes out_dir/gaze_coverage.csv
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/depth_registration.h"
#include "common/mapping/depth_stream.h"
#include "common/mapping/live_voxmap.h"
#include "common/mapping/voxmap_roi.h"
#include "config_robot.pb.h"
#include "operator/model/gaze.h"
#include "operator/station/tool6_explorer.h"
#include "robot_side/sim/simulated_robot.h"
#include "robot_side/truth/scene_slice.h"
#include "robot_side/truth/voxmap_coverage.h"

namespace hm = hemm::mapping;
namespace hr = hemm::robot;
namespace ho = hemm::op;

namespace {

const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";
constexpr double kDurationS = 60.0;  // the explore-table script ends at 58.5 s
constexpr double kSnapshotS = 0.2;

struct Run {
  std::string name;
  bool pan_tilt = false, gaze = false, registration = false;
  double head_y = 0.0, head_z = 1.10;
};

// The explore-table tool goal in W at t (robot at W (1.5, 1.0) facing +y).
struct ToolPath {
  hemm::device::Trajectory tr;
  Eigen::Vector3d origin_R{0.85, 0.0, 0.95};
  Eigen::Vector3d at_W(double t) const {
    const auto& s = tr.samples;
    Eigen::Vector3d p_H = s.back().ee[0].position_H;
    for (std::size_t i = 0; i + 1 < s.size(); ++i) {
      if (t < s[i + 1].t_s) {
        const double a = std::clamp((t - s[i].t_s) / (s[i + 1].t_s - s[i].t_s), 0.0, 1.0);
        p_H = (1 - a) * s[i].ee[0].position_H + a * s[i + 1].ee[0].position_H;
        break;
      }
    }
    const Eigen::Vector3d p_R = p_H + origin_R;
    return {1.5 - p_R.y(), 1.0 + p_R.x(), p_R.z()};
  }
};

struct Feature {
  const char* name;
  std::vector<Eigen::Vector3d> samples;
};

// Which feature a surface sample of the table scene lies on (W, home.xml), or -1.
int feature_of(const Eigen::Vector3d& x) {
  constexpr double e = 0.002;
  const bool in_block_xy = x.x() > 1.70 - e && x.x() < 1.80 + e && x.y() > 1.80 - e && x.y() < 1.90 + e;
  if (in_block_xy && std::abs(x.z() - 0.85) < e) return 0;                               // block top
  if (in_block_xy && std::abs(x.y() - 1.80) < e && x.z() > 0.75) return 1;               // block front (-y)
  if (in_block_xy && std::abs(x.x() - 1.70) < e && x.z() > 0.75) return 2;               // block left (R +y: W -x)
  const bool in_book_xy = x.x() > 1.16 - e && x.x() < 1.34 + e && x.y() > 1.785 - e && x.y() < 1.915 + e;
  if (in_book_xy && std::abs(x.z() - 0.78) < e) return 3;                                // book top
  if (in_book_xy && std::abs(x.y() - 1.785) < e && x.z() > 0.75) return 4;               // book front
  const double rm = std::hypot(x.x() - 1.6, x.y() - 2.2);
  if (rm < 0.04 + e && std::abs(x.z() - 0.85) < e) return 5;                             // mug top
  if (std::abs(rm - 0.04) < e && x.z() > 0.75 + e && x.z() < 0.85 - e) return 6;         // mug side
  return -1;
}
const char* kFeatureNames[] = {"block_top", "block_front", "block_left", "book_top", "book_front", "mug_top", "mug_side"};
constexpr int kFeatures = 7;

hemm::config::RobotConfig robot_config(const Run& r) {
  hemm::config::RobotConfig c;
  c.mutable_sim()->set_start_x_m(1.5);
  c.mutable_sim()->set_start_y_m(1.0);
  c.mutable_sim()->set_start_theta_rad(std::numbers::pi / 2);
  auto& dc = *c.mutable_depth_camera();
  dc.set_enabled(true);
  dc.set_mount(r.pan_tilt ? "pan-tilt" : "mast");
  dc.set_mast_z_m(r.head_z);
  dc.set_head_y_m(r.head_y);
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string out_dir = argc > 1 ? argv[1] : ".";
  std::vector<Run> runs = {{"fixed", false, false, false, 0.0, 1.10},
                           {"active", true, true, false, 0.0, 1.10},
                           {"fixed_high_left", true, false, false, 0.25, 1.40},
                           {"active_high_left", true, true, false, 0.25, 1.40},
                           {"active_reg", true, true, true, 0.0, 1.10}};
  if (argc > 2) {
    std::set<std::string> want(argv + 2, argv + argc);
    std::erase_if(runs, [&](const Run& r) { return !want.count(r.name); });
  }

  // Truth: the table top and the objects on it.
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.8, 1.5, 0.6), Eigen::Vector3d(2.2, 2.5, 0.95));
  hr::SceneMeshes meshes;
  std::string err;
  if (!hr::load_scene_meshes(kScene, region, &meshes, &err)) {
    std::fprintf(stderr, "truth: %s\n", err.c_str());
    return 1;
  }
  std::vector<const hemm::mesh::TriangleMesh*> parts;
  for (const auto& p : meshes.parts)
    if (p.name == "table_top" || p.name == "table_block" || p.name == "table_book" || p.name == "table_mug")
      parts.push_back(&p.mesh);
  if (parts.size() != 4) {
    std::fprintf(stderr, "truth: expected the table top and three objects, found %zu\n", parts.size());
    return 1;
  }
  // The ROI: around the explored objects (the table top 5 cm round them and the objects).
  hr::VisibleSurfaceParams vsp;
  vsp.region = Eigen::AlignedBox3d(Eigen::Vector3d(1.10, 1.74, 0.745), Eigen::Vector3d(1.86, 2.26, 0.86));
  // Seen from either head position (R (0.10, 0, 1.10) and (0.10, 0.25, 1.40)): the same samples for every run.
  std::set<std::tuple<double, double, double>> seen;
  std::vector<Eigen::Vector3d> roi;
  for (const Eigen::Vector3d& o : {Eigen::Vector3d(1.5, 1.10, 1.10), Eigen::Vector3d(1.25, 1.10, 1.40)})
    for (const Eigen::Vector3d& x : hr::surface_samples_seen_from(parts, o, 0.2, 3.0, vsp))
      if (seen.insert({x.x(), x.y(), x.z()}).second) roi.push_back(x);
  std::vector<Feature> features;
  for (const char* n : kFeatureNames) features.push_back({n, {}});
  for (const Eigen::Vector3d& x : roi)
    if (const int f = feature_of(x); f >= 0) features[static_cast<std::size_t>(f)].samples.push_back(x);
  std::printf("ROI: %zu true surface samples (%.0f per m^2) visible from either head position;", roi.size(), vsp.density);
  for (const Feature& f : features) std::printf(" %s %zu,", f.name, f.samples.size());
  std::printf("\n");

  ToolPath path;
  // home.xml's route, checked against the rigid hand's limits as the station does.
  path.tr = ho::load_hand6_route(kScene, "explore-table", path.origin_R, hemm::device::rigid_hand_limits(1).ee[0]);

  const std::string csv_path = out_dir + "/gaze_coverage.csv";
  std::FILE* csv = std::fopen(csv_path.c_str(), "w");
  if (csv == nullptr) {
    std::fprintf(stderr, "cannot write %s\n", csv_path.c_str());
    return 1;
  }
  std::fprintf(csv, "run,t_s,roi,near_tool");
  for (const char* n : kFeatureNames) std::fprintf(csv, ",%s", n);
  std::fprintf(csv, ",pan_deg,tilt_deg,frames,reg_accepted,reg_frames,reg_point_err_before_mm,reg_point_err_after_mm\n");

  std::printf("\n| run | mean ROI coverage | at 10 s | at 30 s | at 60 s | mean near the tool |");
  for (const char* n : kFeatureNames) std::printf(" %s |", n);
  std::printf(" registration | cpu s |\n|---|---|---|---|---|---|");
  for (int i = 0; i < kFeatures; ++i) std::printf("---|");
  std::printf("---|---|\n");

  for (const Run& run : runs) {
    const double cpu0 = hemm::thread_cpu_s();
    const hemm::config::RobotConfig cfg = robot_config(run);
    hr::SimulatedRobot robot;
    if (auto e = robot.load(cfg, kScene)) {
      std::fprintf(stderr, "load: %s\n", e->c_str());
      return 1;
    }
    robot.set_operator_in_control(true);
    if (auto e = robot.enable_depth_camera(hr::depth_camera_params_from_config(cfg))) {
      std::fprintf(stderr, "camera: %s\n", e->c_str());
      return 1;
    }
    hm::LiveVoxmapParams vp;  // as apply_probe3d_config for 1 cm voxels
    vp.voxel_size = 0.01;
    vp.downsample_leaf = 0.005;
    vp.normal_radius = 0.05;
    vp.clear_margin = 0.015;
    vp.layers = 6;
    const hm::ProbeRoiParams roi_p{0.6, 0.15};
    std::optional<Eigen::AlignedBox3d> roi_box = hm::follow_probe(roi_p, std::nullopt, path.at_W(0.0));
    vp.roi = *roi_box;
    hm::LiveVoxmap map(vp);
    hm::DepthStreamReceiver rx;
    hm::DepthFrameRegistration reg{hm::DepthRegistrationParams{}};
    hm::RegistrationSurface surface;
    std::vector<hm::DepthChunkData> ready;
    ho::GazeChooserState gs;
    const ho::GazeParams gp;
    std::uint64_t seq = 0, frames = 0;
    double sum_roi = 0.0, sum_near = 0.0, at10 = 0, at30 = 0, at60 = 0;
    std::vector<double> sum_feat(kFeatures, 0.0), last_feat(kFeatures, 0.0);
    int scored = 0;
    const int steps = static_cast<int>(kDurationS * 1000);
    for (int k = 1; k <= steps; ++k) {
      const double t = k * 1e-3;
      const Eigen::Vector3d tool = path.at_W(t);
      if (k % 5 == 0) {
        hr::BaseArmCommand c;
        c.mode = hemm::wire::MODE_EXPLORATION;
        c.seq = ++seq;
        if (run.gaze) {
          const ho::GazeChoice g = ho::choose_gaze(gp, gs, tool, static_cast<std::int64_t>(k) * 1'000'000, {});
          c.gaze = {true, g.active, g.point_W};
        }
        if (auto e = robot.set_command(c, robot.time_ns())) {
          std::fprintf(stderr, "command: %s\n", e->c_str());
          return 1;
        }
      }
      robot.step(1);
      if (auto moved = hm::follow_probe(roi_p, roi_box, tool); moved && !moved->isApprox(*roi_box)) {
        roi_box = moved;
        map.set_roi(*roi_box);
      }
      for (const hm::DepthImage& img : robot.take_depth_images()) {
        ++frames;
        std::vector<hemm::wire::DepthChunk> wire;
        if (auto e = hm::encode_depth_chunks(img, "depth", hm::DepthStreamParams{}, &wire)) {
          std::fprintf(stderr, "encode: %s\n", e->c_str());
          return 1;
        }
        for (const auto& w : wire) {
          hm::DepthChunkData d;
          if (rx.receive(w, 0, &d) != hm::DepthStreamReceiver::Verdict::kAccepted) continue;
          if (run.registration) {
            ready.clear();
            reg.add(d, &surface, &ready);
            for (const auto& r : ready) map.integrate(r);
          } else {
            map.integrate(d);
          }
        }
      }
      if (k % static_cast<int>(kSnapshotS * 1000) != 0) continue;
      hemm::vps::Voxmap vm;
      const bool ok = !map.snapshot(&vm).has_value();
      if (ok && run.registration) hm::surface_from_voxmap(vm, &surface);
      const double cov = ok ? hr::surface_coverage(vm, roi) : 0.0;
      std::vector<Eigen::Vector3d> near;
      for (const Eigen::Vector3d& x : roi)
        if ((x - tool).norm() < 0.15) near.push_back(x);
      const double cov_near = ok && !near.empty() ? hr::surface_coverage(vm, near) : std::nan("");
      const hr::RobotStateSim st = robot.state();
      const hm::DepthRegistrationStats& rs = reg.stats();
      const double n = static_cast<double>(std::max<std::uint64_t>(rs.truth_frames, 1));
      std::fprintf(csv, "%s,%.2f,%.5f,%.5f", run.name.c_str(), t, cov, cov_near);
      for (int f = 0; f < kFeatures; ++f) {
        const auto& fs = features[static_cast<std::size_t>(f)].samples;
        last_feat[static_cast<std::size_t>(f)] = ok && !fs.empty() ? hr::surface_coverage(vm, fs) : 0.0;
        sum_feat[static_cast<std::size_t>(f)] += last_feat[static_cast<std::size_t>(f)];
        std::fprintf(csv, ",%.5f", last_feat[static_cast<std::size_t>(f)]);
      }
      std::fprintf(csv, ",%.3f,%.3f,%llu,%llu,%llu,%.3f,%.3f\n", st.head.pan_truth * 180 / std::numbers::pi,
                   st.head.present ? st.head.tilt_truth * 180 / std::numbers::pi : 35.0,
                   static_cast<unsigned long long>(frames), static_cast<unsigned long long>(rs.accepted),
                   static_cast<unsigned long long>(rs.frames), 1e3 * rs.sum_point_error_before_m / n,
                   1e3 * rs.sum_point_error_after_m / n);
      sum_roi += cov;
      if (std::isfinite(cov_near)) sum_near += cov_near;
      ++scored;
      if (std::abs(t - 10.0) < 1e-6) at10 = cov;
      if (std::abs(t - 30.0) < 1e-6) at30 = cov;
      if (std::abs(t - 60.0) < 1e-6) at60 = cov;
    }
    std::fflush(csv);
    std::printf("| %s | %.1f %% | %.1f %% | %.1f %% | %.1f %% | %.1f %% |", run.name.c_str(), 100 * sum_roi / scored,
                100 * at10, 100 * at30, 100 * at60, 100 * sum_near / scored);
    for (int f = 0; f < kFeatures; ++f) std::printf(" %.0f %% |", 100 * sum_feat[static_cast<std::size_t>(f)] / scored);
    const hm::DepthRegistrationStats& rs = reg.stats();
    if (run.registration) {
      const double n = static_cast<double>(std::max<std::uint64_t>(rs.truth_frames, 1));
      std::printf(" %llu of %llu accepted (%llu degenerate, %llu poor fit, %llu no gain, %llu step, %llu no surface); sensor error %.1f -> "
                  "%.1f mm, %.2f -> %.2f deg; point error %.1f -> %.1f mm |",
                  static_cast<unsigned long long>(rs.accepted), static_cast<unsigned long long>(rs.frames),
                  static_cast<unsigned long long>(rs.degenerate), static_cast<unsigned long long>(rs.poor_fit), static_cast<unsigned long long>(rs.no_gain),
                  static_cast<unsigned long long>(rs.step_too_large), static_cast<unsigned long long>(rs.no_surface),
                  1e3 * rs.sum_error_before_m / n, 1e3 * rs.sum_error_after_m / n,
                  rs.sum_error_before_rad / n * 180 / std::numbers::pi, rs.sum_error_after_rad / n * 180 / std::numbers::pi,
                  1e3 * rs.sum_point_error_before_m / n, 1e3 * rs.sum_point_error_after_m / n);
    } else {
      std::printf(" - |");
    }
    std::printf(" %.0f |\n", hemm::thread_cpu_s() - cpu0);
    std::fflush(stdout);
  }
  std::fclose(csv);
  std::printf("\nmeans over the %.0f s at every %.1f s snapshot; per feature: mean over time. Wrote %s\n", kDurationS,
              kSnapshotS, csv_path.c_str());
  return 0;
}
