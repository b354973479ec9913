// hemm-vps: build, evaluate and report on Voxmap-PointShell data.
//   hemm-vps build --mesh FILE --voxel SIZE [--roi ...] -o FILE.vps
//   hemm-vps eval --scene A.vps --tool B.vps --poses poses.csv -o forces.csv
//   hemm-vps report
//   hemm-vps scene --name peg-in-hole|assembly --out DIR
#include <CLI/CLI.hpp>

#include <charconv>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/haptics/vps/cache.h"
#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/scenes.h"
#include "common/mesh/mesh_io.h"
#include "common/mesh/primitives.h"
#ifdef HEMM_VPS_HAVE_PCL
#include "common/mesh/point_cloud.h"
#endif
#include "operator/vps/vps_model.h"
#include "operator/vps_tool/report.h"

namespace {

using namespace hemm;

bool load_vps(const std::string& path, vps::Voxmap* vm, vps::PointShell* ps) {
  std::string err;
  if (!op::load_vps_file(path, vm, ps, &err)) {
    std::fprintf(stderr, "error: %s\n", err.c_str());
    return false;
  }
  return true;
}

bool parse_double(const std::string& s, double* v) {
  const char* b = s.data();
  const char* e = s.data() + s.size();
  while (b < e && (*b == ' ' || *b == '\t')) ++b;
  while (e > b && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) --e;
  if (b == e) return false;
  const auto r = std::from_chars(b, e, *v);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(*v);
}

struct PoseRow {
  double t;
  Eigen::Isometry3d T_S_T;
};

// poses.csv: "t,x,y,z,qw,qx,qy,qz" per line (tool pose in the scene frame; metres,
// unit quaternion within 1e-3); blank lines and lines starting with '#' are
// skipped, a first line starting with 't' is a header. Times must not decrease.
bool load_poses(const std::string& path, std::vector<PoseRow>* rows) {
  std::ifstream f(path);
  if (!f) {
    std::fprintf(stderr, "error: %s: cannot open\n", path.c_str());
    return false;
  }
  std::string line;
  int lineno = 0;
  double last_t = -INFINITY;
  while (std::getline(f, line)) {
    ++lineno;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    if (lineno == 1 && (line[0] == 't' || line[0] == 'T')) continue;
    std::vector<std::string> fields;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, ',')) fields.push_back(field);
    if (fields.size() != 8) {
      std::fprintf(stderr, "%s:%d: expected 8 fields t,x,y,z,qw,qx,qy,qz, got %zu\n", path.c_str(), lineno,
                   fields.size());
      return false;
    }
    double v[8];
    for (int i = 0; i < 8; ++i) {
      if (!parse_double(fields[static_cast<std::size_t>(i)], &v[i])) {
        std::fprintf(stderr, "%s:%d: field %d is not a finite number: '%s'\n", path.c_str(), lineno, i + 1,
                     fields[static_cast<std::size_t>(i)].c_str());
        return false;
      }
    }
    if (v[0] < last_t) {
      std::fprintf(stderr, "%s:%d: time %g goes backwards (previous %g)\n", path.c_str(), lineno, v[0], last_t);
      return false;
    }
    last_t = v[0];
    Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      std::fprintf(stderr, "%s:%d: quaternion norm %g is not 1\n", path.c_str(), lineno, q.norm());
      return false;
    }
    if (std::abs(v[1]) > 1e4 || std::abs(v[2]) > 1e4 || std::abs(v[3]) > 1e4) {
      std::fprintf(stderr, "%s:%d: position beyond 10 km\n", path.c_str(), lineno);
      return false;
    }
    q.normalize();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.toRotationMatrix();
    T.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    rows->push_back({v[0], T});
  }
  if (rows->empty()) {
    std::fprintf(stderr, "%s: no poses\n", path.c_str());
    return false;
  }
  return true;
}

