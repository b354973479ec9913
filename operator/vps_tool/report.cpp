#include "operator/vps_tool/report.h"

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/collision_object.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

#include "common/haptics/vps/contact.h"
#include "common/mesh/mesh_io.h"
#include "common/mesh/primitives.h"

namespace hemm::vps_tool {

namespace {

using Clock = std::chrono::steady_clock;
using vps::PairResult;

// CPU time of this thread: excludes the time the shared machine gives to others.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  return v[i];
}

Eigen::Isometry3d pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

// Closed forms (pressure model, see the accuracy tests).
double plane_sphere_force(double K, double R, double h) {  // plane at distance h from the centre
  if (h >= R) return 0.0;
  const double rho2 = R * R - h * h;
  return K * 2 * std::numbers::pi * (R * rho2 / 2 - (R * R * R - h * h * h) / 3);
}
double sphere_sphere_force(double K, double R1, double R2, double D) {
  if (D >= R1 + R2) return 0.0;
  const double u0 = (R1 * R1 + D * D - R2 * R2) / (2 * R1 * D);
  const int n = 2000;
  const double h = (1.0 - u0) / n;
  auto f = [&](double u) { return (R2 - std::sqrt(R1 * R1 + D * D - 2 * R1 * D * u)) * u; };
  double acc = f(u0) + f(1.0);
  for (int i = 1; i < n; ++i) acc += f(u0 + i * h) * (i % 2 ? 4 : 2);
  return 2 * std::numbers::pi * R1 * R1 * K * acc * h / 3.0;
}

std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> fcl_model(const mesh::TriangleMesh& m) {
  auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  std::vector<fcl::Vector3d> v(m.vertices.begin(), m.vertices.end());
  std::vector<fcl::Triangle> t;
  t.reserve(m.triangles.size());
  for (const auto& tr : m.triangles) t.emplace_back(tr[0], tr[1], tr[2]);
  model->beginModel(static_cast<int>(t.size()), static_cast<int>(v.size()));
  model->addSubModel(v, t);
  model->endModel();
  return model;
}

}  // namespace

