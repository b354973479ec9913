#include "robot_side/truth/tool6_truth.h"

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "common/haptics/vps/voxmap.h"
#include "robot_side/truth/probe3_truth.h"
#include "robot_side/truth/scene_slice.h"

namespace hemm::robot {

bool read_tool6_world_log(const std::string& path, std::vector<Tool6Tick>* out, std::string* error) {
  std::ifstream in;
  std::map<std::string, std::size_t> col;
  if (!open_world_log_columns(path,
                              {"t_ns", "mode", "goal_x", "goal_y", "goal_z", "goal_qw", "goal_qx", "goal_qy", "goal_qz",
                               "fw_x", "fw_y", "fw_z", "tw_x", "tw_y", "tw_z", "tool_x", "tool_y", "tool_z",
                               "force_gain", "contacts", "tool_model"},
                              "a 6-DoF tool world log", &in, &col, error))
    return false;
  std::string line;
  std::vector<Tool6Tick> rows;
  std::vector<double> v;
  double t0 = NAN;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    v.clear();
    std::stringstream ss(line);
    std::string f;
    while (std::getline(ss, f, ',')) v.push_back(std::strtod(f.c_str(), nullptr));
    if (v.size() < col.size()) {
      *error = path + ":" + std::to_string(line_no) + ": short row";
      return false;
    }
    auto c = [&](const char* n) { return v[col.at(n)]; };
    Tool6Tick t;
    if (std::isnan(t0)) t0 = c("t_ns");
    t.t_s = (c("t_ns") - t0) * 1e-9;
    Eigen::Quaterniond q(c("goal_qw"), c("goal_qx"), c("goal_qy"), c("goal_qz"));
    t.goal.linear() = q.normalized().toRotationMatrix();
    t.goal.translation() = Eigen::Vector3d(c("goal_x"), c("goal_y"), c("goal_z"));
    t.force = Eigen::Vector3d(c("fw_x"), c("fw_y"), c("fw_z"));
    t.torque = Eigen::Vector3d(c("tw_x"), c("tw_y"), c("tw_z"));
    t.tool = Eigen::Vector3d(c("tool_x"), c("tool_y"), c("tool_z"));
    t.gain = c("force_gain");
    t.contacts = static_cast<int>(c("contacts"));
    t.mode = static_cast<int>(c("mode"));
    t.model = c("tool_model") != 0;
    rows.push_back(t);
  }
  *out = std::move(rows);
  return true;
}

bool read_tool6_params(const std::string& path, vps::ProbeToolGeometry* g, vps::ToolParams* p, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    *error = "cannot read " + path;
    return false;
  }
  std::map<std::string, double> kv;
  std::string k;
  double x;
  while (in >> k >> x) kv[k] = x;
  const char* need[] = {"tip_radius", "rod_radius", "rod_length", "tip_mass", "rod_mass", "spacing", "levels",
                        "stiffness", "budget", "dt", "mass", "ixx", "iyy", "izz", "k_lin", "b_lin", "k_rot", "b_rot",
                        "linear_damping", "angular_damping"};
  for (const char* n : need)
    if (!kv.count(n)) {
      *error = path + ": no " + n;
      return false;
    }
  g->tip_radius = kv["tip_radius"];
  g->rod_radius = kv["rod_radius"];
  g->rod_length = kv["rod_length"];
  g->tip_mass = kv["tip_mass"];
  g->rod_mass = kv["rod_mass"];
  g->spacing = kv["spacing"];
  g->levels = static_cast<int>(kv["levels"]);
  p->contact.stiffness = kv["stiffness"];
  p->budget = static_cast<std::int64_t>(kv["budget"]);
  vps::CouplingParams& c = p->coupling;
  c.dt = kv["dt"];
  c.mass = kv["mass"];
  c.inertia_body = Eigen::Vector3d(kv["ixx"], kv["iyy"], kv["izz"]).asDiagonal();
  c.k_lin = kv["k_lin"];
  c.b_lin = kv["b_lin"];
  c.k_rot = kv["k_rot"];
  c.b_rot = kv["b_rot"];
  c.linear_damping = kv["linear_damping"];
  c.angular_damping = kv["angular_damping"];
  if (std::string e = vps::validate(*g); !e.empty()) {
    *error = path + ": " + e;
    return false;
  }
  return true;
}

bool build_truth_voxmap(const std::string& scene, const Eigen::AlignedBox3d& region_W, double s, vps::Voxmap* out,
                        std::vector<std::string>* parts, std::string* error) {
  SceneMeshes m;
  if (!load_scene_meshes(scene, region_W, &m, error)) return false;
  mesh::TriangleMesh all;
  for (const SceneMeshPart& p : m.parts) {
    mesh::append_mesh(&all, p.mesh);
    if (parts != nullptr) parts->push_back(p.name);
  }
  vps::VoxmapParams vp;
  vp.voxel_size = s;
  vp.layers_out = vp.layers_in = 8;
  vp.roi = region_W;
  if (auto e = vps::build_voxmap(all, vp, out, nullptr)) {
    *error = "truth voxmap: " + e->message;
    return false;
  }
  return true;
}

Tool6Truth evaluate_tool6(const std::vector<Tool6Tick>& ticks, const vps::ProbeTool& tool,
                          const vps::ToolParams& params, const vps::Voxmap& vm) {
  std::vector<Eigen::Isometry3d> goals;
  std::vector<double> gain;
  std::vector<std::uint8_t> model;
  for (const Tool6Tick& t : ticks) {
    goals.push_back(t.goal);
    gain.push_back(t.gain);
    model.push_back(t.model ? 1 : 0);
  }
  Tool6Truth r;
  vps::replay_tool_path(params, tool, vm, goals, gain, model, &r.replay);
  double f2 = 0, t2 = 0;
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    const vps::Wrench& w = r.replay.wrench[i];
    r.true_force_peak = std::max(r.true_force_peak, w.force.norm());
    r.true_torque_peak = std::max(r.true_torque_peak, w.torque.norm());
    if (ticks[i].contacts == 0 && r.replay.contacts[i] == 0) continue;
    const double ef = (ticks[i].force - w.force).norm(), et = (ticks[i].torque - w.torque).norm();
    ++r.contact_ticks;
    f2 += ef * ef;
    t2 += et * et;
    r.force_max = std::max(r.force_max, ef);
    r.torque_max = std::max(r.torque_max, et);
  }
  if (r.contact_ticks > 0) {
    r.force_rms = std::sqrt(f2 / static_cast<double>(r.contact_ticks));
    r.torque_rms = std::sqrt(t2 / static_cast<double>(r.contact_ticks));
  }
  return r;
}

}  // namespace hemm::robot
