#include "operator/vps/vps_config.h"

#include <cmath>
#include <stdexcept>

#include "common/config/config.h"
#include "operator/device/hand_script.h"
#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/device/trajectory_csv.h"
#include "operator/vps/vps_session.h"

namespace hemm::op {

namespace {

[[noreturn]] void fail(const std::string& field, const std::string& message) {
  throw std::invalid_argument(field + ": " + message);
}

VpsMeshSpec mesh_spec(const config::VpsMeshConfig& c, const std::string& field, const std::string& config_path) {
  if (c.mesh().empty()) fail(field + ".mesh", "required");
  VpsMeshSpec s;
  s.mesh_path = config::resolve_relative_to(config_path, c.mesh());
  s.scale = c.scale();
  s.voxel_size = c.voxel_m();
  s.shell_voxel = c.shell_voxel_m();
  if (c.layers() > 100) fail(field + ".layers", "must be 1..100");
  s.layers = static_cast<int>(c.layers());
  s.density = c.density();
  s.mass = c.mass_kg();
  if (const char* bad = check_mesh_spec(s)) fail(field, bad);
  return s;
}

VpsEndEffectorParams ee_params(const config::VpsEndEffectorConfig& c, const std::string& field) {
  VpsEndEffectorParams p;
  const Eigen::Vector3d o(c.h_origin_x(), c.h_origin_y(), c.h_origin_z());
  if (!o.allFinite() || o.cwiseAbs().maxCoeff() > 100) fail(field + ".h_origin", "must be finite, within 100 m");
  p.T_W_H.translation() = o;
  if (c.h_y_up()) p.T_W_H.linear() << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // x_W = x_H, y_W = -z_H, z_W = y_H
  return p;
}

}  // namespace

VpsSetup vps_setup(const config::OperatorConfig& cfg, const std::string& config_path) {
  const config::VpsSceneConfig& v = cfg.vps();
  VpsSetup s;
  s.model.scene = mesh_spec(v.scene(), "vps.scene", config_path);
  if (!v.has_right()) fail("vps.right", "required (the object of end-effector 0)");
  s.model.objects[0] = mesh_spec(v.right().object(), "vps.right.object", config_path);
  s.task.ee[0] = ee_params(v.right(), "vps.right");
  if (v.has_left()) {
    s.model.objects[1] = mesh_spec(v.left().object(), "vps.left.object", config_path);
    s.task.ee[1] = ee_params(v.left(), "vps.left");
  }
  s.model.cache_dir = v.cache_dir().empty() ? std::string() : config::resolve_relative_to(config_path, v.cache_dir());
  if (!(v.contact_stiffness() > 0 && v.contact_stiffness() < 1e12))
    fail("vps.contact_stiffness", "must be in (0, 1e12) N/m^3");
  s.model.contact.stiffness = v.contact_stiffness();
  if (v.work_budget() < 0) fail("vps.work_budget", "must be >= 0 (0: the full cycle)");
  s.task.budget = v.work_budget() == 0 ? vps::kUnlimitedWork : v.work_budget();
  if (!v.hands().empty() && v.hands() != "peg-in-hole" && v.hands() != "assembly")
    fail("vps.hands", "must be \"\", \"peg-in-hole\" or \"assembly\"");
  if (!v.hands().empty() && !v.has_left()) fail("vps.left", "required with scripted hands (two end-effectors)");
  return s;
}

std::unique_ptr<device::HapticDevice> make_vps_device(const config::OperatorConfig& cfg,
                                                      const std::string& replay_file) {
  const config::VpsSceneConfig& v = cfg.vps();
  if (!v.hands().empty()) {
    const int n = v.has_left() ? 2 : 1;
    return std::make_unique<device::ReplayDevice>(scene_hands_trajectory(v.hands()), scripted_hands_limits(n));
  }
  const std::string& type = replay_file.empty() ? cfg.device().type() : std::string("replay");
  if (type == "replay") {
    if (replay_file.empty()) fail("device.replay_file", "required for a replayed device");
    // A replayed trajectory says how many end-effectors it has; the limits
    // are the scripted hands' for two, the Omni's for one.
    device::Trajectory tr;
    device::DeviceLimits limits = scripted_hands_limits(v.has_left() ? 2 : 1);
    if (auto e = device::load_trajectory_csv(replay_file, limits, &tr)) throw std::runtime_error(e->to_string());
    return std::make_unique<device::ReplayDevice>(std::move(tr), limits);
  }
  if (type != "sim-omni") fail("device.type", "the VPS scene runs with sim-omni or replay (or vps.hands)");
  if (v.has_left()) fail("vps.left", "the Omni has one end-effector");
  if (v.omni_waypoints_size() == 0) fail("vps.omni_waypoints", "required for the SIMULATED Omni's hand");
  std::vector<device::Waypoint> w;
  double last = -1;
  for (int i = 0; i < v.omni_waypoints_size(); ++i) {
    const auto& c = v.omni_waypoints(i);
    const Eigen::Vector3d p(c.x(), c.y(), c.z());
    const std::string f = "vps.omni_waypoints[" + std::to_string(i) + "]";
    if (!std::isfinite(c.t_s()) || !(c.t_s() > last)) fail(f + ".t_s", "times must increase");
    if (!p.allFinite() || !device::phantom_omni_limits().ee[0].contains(p)) fail(f, "outside the Omni's workspace");
    last = c.t_s();
    w.push_back({c.t_s(), p, 0});
  }
  return std::make_unique<device::SimulatedOmni>(device::SimulatedOmniModel{},
                                                 std::make_shared<device::WaypointScript>(std::move(w)));
}

}  // namespace hemm::op