bool parse_roi(const std::string& s, Eigen::AlignedBox3d* box) {
  std::vector<std::string> f;
  std::stringstream ss(s);
  std::string x;
  while (std::getline(ss, x, ',')) f.push_back(x);
  double v[6];
  if (f.size() != 6) return false;
  for (int i = 0; i < 6; ++i)
    if (!parse_double(f[static_cast<std::size_t>(i)], &v[i])) return false;
  *box = Eigen::AlignedBox3d(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
  return !box->isEmpty();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hemm-vps: Voxmap-PointShell builder, evaluator and speed-against-error report"};
  app.require_subcommand(1);

  // ---- build
  auto* build = app.add_subcommand("build", "Build voxmap + pointshell from a mesh file and cache them (.vps)");
  std::string mesh_path, points_path, out_path, roi_text;
  double voxel = 0, shell_voxel = 0, scale = 1.0, density = 1000.0;
  int layers = 3;
  auto* mesh_opt = build->add_option("--mesh", mesh_path, "Mesh file (STL, OBJ, PLY, OFF, ...)");
#ifdef HEMM_VPS_HAVE_PCL
  auto* points_opt = build->add_option("--points", points_path,
                                       "Point cloud (PCD) instead of a mesh: unsigned surface voxmap, no pointshell");
  mesh_opt->excludes(points_opt);
  points_opt->excludes(mesh_opt);
#endif
  build->add_option("--voxel", voxel, "Voxel size in metres")->required();
  build->add_option("--shell-voxel", shell_voxel, "Pointshell voxel size in metres (default: --voxel)");
  build->add_option("--roi", roi_text, "Region of interest xmin,ymin,zmin,xmax,ymax,zmax (mesh frame, metres)");
  build->add_option("--layers", layers, "Distance layers inward and outward (1..100)");
  build->add_option("--scale", scale, "File units to metres (e.g. 0.001 for mm)");
  build->add_option("--density", density, "Density for the centre of mass (torque reference)");
  build->add_option("-o,--output", out_path, "Output .vps file")->required();

  // ---- eval
  auto* eval = app.add_subcommand("eval", "Evaluate tool poses against a scene into a force/torque CSV");
  std::string scene_path, tool_path, poses_path, forces_path, model_name = "continuous";
  double stiffness = 1e7;
  eval->add_option("--scene", scene_path, "Scene .vps (its voxmap is used)")->required();
  eval->add_option("--tool", tool_path, "Tool .vps (its pointshell is used)")->required();
  eval->add_option("--poses", poses_path, "CSV t,x,y,z,qw,qx,qy,qz: tool pose in the scene frame")->required();
  eval->add_option("-o,--output", forces_path, "Output CSV t,fx,fy,fz,tx,ty,tz,contacts,max_penetration")->required();
  eval->add_option("--stiffness", stiffness, "Pressure stiffness K (N/m^3)");
  eval->add_option("--model", model_name, "continuous or layered")->check(CLI::IsMember({"continuous", "layered"}));

  // ---- report
  auto* report = app.add_subcommand(
      "report", "Engine report: assembly scene (>1 M triangles), exact-reference errors, time-critical budgets, FCL, "
                "paper-scale run");
  hemm::vps_tool::ReportOptions ro;
  report->add_option("--voxel", ro.scene_voxel, "Scene voxel size (m)")->check(CLI::PositiveNumber);
  report->add_option("--shell-voxel", ro.shell_voxel, "Tool pointshell voxel size (m)")->check(CLI::PositiveNumber);
  report->add_option("--ticks", ro.ticks, "Trajectory length (1 kHz ticks)")->check(CLI::Range(10, 1000000));
  report->add_option("--repeats", ro.repeats, "Timing passes over the trajectory")->check(CLI::Range(1, 100));
  report->add_option("--fcl-every", ro.fcl_every, "Run FCL on every n-th pose (0 = skip)")->check(CLI::Range(0, 1000000));
  report->add_option("--bosses", ro.bosses, "Assembly scene: bosses of 81,920 triangles (13: 1.07 M)")
      ->check(CLI::Range(1, 100));
  report->add_option("--layers", ro.layers, "Scene distance layers (0: from the coupling's maximum expected penetration)")
      ->check(CLI::Range(0, 100));
  report->add_option("--paper-bosses", ro.paper_bosses, "Paper-scale run: bosses (41: 3.36 M; 0 skips it)")
      ->check(CLI::Range(0, 100));
  report->add_option("--budgets", ro.budgets, "Time-critical work budgets (nodes + points per cycle)")
      ->check(CLI::Range(std::int64_t{1}, std::int64_t{100000000}));

  // ---- scene
  auto* scene = app.add_subcommand(
      "scene", "Write one of the paper's two scenes (static part and both tools as STL) and its scripted hands (CSV)");
  std::string scene_name, scene_dir;
  int scene_bosses = 13;
  double scene_rate = 1000.0;
  scene->add_option("--name", scene_name, "peg-in-hole or assembly")
      ->required()
      ->check(CLI::IsMember({"peg-in-hole", "assembly"}));
  scene->add_option("--out", scene_dir, "Output directory (created)")->required();
  scene->add_option("--bosses", scene_bosses, "Assembly: bosses of 81,920 triangles (13: 1.07 M, 41: 3.36 M)")
      ->check(CLI::Range(1, 100));
  scene->add_option("--rate", scene_rate, "Samples per second of the hand paths")->check(CLI::Range(1.0, 10000.0));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;  // bad arguments: 2, with CLI11's message
  }

  if (*scene) {
    const bool peg = scene_name == "peg-in-hole";
    const vps::BimanualScene sc = peg ? vps::make_peg_in_hole_scene() : vps::make_assembly_scene(scene_bosses);
    std::error_code ec;
    std::filesystem::create_directories(scene_dir, ec);
    if (ec) {
      std::fprintf(stderr, "error: %s: %s\n", scene_dir.c_str(), ec.message().c_str());
      return 1;
    }
    const std::string base = scene_dir + "/" + sc.name;
    for (const auto& [suffix, m] : {std::pair<const char*, const mesh::TriangleMesh*>{"-scene.stl", &sc.scene},
                                    {"-right.stl", &sc.right},
                                    {"-left.stl", &sc.left}}) {
      if (auto e = mesh::save_mesh(base + suffix, *m)) {
        std::fprintf(stderr, "error: %s\n", e->message.c_str());
        return 1;
      }
      std::printf("%s%s: %zu triangles\n", base.c_str(), suffix, m->triangles.size());
    }
    if (peg) {  // the Omni's small tool for exploring the scene (deploy/configs/operator_vps_omni.pbtxt)
      const std::string probe = base + "-probe.stl";
      if (auto e = mesh::save_mesh(probe, mesh::make_icosphere(0.008, 4))) {
        std::fprintf(stderr, "error: %s\n", e->message.c_str());
        return 1;
      }
      std::printf("%s: an 8 mm ball (the Omni's tool)\n", probe.c_str());
    }
    // The scripted hands: mesh-frame poses of both objects in the scene
    // frame, as `hemm-vps eval --poses` reads them per object.
    const double duration = peg ? vps::kPegInHoleDuration : vps::kAssemblyDuration;
    const std::string csv = base + "-hands.csv";
    std::FILE* f = std::fopen(csv.c_str(), "w");
    if (f == nullptr) {
      std::fprintf(stderr, "error: %s: cannot write\n", csv.c_str());
      return 1;
    }
    std::fprintf(f, "t,rx,ry,rz,rqw,rqx,rqy,rqz,lx,ly,lz,lqw,lqx,lqy,lqz\n");
    const int n = static_cast<int>(std::floor(duration * scene_rate)) + 1;
    for (int i = 0; i < n; ++i) {
      const double t = i / scene_rate;
      const vps::BimanualPoses h = peg ? vps::peg_in_hole_hands(t) : vps::assembly_hands(t);
      std::fprintf(f, "%.6f", t);
      for (const Eigen::Isometry3d* T : {&h.right, &h.left}) {
        const Eigen::Quaterniond q(T->linear());
        std::fprintf(f, ",%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g", T->translation().x(), T->translation().y(),
                     T->translation().z(), q.w(), q.x(), q.y(), q.z());
      }
      std::fprintf(f, "\n");
    }
    if (std::fclose(f) != 0) {
      std::fprintf(stderr, "error: %s: write failed\n", csv.c_str());
      return 1;
    }
    std::printf("%s: %d hand poses over %.1f s\n", csv.c_str(), n, duration);
    return 0;
  }

  if (*build && !points_path.empty()) {
#ifdef HEMM_VPS_HAVE_PCL
    std::vector<Eigen::Vector3d> pts;
    std::size_t dropped = 0;
    if (auto e = mesh::load_point_cloud_pcd(points_path, {}, &pts, &dropped)) {
      std::fprintf(stderr, "error: %s\n", e->message.c_str());
      return 1;
    }
    if (scale != 1.0) {
      if (!(scale > 0) || !std::isfinite(scale)) {
        std::fprintf(stderr, "error: --scale must be positive\n");
        return 1;
      }
      for (auto& p : pts) p *= scale;
    }
    vps::VoxmapParams vp;
    vp.voxel_size = voxel;
    vp.layers_in = vp.layers_out = layers;
    if (!roi_text.empty()) {
      Eigen::AlignedBox3d box;
      if (!parse_roi(roi_text, &box)) {
        std::fprintf(stderr, "error: --roi needs six numbers xmin,ymin,zmin,xmax,ymax,zmax with min <= max\n");
        return 1;
      }
      vp.roi = box;
    }
    vps::Voxmap vm;
    if (auto e = vps::build_voxmap_from_points(pts, vp, &vm)) {
      std::fprintf(stderr, "error: voxmap: %s\n", e->message.c_str());
      return 1;
    }
    vps::PointShell none;  // a point cloud is a scene only
    none.voxel_size = voxel;
    std::string err;
    if (!op::save_vps_file(out_path, vm, none, &err)) {
      std::fprintf(stderr, "error: %s\n", err.c_str());
      return 1;
    }
    std::printf("%s: %zu points (%zu NaN dropped): %zu surface voxels, %.2f MB; wrote %s\n", points_path.c_str(),
                pts.size(), dropped, vm.surface_voxels, vm.memory_bytes() / 1e6, out_path.c_str());
    return 0;
#endif
  }
  if (*build) {
    if (mesh_path.empty()) {
      std::fprintf(stderr, "error: build needs --mesh FILE%s\n",
#ifdef HEMM_VPS_HAVE_PCL
                   " or --points FILE.pcd"
#else
                   ""
#endif
      );
      return 1;
    }
    mesh::LoadOptions lo;
    lo.scale = scale;
    mesh::TriangleMesh m;
    mesh::MeshReport rep;
    if (auto e = mesh::load_mesh(mesh_path, lo, &m, &rep)) {
      std::fprintf(stderr, "error: %s\n", e->message.c_str());
      return 1;
    }
    if (!(density > 0) || !std::isfinite(density)) {
      std::fprintf(stderr, "error: --density must be positive\n");
      return 1;
    }
    vps::VoxmapParams vp;
    vp.voxel_size = voxel;
    vp.layers_in = vp.layers_out = layers;
    if (!roi_text.empty()) {
      Eigen::AlignedBox3d box;
      if (!parse_roi(roi_text, &box)) {
        std::fprintf(stderr, "error: --roi needs six numbers xmin,ymin,zmin,xmax,ymax,zmax with min <= max\n");
        return 1;
      }
      vp.roi = box;
    }
    std::printf("%s: %zu triangles (%zu degenerate dropped), %s%s\n", mesh_path.c_str(), m.triangles.size(),
                rep.degenerate_dropped, rep.watertight() ? "watertight" : "open or non-manifold",
                rep.watertight() ? "" : ": unsigned voxmap (surface shell) fallback");
    const auto t0 = std::chrono::steady_clock::now();
    vps::Voxmap vm;
    vps::VoxmapBuildInfo info;
    if (auto e = vps::build_voxmap(m, vp, &vm, &info)) {
      std::fprintf(stderr, "error: voxmap: %s\n", e->message.c_str());
      return 1;
    }
    const Eigen::Vector3d ref = rep.watertight() ? mesh::compute_mass_properties(m, density).centre_of_mass
                                                 : rep.bounds.center();
    vps::PointShellParams pp;
    pp.voxel_size = shell_voxel > 0 ? shell_voxel : voxel;
    vps::PointShell ps;
    if (auto e = vps::build_pointshell(m, pp, ref, &ps)) {
      std::fprintf(stderr, "error: pointshell: %s\n", e->message.c_str());
      return 1;
    }
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::string err;
    if (!op::save_vps_file(out_path, vm, ps, &err)) {
      std::fprintf(stderr, "error: %s\n", err.c_str());
      return 1;
    }
    std::printf("voxmap: %zu surface voxels, %zu blocks, %.2f MB; pointshell: %zu points; %.2f s; wrote %s\n",
                info.surface_voxels, vm.blocks.size(), vm.memory_bytes() / 1e6, ps.size(), secs, out_path.c_str());
    return 0;
  }
  if (*eval) {
    vps::Voxmap scene_vm, tool_vm;
    vps::PointShell scene_ps, tool_ps;
    if (!load_vps(scene_path, &scene_vm, &scene_ps) || !load_vps(tool_path, &tool_vm, &tool_ps)) return 1;
    if (!(stiffness > 0) || !std::isfinite(stiffness)) {
      std::fprintf(stderr, "error: --stiffness must be positive\n");
      return 1;
    }
    std::vector<PoseRow> rows;
    if (!load_poses(poses_path, &rows)) return 1;
    vps::ContactParams cp;
    cp.stiffness = stiffness;
    cp.model = model_name == "layered" ? vps::PenetrationModel::kLayered : vps::PenetrationModel::kContinuous;
    std::FILE* out = std::fopen(forces_path.c_str(), "w");
    if (out == nullptr) {
      std::fprintf(stderr, "error: %s: cannot write\n", forces_path.c_str());
      return 1;
    }
    std::fprintf(out, "t,fx,fy,fz,tx,ty,tz,contacts,max_penetration\n");
    // The rows are a trajectory: one pair state carries which side of a thin
    // wall each point came from from row to row.
    vps::PairState state;
    vps::init_pair_state(tool_ps, &state);
    for (const PoseRow& r : rows) {
      vps::PairResult res;
      vps::evaluate_pair(scene_vm, Eigen::Isometry3d::Identity(), scene_ps.reference_point, tool_ps, r.T_S_T, cp,
                         &state, &res);
      const auto& w = res.on_shell;
      std::fprintf(out, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%d,%.9g\n", r.t, w.force.x(), w.force.y(), w.force.z(),
                   w.torque.x(), w.torque.y(), w.torque.z(), res.contacts, res.max_penetration);
    }
    if (std::fclose(out) != 0) {
      std::fprintf(stderr, "error: %s: write failed\n", forces_path.c_str());
      return 1;
    }
    std::printf("evaluated %zu poses into %s\n", rows.size(), forces_path.c_str());
    return 0;
  }
  if (*report) return hemm::vps_tool::run_report(ro, stdout);
  return 0;
}