int run_report(const ReportOptions& o, std::FILE* out) {
  if (!(o.scene_voxel > 0) || !(o.shell_voxel > 0) || o.ticks < 10 || o.repeats < 1 || o.fcl_every < 0 ||
      o.spheres_per_side < 1 || o.spheres_per_side > 20) {
    std::fprintf(out, "error: invalid report options\n");
    return 1;
  }
  // ---- scene and tools
  const double R = 0.08, spacing = 0.25;
  mesh::TriangleMesh scene;
  bool analytic = true;
  if (!o.scene_file.empty()) {
    mesh::MeshReport rep;
    if (auto e = mesh::load_mesh(o.scene_file, {}, &scene, &rep)) {
      std::fprintf(out, "error: %s\n", e->message.c_str());
      return 1;
    }
    analytic = false;
  } else {
    const auto ball = mesh::make_icosphere(R, 5);
    const int n = o.spheres_per_side;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        mesh::append_mesh(&scene, ball,
                          pose(Eigen::Vector3d((i - n / 2) * spacing, (j - n / 2) * spacing, 0.0),
                               Eigen::Matrix3d::Identity()));
  }
  const Eigen::Vector3d hb(0.05, 0.03, 0.02);
  const auto right_mesh = mesh::make_box(hb, 46);               // 25,392 triangles
  const double RL = 0.04;
  const auto left_mesh = mesh::make_uv_sphere(RL, 132, 133);    // 34,848 triangles
  std::fprintf(out, "VPS report: scene %zu triangles%s, right tool (box) %zu, left tool (sphere) %zu\n",
               scene.triangles.size(), analytic ? " (generated: icospheres)" : "", right_mesh.triangles.size(),
               left_mesh.triangles.size());

  vps::VoxmapParams sp;
  sp.voxel_size = o.scene_voxel;
  sp.layers_in = sp.layers_out = 3;
  sp.limits.max_extent = 1000;
  vps::Voxmap scene_vm;
  vps::VoxmapBuildInfo scene_info;
  auto t0 = Clock::now();
  if (auto e = vps::build_voxmap(scene, sp, &scene_vm, &scene_info)) {
    std::fprintf(out, "error: scene voxmap: %s\n", e->message.c_str());
    return 1;
  }
  const double scene_build = seconds_since(t0);
  const auto mem_scene = scene_vm.memory_bytes();
  const double dense_bytes = static_cast<double>(scene_vm.top.size()) * vps::kBlockVoxels * 6.0;
  scene_info.mesh = {};  // the report keeps only the voxmap

  vps::PointShellParams pp;
  pp.voxel_size = o.shell_voxel;
  vps::PointShell right_ps, left_ps;
  vps::Voxmap left_vm;
  vps::VoxmapParams lp;
  lp.voxel_size = o.shell_voxel;
  t0 = Clock::now();
  if (auto e = vps::build_pointshell(right_mesh, pp, Eigen::Vector3d::Zero(), &right_ps)) {
    std::fprintf(out, "error: right pointshell: %s\n", e->message.c_str());
    return 1;
  }
  if (auto e = vps::build_pointshell(left_mesh, pp, Eigen::Vector3d::Zero(), &left_ps)) {
    std::fprintf(out, "error: left pointshell: %s\n", e->message.c_str());
    return 1;
  }
  if (auto e = vps::build_voxmap(left_mesh, lp, &left_vm, nullptr)) {
    std::fprintf(out, "error: left voxmap: %s\n", e->message.c_str());
    return 1;
  }
  const double tools_build = seconds_since(t0);

  std::fprintf(out,
               "\nBuild\n  scene voxmap: voxel %.1f mm, %.2f s, %zu surface voxels, %zu allocated blocks, %zu uniform-inside"
               " blocks\n  scene voxmap memory %.1f MB (a dense grid of the same extent would need %.1f MB)\n"
               "  tools: %zu + %zu pointshell points (voxel %.1f mm), left voxmap %.2f MB, %.2f s\n",
               o.scene_voxel * 1e3, scene_build, scene_info.surface_voxels, scene_info.allocated_blocks,
               scene_info.uniform_inside_blocks, mem_scene / 1e6, dense_bytes / 1e6, right_ps.size(),
               left_ps.size(), o.shell_voxel * 1e3, left_vm.memory_bytes() / 1e6, tools_build);

  // ---- trajectory: right box over the top of the centre sphere, left sphere on
  // its upper +x flank; penetrations 0.5..3 mm, the tools brush each other.
  const double K = 1e7;
  struct Poses {
    Eigen::Isometry3d right, left;
    double right_h;  // scene-sphere centre to the box's bottom plane (for the closed form)
    double left_d;   // centre distance left sphere to scene sphere
  };
  std::vector<Poses> traj;
  traj.reserve(static_cast<std::size_t>(o.ticks));
  for (int k = 0; k < o.ticks; ++k) {
    const double t = k * 1e-3;
    const double pen_r = 0.00175 + 0.00125 * std::sin(2 * std::numbers::pi * 0.7 * t);
    const double pen_l = 0.00175 + 0.00125 * std::cos(2 * std::numbers::pi * 0.9 * t);
    const Eigen::Matrix3d Rr = Eigen::AngleAxisd(0.3 * std::sin(t), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const double xr = -0.012 + 0.008 * std::sin(2 * std::numbers::pi * 0.5 * t);
    const double hr = R + hb.z() - pen_r - hb.z();  // bottom plane height above the sphere centre
    Poses p;
    p.right = pose(Eigen::Vector3d(xr, 0.0, R + hb.z() - pen_r), Rr);
    p.right_h = hr;
    const double dl = R + RL - pen_l;
    const Eigen::Matrix3d Rl = Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    p.left = pose(dl * Eigen::Vector3d(std::cos(0.8), 0.0, std::sin(0.8)), Rl);
    p.left_d = dl;
    traj.push_back(p);
  }
  vps::BimanualModel model;
  model.scene = &scene_vm;
  model.right = {nullptr, &right_ps};
  model.left = {&left_vm, &left_ps};
  model.params.stiffness = K;
  const Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();

  std::vector<double> cycle_us, cycle_cpu_us, err_right, err_left, ang_right, ang_left;
  vps::BimanualData data;
  long contacts_rl = 0, tested = 0;
  for (int rep = 0; rep < o.repeats; ++rep) {
    for (const Poses& p : traj) {
      const double cpu0 = thread_cpu_seconds();
      const auto c0 = Clock::now();
      vps::evaluate_bimanual(model, T_W_S, p.right, p.left, nullptr, &data);
      cycle_us.push_back(seconds_since(c0) * 1e6);
      cycle_cpu_us.push_back((thread_cpu_seconds() - cpu0) * 1e6);
      if (rep != 0) continue;
      contacts_rl += data.right_left.contacts > 0 ? 1 : 0;
      tested += data.right_scene.points_tested + data.left_scene.points_tested + data.right_left.points_tested;
      if (!analytic) continue;
      const double fr = plane_sphere_force(K, R, p.right_h);
      const double fl = sphere_sphere_force(K, RL, R, p.left_d);
      const Eigen::Vector3d dir_l = p.left.translation().normalized();
      if (fr > 0) {
        err_right.push_back(std::abs(data.right_scene.on_shell.force.norm() - fr) / fr);
        ang_right.push_back(std::acos(std::clamp(data.right_scene.on_shell.force.normalized().z(), -1.0, 1.0)) * 180 /
                            std::numbers::pi);
      }
      if (fl > 0) {
        err_left.push_back(std::abs(data.left_scene.on_shell.force.norm() - fl) / fl);
        ang_left.push_back(std::acos(std::clamp(data.left_scene.on_shell.force.normalized().dot(dir_l), -1.0, 1.0)) *
                           180 / std::numbers::pi);
      }
    }
  }
  std::fprintf(out,
               "\nVPS three-pair cycle (right-scene, left-scene, right-left), one core, %d ticks x %d passes\n"
               "  wall time: median %.1f us, p99 %.1f us, max %.1f us (paper: < 1000 us)\n"
               "  thread CPU time: median %.1f us, p99 %.1f us (the shared VM preempts; wall p99 shows its stalls)\n"
               "  mean points tested per cycle %.0f of %zu; right-left in contact on %ld of %d ticks\n",
               o.ticks, o.repeats, percentile(cycle_us, 0.5), percentile(cycle_us, 0.99),
               percentile(cycle_us, 1.0), percentile(cycle_cpu_us, 0.5), percentile(cycle_cpu_us, 0.99),
               static_cast<double>(tested) / o.ticks,
               right_ps.size() * 2 + left_ps.size(), contacts_rl, o.ticks);
  if (analytic) {
    std::fprintf(out,
                 "\nForce error against closed forms at this resolution (pressure model, K = %.0e N/m^3)\n"
                 "  pair                      | |F| error median | p99     | direction error p99\n"
                 "  box face - scene sphere   | %14.2f%% | %6.2f%% | %6.2f deg\n"
                 "  sphere - scene sphere     | %14.2f%% | %6.2f%% | %6.2f deg\n",
                 K, 100 * percentile(err_right, 0.5), 100 * percentile(err_right, 0.99), percentile(ang_right, 0.99),
                 100 * percentile(err_left, 0.5), 100 * percentile(err_left, 0.99), percentile(ang_left, 0.99));
  }

  // ---- speed against error: the same scene voxmap, tool pointshells at other resolutions.
  if (analytic) {
    std::fprintf(out,
                 "\nSpeed against error (scene voxmap fixed at %.1f mm; tool pointshell resolution varied)\n"
                 "  shell voxel | points R+L | cycle CPU median | cycle CPU p99 | |F| err box median | sphere median\n",
                 o.scene_voxel * 1e3);
    for (double sv : {0.004, 0.003, 0.002, 0.0015}) {
      vps::PointShellParams q;
      q.voxel_size = sv;
      vps::PointShell rps, lps;
      if (vps::build_pointshell(right_mesh, q, Eigen::Vector3d::Zero(), &rps) ||
          vps::build_pointshell(left_mesh, q, Eigen::Vector3d::Zero(), &lps))
        continue;
      vps::BimanualModel m2 = model;
      m2.right = {nullptr, &rps};
      m2.left = {&left_vm, &lps};
      std::vector<double> cpu, er, el;
      for (std::size_t k = 0; k < traj.size(); k += 2) {
        const Poses& p = traj[k];
        const double cpu0 = thread_cpu_seconds();
        vps::evaluate_bimanual(m2, T_W_S, p.right, p.left, nullptr, &data);
        cpu.push_back((thread_cpu_seconds() - cpu0) * 1e6);
        const double fr = plane_sphere_force(K, R, p.right_h);
        const double fl = sphere_sphere_force(K, RL, R, p.left_d);
        if (fr > 0) er.push_back(std::abs(data.right_scene.on_shell.force.norm() - fr) / fr);
        if (fl > 0) el.push_back(std::abs(data.left_scene.on_shell.force.norm() - fl) / fl);
      }
      std::fprintf(out, "  %8.1f mm | %10zu | %13.1f us | %10.1f us | %17.2f%% | %12.2f%%\n", sv * 1e3,
                   rps.size() + lps.size(), percentile(cpu, 0.5), percentile(cpu, 0.99),
                   100 * percentile(er, 0.5), 100 * percentile(el, 0.5));
    }
  }

  // ---- speed against error over the scene voxel size: the error comes from the
  // scene's field, which depends only on the local geometry, so this sweep uses
  // one sphere of the scene (memory and build scale with the sphere count).
  if (analytic) {
    std::fprintf(out,
                 "\nSpeed against error over the scene voxel (one scene sphere of 20480 triangles; x%d for the scene)\n"
                 "  scene voxel | build   | memory   | cycle CPU median | p99      | |F| err box median | sphere median\n",
                 o.spheres_per_side * o.spheres_per_side);
    const auto ball = mesh::make_icosphere(R, 5);
    for (double sv : {0.004, 0.003, 0.002, 0.0015, 0.001}) {
      vps::VoxmapParams q;
      q.voxel_size = sv;
      q.layers_in = q.layers_out = std::max(3, static_cast<int>(std::ceil(0.006 / sv)));
      vps::Voxmap one;
      const auto b0 = Clock::now();
      if (vps::build_voxmap(ball, q, &one, nullptr)) continue;
      const double bt = seconds_since(b0);
      vps::BimanualModel m2 = model;
      m2.scene = &one;
      std::vector<double> cpu, er, el;
      for (std::size_t k = 0; k < traj.size(); k += 2) {
        const Poses& p = traj[k];
        const double cpu0 = thread_cpu_seconds();
        vps::evaluate_bimanual(m2, T_W_S, p.right, p.left, nullptr, &data);
        cpu.push_back((thread_cpu_seconds() - cpu0) * 1e6);
        const double fr = plane_sphere_force(K, R, p.right_h);
        const double fl = sphere_sphere_force(K, RL, R, p.left_d);
        if (fr > 0) er.push_back(std::abs(data.right_scene.on_shell.force.norm() - fr) / fr);
        if (fl > 0) el.push_back(std::abs(data.left_scene.on_shell.force.norm() - fl) / fl);
      }
      std::fprintf(out, "  %8.1f mm | %5.2f s | %5.1f MB | %13.1f us | %5.1f us | %17.2f%% | %12.2f%%\n", sv * 1e3, bt,
                   one.memory_bytes() / 1e6, percentile(cpu, 0.5), percentile(cpu, 0.99), 100 * percentile(er, 0.5),
                   100 * percentile(el, 0.5));
    }
  }

  // ---- FCL on the same poses.
  if (o.fcl_every > 0) {
    t0 = Clock::now();
    auto fs = fcl_model(scene);
    auto fr = fcl_model(right_mesh);
    auto fl = fcl_model(left_mesh);
    const double fcl_build = seconds_since(t0);
    fcl::CollisionObjectd os(fs, fcl::Transform3d::Identity());
    fcl::CollisionObjectd orr(fr, fcl::Transform3d::Identity());
    fcl::CollisionObjectd ol(fl, fcl::Transform3d::Identity());
    std::vector<double> fcl_us, fcl_cpu_us, fcl_pair_us;
    std::size_t fcl_contacts = 0;
    int n = 0;
    for (std::size_t k = 0; k < traj.size(); k += static_cast<std::size_t>(o.fcl_every)) {
      orr.setTransform(fcl::Transform3d(traj[k].right.matrix()));
      ol.setTransform(fcl::Transform3d(traj[k].left.matrix()));
      orr.computeAABB();
      ol.computeAABB();
      const double cpu0 = thread_cpu_seconds();
      const auto c0 = Clock::now();
      std::size_t nc = 0;
      for (int pair = 0; pair < 3; ++pair) {
        const auto p0 = Clock::now();
        fcl::CollisionRequestd req(100000, true);
        fcl::CollisionResultd res;
        if (pair == 0) fcl::collide(&orr, &os, req, res);
        if (pair == 1) fcl::collide(&ol, &os, req, res);
        if (pair == 2) fcl::collide(&orr, &ol, req, res);
        nc += res.numContacts();
        fcl_pair_us.push_back(seconds_since(p0) * 1e6);
      }
      fcl_us.push_back(seconds_since(c0) * 1e6);
      fcl_cpu_us.push_back((thread_cpu_seconds() - cpu0) * 1e6);
      fcl_contacts += nc;
      ++n;
    }
    std::fprintf(out,
                 "\nFCL 0.7 (BVHModel<OBBRSS>, collide with enable_contact, up to 100000 contacts) on every %d-th pose\n"
                 "  BVH build %.2f s; three pairs per cycle: median %.1f us, p99 %.1f us; per query median %.1f us\n"
                 "  mean %.0f triangle-pair contacts per cycle (no penetration-consistent force: contacts only)\n",
                 o.fcl_every, fcl_build, percentile(fcl_us, 0.5), percentile(fcl_us, 0.99),
                 percentile(fcl_pair_us, 0.5), n > 0 ? static_cast<double>(fcl_contacts) / n : 0.0);
    std::fprintf(out,
                 "\nSide by side (same poses; wall and thread-CPU time per three-pair cycle)\n"
                 "  method | wall median | wall p99    | CPU median | CPU p99     | scene memory | scene build\n"
                 "  VPS    | %8.1f us | %8.1f us | %7.1f us | %8.1f us | %7.1f MB   | %6.2f s\n"
                 "  FCL    | %8.1f us | %8.1f us | %7.1f us | %8.1f us |   (BVH)      | %6.2f s\n",
                 percentile(cycle_us, 0.5), percentile(cycle_us, 0.99), percentile(cycle_cpu_us, 0.5),
                 percentile(cycle_cpu_us, 0.99), mem_scene / 1e6, scene_build, percentile(fcl_us, 0.5),
                 percentile(fcl_us, 0.99), percentile(fcl_cpu_us, 0.5), percentile(fcl_cpu_us, 0.99), fcl_build);
  }
  return 0;
}

}  // namespace hemm::vps_tool
