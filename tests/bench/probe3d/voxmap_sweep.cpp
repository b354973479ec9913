// Issue 13, "model only what the scene needs" and "how it falls as the robot
// sees more": the live voxmap from the SIMULATED mast depth camera of the
// home scene (robot standing before the table with the block, book and mug),
// against the scene's exact geometry (SIMULATION ONLY ground truth: the MJCF's
// geoms meshed by robot::load_scene_meshes, voxelised exactly at 2.5 mm).
//
// One scripted probe path (goal points in W at 1 kHz) presses the 3-DoF
// point probe onto the table top, the -y and -x sides and the top of the
// block, the +x side, the top and the -y side of the book. The force error is
// the same probe (same params, same path) on the live voxmap against on the
// truth voxmap, over the ticks where either touches: RMS and max.
//
// Part 1, the sweep: voxel size {5, 10, 20} mm x region of interest {cube
// of 0.3 m and of 0.6 m around the probe (mapping::follow_probe, margin a
// quarter of the edge), ahead of the robot (the operator's shipped box)}.
// Frames are integrated as they come (15 Hz, 12 chunks each), the ROI
// follows the live probe, a rebuild runs at most 5 times a second and its
// snapshot reaches the probe only once the rebuild's measured CPU time has
// passed (as on the voxmap thread); the probe path starts after 1.5 s of
// frames. Times are thread CPU times (the machine is shared).
//
// Part 2, coverage against time: 1 cm voxels ahead of the robot, every
// frame of the first 3 s integrated with 0 %, 5 % and 20 % of the chunks
// dropped at random; after each frame, the snapshot's coverage of the truly
// visible surface (robot::surface_coverage: samples the camera sees within
// one voxel of a rendered cell) and the force error along the whole path on
// that snapshot. Written to <out>/voxmap_coverage.csv.
//
// Usage: voxmap_sweep [out_dir]   (default: the current directory)
#include <algorithm>
#include <cmath>
#include <numbers>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/point_probe.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mapping/live_voxmap.h"
#include "common/mapping/voxmap_roi.h"
#include "common/math/workspace_maps.h"
#include "robot_side/truth/scene_slice.h"
#include "robot_side/truth/voxmap_coverage.h"
#include "tests/robot_side/sim/mast_frames.h"

namespace hm = hemm::mapping;
namespace hr = hemm::robot;
namespace vps = hemm::vps;
namespace ht = hemm::test;

