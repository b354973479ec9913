#include "operator/vps/vps_config.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "common/config/config.h"
#include "operator/device/hand_script.h"
#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/device/trajectory_csv.h"
#include "operator/vps/vps_bimanual.h"
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
  const Eigen::Vector3d h_r(c.h_rx(), c.h_ry(), c.h_rz());
  if (!h_r.allFinite() || h_r.norm() > std::numbers::pi + 1e-9)
    fail(field + ".h_rx", "the device frame's rotation vector must be finite, at most pi rad");
  if (h_r.norm() > 0) p.T_W_H.linear() = Eigen::AngleAxisd(h_r.norm(), h_r.normalized()).toRotationMatrix() * p.T_W_H.linear();
  // A hand-held object: its mesh frame within half a metre of the hand.
  const Eigen::Vector3d g(c.grasp_x(), c.grasp_y(), c.grasp_z());
  if (!g.allFinite() || g.norm() > 0.5) fail(field + ".grasp_x", "the grasp's origin must be finite, within 0.5 m of E");
  const Eigen::Vector3d r(c.grasp_rx(), c.grasp_ry(), c.grasp_rz());
  if (!r.allFinite() || r.norm() > std::numbers::pi + 1e-9)
    fail(field + ".grasp_rx", "the grasp's rotation vector must be finite, at most pi rad");
  p.T_E_M.translation() = g;
  if (r.norm() > 0) p.T_E_M.linear() = Eigen::AngleAxisd(r.norm(), r.normalized()).toRotationMatrix();
  return p;
}

std::array<VpsEndEffectorParams, device::kMaxEndEffectors> ee_mappings(const config::VpsSceneConfig& v) {
  std::array<VpsEndEffectorParams, device::kMaxEndEffectors> m{};
  m[0] = ee_params(v.right(), "vps.right");
  if (v.has_left()) m[1] = ee_params(v.left(), "vps.left");
  return m;
}

}  // namespace

VpsSetup vps_setup(const config::OperatorConfig& cfg, const std::string& config_path) {
  const config::VpsSceneConfig& v = cfg.vps();
  VpsSetup s;
  s.model.scene = mesh_spec(v.scene(), "vps.scene", config_path);
  if (!v.has_right()) fail("vps.right", "required (the object of end-effector 0)");
  s.model.objects[0] = mesh_spec(v.right().object(), "vps.right.object", config_path);
  if (v.has_left()) s.model.objects[1] = mesh_spec(v.left().object(), "vps.left.object", config_path);
  s.task.ee = ee_mappings(v);
  s.model.cache_dir = v.cache_dir().empty() ? std::string() : config::resolve_relative_to(config_path, v.cache_dir());
  if (!(v.contact_stiffness() > 0 && v.contact_stiffness() < 1e12))
    fail("vps.contact_stiffness", "must be in (0, 1e12) N/m^3");
  s.model.contact.stiffness = v.contact_stiffness();
  if (v.work_budget() < 0) fail("vps.work_budget", "must be >= 0 (0: the full cycle)");
  s.task.budget = v.work_budget() == 0 ? vps::kUnlimitedWork : v.work_budget();
  if (!(v.tick_budget_us() >= 0 && v.tick_budget_us() <= 100'000))
    fail("vps.tick_budget_us", "must be in [0, 100000] (0: no time budget)");
  if (!(v.tick_margin_us() >= 0 && v.tick_margin_us() <= 100'000)) fail("vps.tick_margin_us", "must be in [0, 100000]");
  s.task.tick_budget_ns = std::llround(v.tick_budget_us() * 1e3);
  s.task.tick_margin_ns = std::llround(v.tick_margin_us() * 1e3);
  if (!v.hands().empty() && v.hands() != "peg-in-hole" && v.hands() != "assembly")
    fail("vps.hands", "must be \"\", \"peg-in-hole\" or \"assembly\"");
  if (!v.hands().empty() && !v.has_left()) fail("vps.left", "required with scripted hands (two end-effectors)");
  return s;
}

std::unique_ptr<device::HapticDevice> make_vps_device(const config::OperatorConfig& cfg,
                                                      const std::string& replay_file) {
  const config::VpsSceneConfig& v = cfg.vps();
  const std::string& type = replay_file.empty() ? cfg.device().type() : std::string("replay");
  if (type == "sim-bimanual") {
    if (v.hands().empty())
      fail("vps.hands", "the SIMULATED bimanual device's humans follow a scene's scripted hands: \"peg-in-hole\" or "
                        "\"assembly\"");
    if (!v.has_left()) fail("vps.left", "required with the bimanual device (two end-effectors)");
    if (cfg.servo().rate_hz() < 100 || cfg.servo().rate_hz() > 10000) fail("servo.rate_hz", "must be in [100, 10000]");
    return make_vps_bimanual_device(cfg, v.hands(), ee_mappings(v), 1.0 / cfg.servo().rate_hz());
  }
  if (!v.hands().empty()) {
    const int n = v.has_left() ? 2 : 1;
    return std::make_unique<device::ReplayDevice>(scene_hands_trajectory(v.hands(), 1000.0, ee_mappings(v)),
                                                  scripted_hands_limits(n));
  }
  if (type == "replay") {
    if (replay_file.empty()) fail("device.replay_file", "required for a replayed device");
    // A replayed trajectory says how many end-effectors it has; the limits
    // are the scripted hands' for two, the Omni's for one.
    device::Trajectory tr;
    device::DeviceLimits limits = scripted_hands_limits(v.has_left() ? 2 : 1);
    if (auto e = device::load_trajectory_csv(replay_file, limits, &tr)) throw std::runtime_error(e->to_string());
    return std::make_unique<device::ReplayDevice>(std::move(tr), limits);
  }
  if (type != "sim-omni") fail("device.type", "the VPS scene runs with sim-omni, replay or sim-bimanual (or vps.hands)");
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

double vps_default_duration_s(const config::OperatorConfig& cfg) {
  const config::VpsSceneConfig& v = cfg.vps();
  if (v.hands().empty()) return 0.0;
  // The rigid hands are at rest when their path ends; the SIMULATED humans
  // of the bimanual device lag it and settle after it (hand and felt arm
  // ~2.5 kg on the arm's 300 N/m spring with ~30 N s/m: ~0.7 s), and hold
  // the start first (kStartHold_s).
  const double hold = cfg.device().type() == "sim-bimanual" ? kStartHold_s + 1.5 : 0.5;
  return scene_hands(v.hands()).duration_s + hold;
}

}  // namespace hemm::op
