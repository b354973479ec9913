#include "operator/vps_tool/report.h"

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/collision_object.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <memory>
#include <numbers>
#include <vector>

#include "common/haptics/vps/closed_forms.h"
#include "common/haptics/vps/contact.h"
#include "common/haptics/vps/coupling.h"
#include "common/haptics/vps/scenes.h"

namespace hemm::vps_tool {

namespace {

using Clock = std::chrono::steady_clock;
using vps::Wrench;

constexpr double kStiffness = 1e7;  // pressure stiffness K (N/m^3); errors are relative, K only scales

// CPU time of this thread: excludes the time the shared machine gives to others.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1));
  return v[i];
}

Eigen::Isometry3d pose(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

// One pose of the report's trajectory and its exact wrenches. The tank's
// bottom face rests on top of boss 0 (plane-sphere), the drill's ball on the
// boss's flank (sphere-sphere) and against the tank's +x face (plane-sphere);
// every contact patch lies inside its face and nothing else touches (checked).
struct Truth {
  Eigen::Isometry3d right, left;  // mesh frames of the tank and the drill in W
  Wrench right_total, left_total;  // on each tool, torque about its mesh origin
  double max_penetration = 0.0;
  bool valid = true;
};

Truth report_pose(double t, const vps::AssemblyLayout& L) {
  const double R = L.boss_radius, RL = L.drill_ball_radius;
  const Eigen::Vector3d hb = L.tank_half;
  const double mm = 1e-3, w = 2 * std::numbers::pi;
  const double pen_r = (1.75 + 1.25 * std::sin(w * 0.7 * t)) * mm;
  const double pen_l = (1.75 + 1.25 * std::cos(w * 0.9 * t)) * mm;
  const double pen_rl = (1.25 + 0.75 * std::sin(w * 1.1 * t)) * mm;
  const double yaw = 0.08 * std::sin(w * 0.3 * t);
  const double y_b = 2 * mm * std::sin(w * 0.4 * t), y_off = 4 * mm * std::sin(w * 0.5 * t);
  const double z_off = 2 * mm * std::cos(w * 0.6 * t);
  const Eigen::Matrix3d Rb = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double z_b = R - pen_r + hb.z();
  const double h_rl = RL - pen_rl;  // ball centre beyond the tank's +x face
  const Eigen::Vector3d q = Rb * Eigen::Vector3d(hb.x() + h_rl, y_off, z_off);
  const double D = R + RL - pen_l;
  Truth tr;
  const double rx2 = D * D - (y_b + q.y()) * (y_b + q.y()) - (z_b + q.z()) * (z_b + q.z());
  if (rx2 <= 0) {
    tr.valid = false;
    return tr;
  }
  const double x_b = std::sqrt(rx2) - q.x();
  const Eigen::Vector3d c_b(x_b, y_b, z_b), c_l = c_b + q;
  tr.right = pose(c_b, Rb);
  // The drill's handle points away from the boss (radially), spinning about itself.
  const Eigen::Vector3d u = c_l.normalized();
  tr.left = pose(c_l, Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), u).toRotationMatrix() *
                          Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  // Contact patches inside their faces: the boss's cap on the bottom face,
  // the ball's cap on the +x face; the ball clear of the bottom face's edge.
  const double cap_b = std::sqrt(2 * R * pen_r), cap_s = std::sqrt(RL * RL - h_rl * h_rl);
  const Eigen::Vector3d top_local = Rb.transpose() * (Eigen::Vector3d(0, 0, R) - c_b);
  tr.valid = std::abs(top_local.x()) + cap_b < hb.x() - 1 * mm && std::abs(top_local.y()) + cap_b < hb.y() - 1 * mm &&
             std::abs(y_off) + cap_s < hb.y() - 1 * mm && std::abs(z_off) + cap_s < hb.z() - 1 * mm;
  // Right-scene: +z on the tank through the boss's axis.
  const Eigen::Vector3d F_rs(0, 0, vps::plane_sphere_force(kStiffness, R, R - pen_r));
  const Eigen::Vector3d p_rs(0, 0, R - pen_r);
  // Right-left: along -x of the tank through the foot of the ball's centre.
  const Eigen::Vector3d ex = Rb.col(0);
  const Eigen::Vector3d F_rl = -vps::plane_sphere_force(kStiffness, RL, h_rl) * ex;
  const Eigen::Vector3d p_rl = c_l - h_rl * ex;
  // Left-scene: along u on the ball, no torque about its centre.
  const Eigen::Vector3d F_ls = vps::sphere_sphere_force(kStiffness, RL, R, D) * u;
  tr.right_total.force = F_rs + F_rl;
  tr.right_total.torque = (p_rs - c_b).cross(F_rs) + (p_rl - c_b).cross(F_rl);
  tr.left_total.force = F_ls - F_rl;
  tr.left_total.torque = (p_rl - c_l).cross(-F_rl);  // zero: along the lever
  tr.max_penetration = std::max({pen_r, pen_l, pen_rl});
  return tr;
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

struct Built {
  std::size_t scene_triangles = 0, right_triangles = 0, left_triangles = 0;
  vps::Voxmap scene;
  vps::PointShell right, left;
  vps::Voxmap left_vm;
  double scene_build_cpu = 0, scene_build_wall = 0, tools_build_cpu = 0;
  std::size_t memory() const {
    return scene.memory_bytes() + right.memory_bytes() + left.memory_bytes() + left_vm.memory_bytes();
  }
};

bool build(const ReportOptions& o, int bosses, int layers, const vps::BimanualScene& sc, Built* b, std::FILE* out) {
  b->scene_triangles = sc.scene.triangles.size();
  b->right_triangles = sc.right.triangles.size();
  b->left_triangles = sc.left.triangles.size();
  vps::VoxmapParams sp;
  sp.voxel_size = o.scene_voxel;
  sp.layers_in = sp.layers_out = layers;
  const auto w0 = Clock::now();
  double c0 = thread_cpu_seconds();
  if (auto e = vps::build_voxmap(sc.scene, sp, &b->scene, nullptr)) {
    std::fprintf(out, "error: scene voxmap (%d bosses): %s\n", bosses, e->message.c_str());
    return false;
  }
  b->scene_build_cpu = thread_cpu_seconds() - c0;
  b->scene_build_wall = std::chrono::duration<double>(Clock::now() - w0).count();
  c0 = thread_cpu_seconds();
  vps::PointShellParams pp;
  pp.voxel_size = o.shell_voxel;
  vps::VoxmapParams lp;
  lp.voxel_size = o.shell_voxel;
  lp.layers_in = lp.layers_out = std::max(4, vps::layers_for_depth(0.003, o.shell_voxel));
  if (auto e = vps::build_pointshell(sc.right, pp, Eigen::Vector3d::Zero(), &b->right)) {
    std::fprintf(out, "error: right pointshell: %s\n", e->message.c_str());
    return false;
  }
  if (auto e = vps::build_pointshell(sc.left, pp, Eigen::Vector3d::Zero(), &b->left)) {
    std::fprintf(out, "error: left pointshell: %s\n", e->message.c_str());
    return false;
  }
  if (auto e = vps::build_voxmap(sc.left, lp, &b->left_vm, nullptr)) {
    std::fprintf(out, "error: left voxmap: %s\n", e->message.c_str());
    return false;
  }
  b->tools_build_cpu = thread_cpu_seconds() - c0;
  return true;
}

// One mode over the trajectory: cycle CPU times (every cycle of every pass,
// and each pose's fastest pass: what the pose costs without the machine's
// interference), errors (first pass), work and levels.
struct RunStats {
  std::vector<double> cpu_us, best_us;
  double f_err_r = 0, f_err_l = 0, t_err_r = 0, t_err_l = 0;
  double mean_work = 0;
  double pair_nodes[3] = {0, 0, 0}, pair_points[3] = {0, 0, 0}, pair_contacts[3] = {0, 0, 0};
  int min_levels = 99;
  double mean_levels = 0;
};

RunStats run_mode(const vps::BimanualModel& model, const std::vector<Truth>& traj, int repeats, std::int64_t budget,
                  double r_right, double r_left) {
  RunStats st;
  vps::BimanualState state;
  vps::init_bimanual_state(model, &state);
  vps::BimanualData data;
  st.best_us.assign(traj.size(), 1e300);
  double ef_r = 0, ef_l = 0, rf_r = 0, rf_l = 0, et_r = 0, et_l = 0, rt_r = 0, rt_l = 0;
  double work = 0, levels = 0;
  const Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();
  for (int rep = 0; rep < repeats; ++rep) {
    for (std::size_t k = 0; k < traj.size(); ++k) {
      const Truth& tr = traj[k];
      const double c0 = thread_cpu_seconds();
      if (budget == vps::kUnlimitedWork) {
        vps::evaluate_bimanual(model, T_W_S, tr.right, tr.left, &state, &data);
      } else {
        vps::evaluate_bimanual_budgeted(model, T_W_S, tr.right, tr.left, budget, &state, &data);
      }
      const double us = (thread_cpu_seconds() - c0) * 1e6;
      st.cpu_us.push_back(us);
      st.best_us[k] = std::min(st.best_us[k], us);
      if (rep != 0) continue;
      ef_r += (data.right_total.force - tr.right_total.force).squaredNorm();
      ef_l += (data.left_total.force - tr.left_total.force).squaredNorm();
      rf_r += tr.right_total.force.squaredNorm();
      rf_l += tr.left_total.force.squaredNorm();
      et_r += (data.right_total.torque - tr.right_total.torque).squaredNorm();
      et_l += (data.left_total.torque - tr.left_total.torque).squaredNorm();
      rt_r += tr.right_total.force.squaredNorm() * r_right * r_right;
      rt_l += tr.left_total.force.squaredNorm() * r_left * r_left;
      work += static_cast<double>(data.work);
      const vps::PairResult* pr[3] = {&data.right_scene, &data.left_scene, &data.right_left};
      for (int p = 0; p < 3; ++p) {
        st.pair_nodes[p] += pr[p]->nodes_visited / static_cast<double>(traj.size());
        st.pair_points[p] += pr[p]->points_tested / static_cast<double>(traj.size());
        st.pair_contacts[p] += pr[p]->contacts / static_cast<double>(traj.size());
      }
      levels += data.levels_completed;
      st.min_levels = std::min(st.min_levels, data.levels_completed);
    }
  }
  st.f_err_r = std::sqrt(ef_r / rf_r);
  st.f_err_l = std::sqrt(ef_l / rf_l);
  st.t_err_r = std::sqrt(et_r / rt_r);
  st.t_err_l = std::sqrt(et_l / rt_l);
  st.mean_work = work / static_cast<double>(traj.size());
  st.mean_levels = levels / static_cast<double>(traj.size());
  return st;
}

void print_row(std::FILE* out, const char* name, const Built& b, const ReportOptions& o, const RunStats& st,
               const char* work) {
  std::fprintf(out,
               "| %-24s | %9zu | %3.1f / %3.1f | %6.1f MB | %5.1f s | %6.1f | %6.1f | %6.1f | %6.1f | %5.2f%% | "
               "%5.2f%% | %5.2f%% | %5.2f%% | %s |\n",
               name, b.scene_triangles, o.scene_voxel * 1e3, o.shell_voxel * 1e3, b.memory() / 1e6,
               b.scene_build_cpu + b.tools_build_cpu, percentile(st.cpu_us, 0.5), percentile(st.cpu_us, 0.99),
               percentile(st.best_us, 0.5), percentile(st.best_us, 0.99), 100 * st.f_err_r, 100 * st.f_err_l,
               100 * st.t_err_r, 100 * st.t_err_l, work);
}

}  // namespace

int run_report(const ReportOptions& o, std::FILE* out) {
  if (!(o.scene_voxel > 0) || !(o.shell_voxel > 0) || o.ticks < 10 || o.repeats < 1 || o.fcl_every < 0 ||
      o.bosses < 1 || o.bosses > 100 || o.paper_bosses < 0 || o.paper_bosses > 100) {
    std::fprintf(out, "error: invalid report options\n");
    return 1;
  }
  const vps::AssemblyLayout L;
  std::vector<Truth> traj;
  traj.reserve(static_cast<std::size_t>(o.ticks));
  double max_pen = 0;
  for (int k = 0; k < o.ticks; ++k) {
    traj.push_back(report_pose(k * 1e-3, L));
    if (!traj.back().valid) {
      std::fprintf(out, "error: report trajectory pose %d leaves its faces (internal)\n", k);
      return 1;
    }
    max_pen = std::max(max_pen, traj.back().max_penetration);
  }
  // Distance layers: deep enough for the deepest penetration the LWR-class
  // coupling of the tank is expected to produce (its force at a 5 mm lead of
  // the hand, capped by 150 N, over the tank's bottom face) and for the
  // trajectory's scripted 3 mm, whichever is deeper; and at least 4, because
  // beyond the layers a voxel's clearance is only known as "more than the
  // layers", which limits culling (measured on this scene: 2 -> 3 -> 4 -> 6
  // layers cost 5470 -> 4235 -> 3846 -> 3653 work per cycle, 21 -> 26 -> 27
  // -> 34 MB).
  vps::CouplingDeviceLimits lwr;
  lwr.peak_force = 150.0;
  lwr.max_stiffness = 5000.0;
  lwr.renders_torque = true;
  lwr.peak_torque = 25.0;
  lwr.max_rot_stiffness = 300.0;
  const vps::BimanualScene sc = vps::make_assembly_scene(o.bosses, L);
  mesh::MeshReport rep;
  mesh::TriangleMesh valid;
  if (auto e = mesh::validate_mesh(sc.right, {}, &valid, &rep)) {
    std::fprintf(out, "error: tank mesh: %s\n", e->message.c_str());
    return 1;
  }
  const auto tank = mesh::compute_mass_properties(valid, 1000.0);
  const vps::CouplingParams cpl = vps::design_coupling(tank.mass, tank.inertia_com, lwr).params;
  const double bottom = 4 * L.tank_half.x() * L.tank_half.y();
  const double p_coupling = vps::max_expected_penetration(cpl, 0.005, lwr.peak_force, kStiffness * bottom);
  const int layers_pen = vps::layers_for_depth(std::max(p_coupling, max_pen), o.scene_voxel);
  const int layers = o.layers > 0 ? o.layers : std::max(4, layers_pen);
  std::fprintf(out,
               "VPS engine report: assembly scene %zu triangles (%d bosses of 81,920), tank %zu, drill %zu; %d ticks "
               "x %d passes\n  distance layers %d (penetration needs %d: coupling's maximum expected penetration %.2f mm, "
               "K_c %.0f N/m at 5 mm lead, 150 N cap, over the tank's %.0f mm^2 face at K %.0e N/m^3; trajectory %.1f "
               "mm; culling wants at least 4)\n",
               sc.scene.triangles.size(), o.bosses, sc.right.triangles.size(), sc.left.triangles.size(), o.ticks,
               o.repeats, layers, layers_pen, p_coupling * 1e3, cpl.k_lin, bottom * 1e6, kStiffness, max_pen * 1e3);

  Built b;
  if (!build(o, o.bosses, layers, sc, &b, out)) return 1;
  std::fprintf(out,
               "  scene voxmap: %.1f mm voxels, %zu blocks, %.1f MB, build %.1f s CPU (%.1f s wall); tools: %zu + %zu "
               "pointshell points in %d levels, left voxmap %.1f MB, %.1f s CPU\n",
               o.scene_voxel * 1e3, b.scene.blocks.size(), b.scene.memory_bytes() / 1e6, b.scene_build_cpu,
               b.scene_build_wall, b.right.size(), b.left.size(), b.right.levels, b.left_vm.memory_bytes() / 1e6,
               b.tools_build_cpu);
  vps::BimanualModel model;
  model.scene = &b.scene;
  model.right = {nullptr, &b.right};
  model.left = {&b.left_vm, &b.left};
  model.params.stiffness = kStiffness;
  // Torque errors are scaled by the tools' radii about their references.
  const double r_right = L.tank_half.norm(), r_left = L.drill_ball_radius;

  std::fprintf(out,
               "\n| run                      | scene tris | voxel mm  | memory    | build   | CPU us | p99    | "
               "best50 | best99 | F err R | F err L | T err R | T err L | work / levels |\n"
               "|--------------------------|-----------:|-----------|----------:|--------:|-------:|-------:|-------:|"
               "-------:|--------:|--------:|--------:|--------:|---------------|\n");
  const RunStats full = run_mode(model, traj, o.repeats, vps::kUnlimitedWork, r_right, r_left);
  char work[64];
  std::snprintf(work, sizeof work, "%.0f / all", full.mean_work);
  print_row(out, "VPS full cycle", b, o, full, work);

  for (const std::int64_t budget : o.budgets) {
    const RunStats st = run_mode(model, traj, o.repeats, budget, r_right, r_left);
    char name[64];
    std::snprintf(name, sizeof name, "VPS time-critical %lld", static_cast<long long>(budget));
    std::snprintf(work, sizeof work, "%.0f / %.1f (min %d)", st.mean_work, st.mean_levels, st.min_levels);
    print_row(out, name, b, o, st, work);
  }
  if (o.fcl_every > 0) {
    const double c0 = thread_cpu_seconds();
    auto fs = fcl_model(sc.scene);
    auto fr = fcl_model(sc.right);
    auto fl = fcl_model(sc.left);
    const double fcl_build = thread_cpu_seconds() - c0;
    fcl::CollisionObjectd os(fs, fcl::Transform3d::Identity());
    fcl::CollisionObjectd orr(fr, fcl::Transform3d::Identity());
    fcl::CollisionObjectd ol(fl, fcl::Transform3d::Identity());
    std::vector<double> cpu;
    std::size_t contacts = 0;
    int n = 0;
    for (std::size_t k = 0; k < traj.size(); k += static_cast<std::size_t>(o.fcl_every)) {
      orr.setTransform(fcl::Transform3d(traj[k].right.matrix()));
      ol.setTransform(fcl::Transform3d(traj[k].left.matrix()));
      orr.computeAABB();
      ol.computeAABB();
      const double t0 = thread_cpu_seconds();
      for (int pair = 0; pair < 3; ++pair) {
        fcl::CollisionRequestd req(100000, true);
        fcl::CollisionResultd res;
        if (pair == 0) fcl::collide(&orr, &os, req, res);
        if (pair == 1) fcl::collide(&ol, &os, req, res);
        if (pair == 2) fcl::collide(&orr, &ol, req, res);
        contacts += res.numContacts();
      }
      cpu.push_back((thread_cpu_seconds() - t0) * 1e6);
      ++n;
    }
    std::fprintf(out,
                 "| FCL 0.7 OBBRSS collide   | %9zu | triangles | (BVH)     | %5.1f s | %6.1f | %6.1f |        |     "
                 "   |     contacts only, no force     | %.0f contacts  |\n",
                 sc.scene.triangles.size(), fcl_build, percentile(cpu, 0.5), percentile(cpu, 0.99),
                 n > 0 ? static_cast<double>(contacts) / n : 0.0);
  }
  if (o.paper_bosses > 0) {
    const vps::BimanualScene big = vps::make_assembly_scene(o.paper_bosses, L);
    Built pb;
    if (!build(o, o.paper_bosses, layers, big, &pb, out)) return 1;
    vps::BimanualModel m2 = model;
    m2.scene = &pb.scene;
    m2.right = {nullptr, &pb.right};
    m2.left = {&pb.left_vm, &pb.left};
    const RunStats st = run_mode(m2, traj, o.repeats, vps::kUnlimitedWork, r_right, r_left);
    std::snprintf(work, sizeof work, "%.0f / all", st.mean_work);
    print_row(out, "VPS full, paper scale", pb, o, st, work);
  }
  std::fprintf(out,
               "\nFull cycle, mean per pair (sphere nodes visited / points tested / points in contact): tank-scene "
               "%.0f / %.0f / %.0f, drill-scene %.0f / %.0f / %.0f, tank-drill %.0f / %.0f / %.0f\n",
               full.pair_nodes[0], full.pair_points[0], full.pair_contacts[0], full.pair_nodes[1], full.pair_points[1],
               full.pair_contacts[1], full.pair_nodes[2], full.pair_points[2], full.pair_contacts[2]);
  std::fprintf(out,
               "CPU us: thread CPU time per three-pair cycle, median and p99 over all cycles of all passes; best50 / "
               "best99: the same over each pose's fastest pass.\nF err: RMS over the trajectory of |F - F_exact| over "
               "RMS |F_exact|, total wrench on each tool (R tank, L drill); T err: RMS |tau - tau_exact| over RMS "
               "(|F_exact| r), r the tool's radius about its reference (%.0f, %.0f mm).\nMemory: scene voxmap + both "
               "pointshells + the drill's voxmap. Build: CPU seconds of the scene voxmap and the tools.\nTarget: "
               "full-cycle p99 <= 250 us at <= 2 %% RMS force error.\n",
               r_right * 1e3, r_left * 1e3);
  return 0;
}

}  // namespace hemm::vps_tool