namespace {

constexpr double kRho = 0.01;      // the probe's radius (probe_3d default)
constexpr double kPress = 0.012;   // how far the goal goes past a surface
constexpr double kFill = 1.5;      // s of frames before the path starts

// What a stretch of the path touches: nothing, a top, a side the mast camera
// faces (the -y sides), a side it sees nearly edge-on (the block's -x and
// the book's +x sides, 75-80 degrees from their normals).
enum Face { kAir = 0, kTop = 1, kFacing = 2, kGrazing = 3 };

struct Path {
  std::vector<Eigen::Vector3d> goal;  // W, one per 1 kHz tick
  std::vector<Face> face;
  std::vector<std::string> surface;   // which one ("" in the air)
};

// The path: waypoints (x, y, z in W), the seconds to reach each from the one
// before (sampled at 1 kHz) and what that stretch touches. Tops: the goal
// kPress below the contact height (top + rho); sides: kPress past the face's
// contact plane.
Path probe_path() {
  struct Wp {
    double x, y, z, s;
    Face face;
    const char* surface;  // "" in the air
  };
  const double top = 0.75, block = 0.85, book = 0.78;
  const double side_z = 0.80, book_side_z = 0.767;  // probe centres beside the block / the book
  const Wp w[] = {
      {1.50, 1.70, 0.80, 0.0, kAir, ""},
      {1.50, 1.70, 0.80, 0.3, kAir, ""},                              // hold above the table
      {1.50, 1.70, top + kRho - kPress, 0.5, kTop, "table top"},      // press onto the table top
      {1.62, 1.70, top + kRho - kPress, 1.2, kTop, "table top"},      // slide along it
      {1.62, 1.70, side_z, 0.3, kTop, "table top"},                   // lift
      {1.73, 1.74, side_z, 0.6, kAir, ""},                            // before the block's -y face (y 1.80)
      {1.73, 1.80 - kRho + kPress, side_z, 0.5, kFacing, "block -y side"},// press into it
      {1.77, 1.80 - kRho + kPress, side_z, 0.8, kFacing, "block -y side"},// slide along it
      {1.77, 1.74, side_z, 0.3, kFacing, "block -y side"},            // back off
      {1.77, 1.74, 0.90, 0.4, kAir, ""},                              // up
      {1.75, 1.83, 0.90, 0.5, kAir, ""},                              // over the block's top
      {1.75, 1.83, block + kRho - kPress, 0.5, kTop, "block top"},    // press onto it
      {1.75, 1.87, block + kRho - kPress, 0.8, kTop, "block top"},    // slide along it
      {1.75, 1.87, 0.90, 0.3, kTop, "block top"},                     // lift
      {1.64, 1.85, 0.90, 0.6, kAir, ""},                              // before the block's -x face (x 1.70)
      {1.64, 1.85, side_z, 0.5, kAir, ""},                            // down
      {1.70 - kRho + kPress, 1.85, side_z, 0.5, kGrazing, "block -x side"},// press into it
      {1.70 - kRho + kPress, 1.88, side_z, 0.6, kGrazing, "block -x side"},// slide along it
      {1.64, 1.88, side_z, 0.3, kGrazing, "block -x side"},           // back off
      {1.64, 1.88, 0.86, 0.3, kAir, ""},                              // up
      {1.40, 1.85, 0.86, 1.0, kAir, ""},                              // before the book's +x face (x 1.34)
      {1.40, 1.85, book_side_z, 0.5, kAir, ""},                       // down beside it
      {1.34 + kRho - kPress, 1.85, book_side_z, 0.5, kGrazing, "book +x side"},// press into it
      {1.34 + kRho - kPress, 1.82, book_side_z, 0.6, kGrazing, "book +x side"},// slide along it
      {1.40, 1.82, book_side_z, 0.3, kGrazing, "book +x side"},       // back off
      {1.40, 1.82, 0.83, 0.3, kAir, ""},                              // up
      {1.25, 1.83, 0.83, 0.6, kAir, ""},                              // over the book's top
      {1.25, 1.83, book + kRho - kPress, 0.5, kTop, "book top"},      // press onto it
      {1.20, 1.87, book + kRho - kPress, 0.8, kTop, "book top"},      // slide along it
      {1.20, 1.87, 0.83, 0.3, kTop, "book top"},                      // lift
      {1.25, 1.74, 0.83, 0.6, kAir, ""},                              // before the book's -y face (y 1.785)
      {1.25, 1.74, book_side_z, 0.5, kAir, ""},                       // down
      {1.25, 1.785 - kRho + kPress, book_side_z, 0.5, kFacing, "book -y side"},// press into it
      {1.30, 1.785 - kRho + kPress, book_side_z, 0.6, kFacing, "book -y side"},// slide along it
      {1.30, 1.74, book_side_z, 0.3, kFacing, "book -y side"},        // back off
      {1.30, 1.74, 0.85, 0.4, kAir, ""},                              // up
  };
  Path out;
  for (std::size_t i = 1; i < std::size(w); ++i) {
    const Eigen::Vector3d a(w[i - 1].x, w[i - 1].y, w[i - 1].z), b(w[i].x, w[i].y, w[i].z);
    const int n = static_cast<int>(std::lround(w[i].s * 1000.0));
    for (int k = 1; k <= n; ++k) {
      out.goal.push_back(a + (b - a) * (static_cast<double>(k) / n));
      out.face.push_back(w[i].face);
      out.surface.emplace_back(w[i].surface);
    }
  }
  return out;
}

vps::PointProbeParams probe_params() {
  vps::PointProbeParams p;
  p.force = hemm::haptics::ProxyModel{};  // the operator's proxy model (OperatorTaskParams::proxy)
  p.force.probe_radius = kRho;
  return p;
}

// W metres per device metre: probe_3d range_m 0.6 over the Omni's half extent.
double probe_scale() { return 0.6 / hemm::math::horizontal_half_extent(hemm::math::DeviceWorkspace{}); }

struct Truth {
  std::vector<Eigen::Vector3d> force, proxy;
  std::vector<char> contact;
  double peak = 0.0;
};

// Force error over the ticks where either probe touches: all of them and
// by what the path touches there.
struct ForceError {
  double sum2[4] = {0, 0, 0, 0};
  std::size_t n[4] = {0, 0, 0, 0};
  double max = 0.0;
  // By surface, in path order: name, sum of squares, ticks, max.
  struct Surface {
    std::string name;
    double sum2 = 0.0, max = 0.0;
    std::size_t n = 0;
  };
  std::vector<Surface> surfaces;
  void add(Face f, double e, const std::string& surface = {}) {
    sum2[f] += e * e;
    ++n[f];
    max = std::max(max, e);
    if (surface.empty()) return;
    if (surfaces.empty() || surfaces.back().name != surface) surfaces.push_back({surface});
    surfaces.back().sum2 += e * e;
    surfaces.back().max = std::max(surfaces.back().max, e);
    ++surfaces.back().n;
  }
  std::size_t ticks() const { return n[0] + n[1] + n[2] + n[3]; }
  double rms(int f) const { return n[f] > 0 ? std::sqrt(sum2[f] / static_cast<double>(n[f])) : 0.0; }
  double rms() const {
    const double s = sum2[0] + sum2[1] + sum2[2] + sum2[3];
    return ticks() > 0 ? std::sqrt(s / static_cast<double>(ticks())) : 0.0;
  }
};

// The live probe along the path on one snapshot (may be null) against the
// truth; with `dump`, one CSV row per tick (goal, live and true proxy and force).
ForceError path_error(const vps::Voxmap* vm, const Path& path, const Truth& truth, std::FILE* dump = nullptr) {
  const auto pp = probe_params();
  const double scale = probe_scale();
  vps::PointProbeData d;
  vps::point_probe_reset(d, path.goal.front());
  ForceError e;
  for (std::size_t i = 0; i < path.goal.size(); ++i) {
    vps::point_probe_tick(pp, vm, d, path.goal[i], scale);
    if (dump != nullptr) {
      const Eigen::Vector3d &g = path.goal[i], &tp = truth.proxy[i], &tf = truth.force[i];
      std::fprintf(dump, "%zu,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d\n", i, g.x(),
                   g.y(), g.z(), d.proxy_W.x(), d.proxy_W.y(), d.proxy_W.z(), d.force_W.x(), d.force_W.y(), d.force_W.z(),
                   d.contact ? 1 : 0, tp.x(), tp.y(), tp.z(), tf.x(), tf.y(), tf.z(), truth.contact[i]);
    }
    if (!d.contact && truth.contact[i] == 0) continue;
    e.add(path.face[i], (d.force_W - truth.force[i]).norm(), path.surface[i]);
  }
  return e;
}

hm::LiveVoxmapParams voxmap_params(double s, const Eigen::AlignedBox3d& roi) {
  // As the operator sets them (apply_probe3d_config).
  hm::LiveVoxmapParams vp;
  vp.voxel_size = s;
  vp.downsample_leaf = 0.5 * s;
  vp.normal_radius = std::max(0.05, 2.5 * s);
  vp.clear_margin = std::max(vp.clear_margin, 1.5 * s);
  vp.roi = roi;
  return vp;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const std::string out_dir = argc > 1 ? argv[1] : ".";
  const Path path = probe_path();
  const double path_s = static_cast<double>(path.goal.size()) * 1e-3;

  // Truth: the table top and the objects on it, voxelised exactly.
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.8, 1.5, 0.6), Eigen::Vector3d(2.2, 2.5, 0.95));
  hr::SceneMeshes meshes;
  std::string err;
  if (!hr::load_scene_meshes(ht::kHomeScene, region, &meshes, &err)) {
    std::fprintf(stderr, "truth: %s\n", err.c_str());
    return 1;
  }
  hemm::mesh::TriangleMesh scene;
  std::vector<const hemm::mesh::TriangleMesh*> parts;  // the table top first (see load_scene_meshes' order)
  std::vector<std::string> meshes_names;
  for (const auto& p : meshes.parts) {
    if (p.name != "table_top" && p.name != "table_block" && p.name != "table_book" && p.name != "table_mug") continue;
    hemm::mesh::append_mesh(&scene, p.mesh);
    parts.push_back(&p.mesh);
    meshes_names.push_back(p.name);
  }
  if (parts.size() != 4 || meshes_names[0] != "table_top") {
    std::fprintf(stderr, "truth: expected the table top and three objects, found %zu\n", parts.size());
    return 1;
  }
  vps::VoxmapParams tvp;
  tvp.voxel_size = 0.0025;
  tvp.layers_out = tvp.layers_in = 8;
  tvp.roi = Eigen::AlignedBox3d(Eigen::Vector3d(1.05, 1.6, 0.65), Eigen::Vector3d(1.95, 2.1, 0.95));
  vps::Voxmap truth_vm;
  if (auto e = vps::build_voxmap(scene, tvp, &truth_vm, nullptr)) {
    std::fprintf(stderr, "truth voxmap: %s\n", e->message.c_str());
    return 1;
  }
  Truth truth;
  {
    const auto pp = probe_params();
    vps::PointProbeData d;
    vps::point_probe_reset(d, path.goal.front());
    for (const Eigen::Vector3d& g : path.goal) {
      vps::point_probe_tick(pp, &truth_vm, d, g, probe_scale());
      truth.force.push_back(d.force_W);
      truth.proxy.push_back(d.proxy_W);
      truth.contact.push_back(d.contact ? 1 : 0);
      truth.peak = std::max(truth.peak, d.force_W.norm());
    }
  }
  std::size_t truth_contacts = 0;
  for (char c : truth.contact) truth_contacts += c != 0 ? 1 : 0;
  std::printf("path: %zu ticks (%.1f s), truth in contact %zu ticks, true peak %.3f N\n", path.goal.size(), path_s,
              truth_contacts, truth.peak);

  // SIMULATED mast frames for the whole run.
  std::vector<ht::MastChunk> chunks;
  if (auto e = ht::simulate_mast_chunks(static_cast<int>(std::lround((kFill + path_s) * 1000.0)) + 1, &chunks)) {
    std::fprintf(stderr, "frames: %s\n", e->c_str());
    return 1;
  }
  const double run_s = kFill + path_s;
  std::printf("%zu chunks over %.1f s (%.0f chunks/s)\n", chunks.size(), run_s, static_cast<double>(chunks.size()) / run_s);
  const double chunk_rate = static_cast<double>(chunks.size()) / run_s;

  // ---- Part 1: voxel size x ROI ----
  // The operator's shipped box ahead of the robot, placed at the robot (W
  // (1.5, 1.0), facing +y): R x 0.25..1.6, |y| <= 0.7, z 0.3..1.3.
  const Eigen::AlignedBox3d ahead(Eigen::Vector3d(0.8, 1.25, 0.3), Eigen::Vector3d(2.2, 2.6, 1.3));
  struct Roi {
    const char* name;
    double size;  // 0: ahead of the robot
  };
  const Roi rois[] = {{"probe 0.3 m", 0.3}, {"probe 0.6 m", 0.6}, {"ahead 1.4x1.35x1.0 m", 0.0}};
  std::printf("\n| ROI | voxel | peak cells | peak cells kB | peak snapshot kB | integrate per chunk | %% of a core | "
              "rebuild median / max | ROI moves | force error rms: tops / facing sides / edge-on sides [N] | all: rms / max (contact ticks) |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  const bool coverage_only = std::getenv("VOXMAP_SWEEP_COVERAGE_ONLY") != nullptr;  // part 2 alone
  for (const Roi& roi : rois) {
    if (coverage_only) break;
    for (double s : {0.005, 0.01, 0.02}) {
      const hm::ProbeRoiParams prp{roi.size, 0.25 * roi.size};
      const bool follow = roi.size > 0.0;
      std::optional<Eigen::AlignedBox3d> box =
          follow ? hm::follow_probe(prp, std::nullopt, path.goal.front()) : std::optional<Eigen::AlignedBox3d>(ahead);
      hm::LiveVoxmap map(voxmap_params(s, *box));
      std::shared_ptr<vps::Voxmap> live, pending;
      double pending_at = 0.0, next_build = 0.0;
      bool dirty = false;
      double integrate_cpu = 0.0;
      std::size_t integrated = 0, peak_cells = 0, peak_bytes = 0, peak_snap = 0, moves = 0;
      std::vector<double> builds;
      const auto pp = probe_params();
      vps::PointProbeData d;
      vps::point_probe_reset(d, path.goal.front());
      ForceError fe;
      std::size_t next_chunk = 0;
      const auto ticks = static_cast<std::size_t>(std::lround(run_s * 1000.0));
      for (std::size_t tick = 0; tick < ticks; ++tick) {
        const double t = static_cast<double>(tick) * 1e-3;
        // The ROI follows the probe's proxy (the servo's newest).
        if (follow) {
          const auto next = hm::follow_probe(prp, box, d.proxy_W);
          if (next && (next->min() != box->min() || next->max() != box->max())) {
            box = next;
            map.set_roi(*box);
            dirty = true;
            ++moves;
          }
        }
        while (next_chunk < chunks.size() && chunks[next_chunk].t_s <= t) {
          const double c0 = hemm::thread_cpu_s();
          map.integrate(chunks[next_chunk].chunk);
          integrate_cpu += hemm::thread_cpu_s() - c0;
          ++integrated;
          ++next_chunk;
          dirty = true;
        }
        peak_cells = std::max(peak_cells, map.cells());
        peak_bytes = std::max(peak_bytes, map.memory_bytes());
        if (pending && t >= pending_at) live = std::move(pending);
        if (!pending && dirty && t >= next_build) {
          auto vm = std::make_shared<vps::Voxmap>();
          const double b0 = hemm::thread_cpu_s();
          const bool ok = !map.snapshot(vm.get());
          const double b = hemm::thread_cpu_s() - b0;
          builds.push_back(b);
          dirty = false;
          next_build = t + 0.2;
          if (ok) {
            peak_snap = std::max(peak_snap, vm->memory_bytes());
            pending = std::move(vm);
            pending_at = t + b;  // the voxmap thread's rebuild takes this long
          }
        }
        if (t + 1e-9 < kFill) {
          // Before the path: the probe rests where the path starts (above the table).
          vps::point_probe_tick(pp, live.get(), d, path.goal.front(), probe_scale());
          continue;
        }
        const std::size_t i = tick - static_cast<std::size_t>(std::lround(kFill * 1000.0));
        if (i >= path.goal.size()) break;
        vps::point_probe_tick(pp, live.get(), d, path.goal[i], probe_scale());
        if (!d.contact && truth.contact[i] == 0) continue;
        fe.add(path.face[i], (d.force_W - truth.force[i]).norm());
      }
      const double per_chunk_ms = integrate_cpu * 1e3 / static_cast<double>(std::max<std::size_t>(integrated, 1));
      std::printf("| %s | %.0f mm | %zu | %.0f | %.0f | %.2f ms | %.0f %% | %.0f / %.0f ms | %zu | %.3f / %.3f / %.3f | %.3f / %.3f N (%zu) |\n",
                  roi.name, s * 1e3, peak_cells, static_cast<double>(peak_bytes) / 1e3,
                  static_cast<double>(peak_snap) / 1e3, per_chunk_ms, per_chunk_ms * chunk_rate / 10.0,
                  median(builds) * 1e3, builds.empty() ? 0.0 : *std::max_element(builds.begin(), builds.end()) * 1e3,
                  moves, fe.rms(kTop), fe.rms(kFacing), fe.rms(kGrazing), fe.rms(), fe.max, fe.ticks());
      std::fflush(stdout);
    }
  }

  // ---- Part 2: coverage and force error against time, with loss ----
  const hm::DepthChunkData& first = chunks.front().chunk;
  const Eigen::Isometry3d T_W_S = first.has_truth ? first.T_W_S_truth : first.T_W_S;
  {
    // How the camera sees the faces the path touches: the angle between each
    // face's normal and the direction to the camera, at the face's centre.
    const Eigen::Vector3d o = T_W_S.translation();
    struct F {
      const char* name;
      Eigen::Vector3d c, n;
    };
    const F faces[] = {{"block top", {1.75, 1.85, 0.85}, Eigen::Vector3d::UnitZ()},
                       {"block -y", {1.75, 1.80, 0.80}, -Eigen::Vector3d::UnitY()},
                       {"block -x", {1.70, 1.85, 0.80}, -Eigen::Vector3d::UnitX()},
                       {"book top", {1.25, 1.85, 0.78}, Eigen::Vector3d::UnitZ()},
                       {"book +x", {1.34, 1.85, 0.765}, Eigen::Vector3d::UnitX()},
                       {"book -y", {1.25, 1.785, 0.765}, -Eigen::Vector3d::UnitY()}};
    std::printf("\ncamera at W (%.3f, %.3f, %.3f); faces seen at (from their normal):", o.x(), o.y(), o.z());
    for (const F& f : faces)
      std::printf(" %s %.0f deg,", f.name, std::acos(f.n.dot((o - f.c).normalized())) * 180.0 / std::numbers::pi);
    std::printf("\n");
  }
  hr::VisibleSurfaceParams vsp;
  vsp.region = ahead;
  const std::vector<Eigen::Vector3d> visible = hr::visible_surface_samples(parts, first.K, T_W_S, vsp);
  // The samples of each part (by its bounds: the objects stand on the top,
  // whose bounds end at z 0.75 where their hidden bottoms are).
  std::vector<std::vector<Eigen::Vector3d>> visible_of(parts.size());
  for (const Eigen::Vector3d& x : visible) {
    for (std::size_t j = parts.size(); j-- > 0;) {
      Eigen::AlignedBox3d b;
      for (const Eigen::Vector3d& v : parts[j]->vertices) b.extend(v);
      if (b.contains(x) || j == 0) {
        visible_of[j].push_back(x);
        break;
      }
    }
  }
  std::printf("\ncoverage: %zu truly visible samples (%.0f per m^2) on the table top and objects\n", visible.size(),
              vsp.density);
  const std::string csv_path = out_dir + "/voxmap_coverage.csv";
  std::FILE* csv = std::fopen(csv_path.c_str(), "w");
  if (csv == nullptr) {
    std::fprintf(stderr, "cannot write %s\n", csv_path.c_str());
    return 1;
  }
  std::fprintf(csv, "drop,t_s,chunks_integrated,coverage,force_rms_N,force_max_N,contact_ticks,cells,force_rms_tops_N,"
                   "force_rms_facing_sides_N,force_rms_edge_on_sides_N\n");
  std::printf("| chunks dropped | covered at t = 0.2 s | 0.5 s | 1 s | 2 s | 3 s | force rms tops / all at 0.2 s | 1 s | 3 s |\n"
              "|---|---|---|---|---|---|---|---|---|\n");
  for (double drop : {0.0, 0.05, 0.2}) {
    hm::LiveVoxmap map(voxmap_params(0.01, ahead));
    std::mt19937_64 rng(7);
    std::bernoulli_distribution lost(drop);
    std::size_t integrated = 0;
    struct Row {
      double t, cov, rms, rms_tops;
    };
    std::vector<Row> rows;
    for (std::size_t k = 0; k < chunks.size() && chunks[k].t_s <= 3.0 + 1e-9; ++k) {
      if (!lost(rng)) {
        map.integrate(chunks[k].chunk);
        ++integrated;
      }
      const bool frame_end = k + 1 == chunks.size() || chunks[k + 1].t_s != chunks[k].t_s;
      if (!frame_end) continue;
      vps::Voxmap vm;
      const bool ok = !map.snapshot(&vm);
      const double cov = ok ? hr::surface_coverage(vm, visible) : 0.0;
      // The last snapshot without loss, tick by tick (for plots of the path).
      const bool last = drop == 0.0 && (k + 1 == chunks.size() || chunks[k + 1].t_s > 3.0 + 1e-9);
      std::FILE* dump = last ? std::fopen((out_dir + "/voxmap_path.csv").c_str(), "w") : nullptr;
      if (dump != nullptr)
        std::fprintf(dump, "tick,goal_x,goal_y,goal_z,proxy_x,proxy_y,proxy_z,f_x,f_y,f_z,contact,true_proxy_x,"
                           "true_proxy_y,true_proxy_z,true_f_x,true_f_y,true_f_z,true_contact\n");
      const ForceError fe = path_error(ok ? &vm : nullptr, path, truth, dump);
      if (dump != nullptr) std::fclose(dump);
      std::fprintf(csv, "%.2f,%.4f,%zu,%.5f,%.5f,%.5f,%zu,%zu,%.5f,%.5f,%.5f\n", drop, chunks[k].t_s, integrated, cov,
                   fe.rms(), fe.max, fe.ticks(), map.cells(), fe.rms(kTop), fe.rms(kFacing), fe.rms(kGrazing));
      rows.push_back({chunks[k].t_s, cov, fe.rms(), fe.rms(kTop)});
      if (last && ok) {
        std::printf("at %.2f s without loss, force error rms / max by surface:", chunks[k].t_s);
        for (const auto& sf : fe.surfaces)
          std::printf(" %s %.3f / %.3f N,", sf.name.c_str(), std::sqrt(sf.sum2 / static_cast<double>(sf.n)), sf.max);
        std::printf("\ncovered:");
        for (std::size_t j = 0; j < parts.size(); ++j)
          std::printf(" %s %.1f %% of %zu,", meshes_names[j].c_str(), 100.0 * hr::surface_coverage(vm, visible_of[j]),
                      visible_of[j].size());
        std::printf("\n");
      }
    }
    auto at = [&](double t) {
      const Row* best = rows.empty() ? nullptr : &rows.front();
      for (const Row& r : rows)
        if (r.t <= t + 1e-9) best = &r;
      return best;
    };
    std::printf("| %.0f %% |", drop * 100.0);
    for (double t : {0.2, 0.5, 1.0, 2.0, 3.0}) std::printf(" %.1f %% |", at(t) != nullptr ? 100.0 * at(t)->cov : 0.0);
    for (double t : {0.2, 1.0, 3.0}) std::printf(" %.3f / %.3f |", at(t) ? at(t)->rms_tops : 0.0, at(t) ? at(t)->rms : 0.0);
    std::printf("\n");
    std::fflush(stdout);
  }
  std::fclose(csv);
  std::printf("wrote %s\n", csv_path.c_str());
  return 0;
}
