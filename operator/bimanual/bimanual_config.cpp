#include "operator/bimanual/bimanual_config.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "operator/bimanual/bimanual_scripts.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

namespace {

bool in(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

hb::ArmControlParams arm_params(const config::BimanualArmConfig& a, double activation) {
  hb::ArmControlParams p = hb::default_arm_control();
  p.elbow_force = a.elbow_force_n();
  p.projector = a.null_space_projector() == "kinematic" ? hb::NullSpaceProjector::kKinematic : hb::NullSpaceProjector::kDynamic;
  p.inertia_ratio_translation = a.inertia_ratio_translation();
  p.inertia_ratio_rotation = a.inertia_ratio_rotation();
  p.feedforward = a.inertia_ratio_translation() < 1.0 || a.inertia_ratio_rotation() < 1.0;
  p.peak_force = a.peak_force_n();
  p.peak_torque = a.peak_torque_nm();
  p.max_linear_speed = a.max_linear_speed_mps();
  p.collision.activation_m = activation;
  return p;
}

void check_arm(const config::BimanualArmConfig& a, const std::string& f, double max_stiffness,
               std::vector<config::FieldIssue>& out) {
  const auto handle = hb::handle_from_string(a.handle());
  if (!handle) out.push_back({f + "handle", "must be \"magnetic_clutch\", \"grip_force\" or \"joystick\""});
  if (!in(a.elbow_force_n(), 0.0, 100.0)) out.push_back({f + "elbow_force_n", "must be in [0, 100] N"});
  if (a.null_space_projector() != "kinematic" && a.null_space_projector() != "dynamic")
    out.push_back({f + "null_space_projector", "must be \"kinematic\" (Eq. 1-4) or \"dynamic\""});
  if (!in(a.inertia_ratio_translation(), 0.1, 1.0)) out.push_back({f + "inertia_ratio_translation", "must be in [0.1, 1]"});
  if (!in(a.inertia_ratio_rotation(), 0.1, 1.0)) out.push_back({f + "inertia_ratio_rotation", "must be in [0.1, 1]"});
  if (!(in(a.peak_force_n(), 0.0, 300.0) && a.peak_force_n() > 0.0)) out.push_back({f + "peak_force_n", "must be in (0, 300] N"});
  if (!(in(a.peak_torque_nm(), 0.0, 50.0) && a.peak_torque_nm() > 0.0))
    out.push_back({f + "peak_torque_nm", "must be in (0, 50] N m"});
  if (!(in(a.max_linear_speed_mps(), 0.0, 3.0) && a.max_linear_speed_mps() > 0.0))
    out.push_back({f + "max_linear_speed_mps", "must be in (0, 3] m/s"});
  const Eigen::Vector3d p(a.plane_point_x(), a.plane_point_y(), a.plane_point_z());
  const Eigen::Vector3d n(a.plane_normal_x(), a.plane_normal_y(), a.plane_normal_z());
  if (!p.allFinite() || p.norm() > 3.0) out.push_back({f + "plane_point_x", "the plane point must be finite, within 3 m"});
  if (!n.allFinite() || n.norm() < 1e-6) out.push_back({f + "plane_normal_x", "the plane normal must be finite and non-zero"});
  if (!(in(a.plane_stiffness_n_per_m(), 0.0, max_stiffness) && a.plane_stiffness_n_per_m() > 0.0))
    out.push_back({f + "plane_stiffness_n_per_m",
                   "must be in (0, " + std::to_string(static_cast<int>(max_stiffness)) + "] N/m (the device's max_stiffness)"});
  if (!in(a.plane_damping_ns_per_m(), 0.0, 500.0)) out.push_back({f + "plane_damping_ns_per_m", "must be in [0, 500] N s/m"});
  if (a.has_grip_object_at_m()) {
    if (handle && !hb::has_input(*handle, hb::HandleInput::kGrip))
      out.push_back({f + "grip_object_at_m", *hb::require_input(*handle, hb::HandleInput::kGrip)});
    else if (handle && !in(a.grip_object_at_m(), 0.0, hb::handle_spec(*handle).grip_travel))
      out.push_back({f + "grip_object_at_m", "must be within the lever's travel [0, " +
                                                 std::to_string(hb::handle_spec(*handle).grip_travel) + "] m"});
  }
  if (!in(a.grip_object_stiffness_n_per_m(), 0.0, 5000.0))
    out.push_back({f + "grip_object_stiffness_n_per_m", "must be in [0, 5000] N/m"});
}

}  // namespace

std::vector<config::FieldIssue> validate_bimanual_config(const config::BimanualDeviceConfig& c, const std::string& prefix) {
  std::vector<config::FieldIssue> out;
  if (!in(c.collision_activation_m(), 0.0, 0.5) || c.collision_activation_m() <= 0.0)
    out.push_back({prefix + "collision_activation_m", "must be in (0, 0.5] m"});
  if (!in(c.human_voluntary_force_n(), 0.0, 50.0))
    out.push_back({prefix + "human_voluntary_force_n", "must be in [0, 50] N"});
  const double max_k = hb::bimanual_limits(hb::SimulationConfig{}).ee[0].max_stiffness;
  check_arm(c.right(), prefix + "right.", max_k, out);
  check_arm(c.left(), prefix + "left.", max_k, out);
  const auto names = bimanual_script_names();
  if (std::find(names.begin(), names.end(), c.script()) == names.end()) {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    out.push_back({prefix + "script", "must be one of: " + list});
  }
  if (out.empty()) {
    // Whatever the field checks let through, the simulation's own validation has the last word.
    try {
      bimanual_setup(c);
    } catch (const std::exception& e) {
      out.push_back({prefix.substr(0, prefix.size() - 1), e.what()});
    }
  }
  return out;
}

std::vector<config::FieldIssue> validate_operator_config_with_bimanual(const google::protobuf::Message& m) {
  std::vector<config::FieldIssue> out = config::validate_operator_config(m);
  const auto& c = static_cast<const config::OperatorConfig&>(m);
  if (c.device().type() == "sim-bimanual") {
    auto more = validate_bimanual_config(c.device().bimanual());
    out.insert(out.end(), more.begin(), more.end());
  }
  return out;
}

BimanualSetup bimanual_setup(const config::BimanualDeviceConfig& c) {
  BimanualSetup s;
  s.script = c.script();
  if (c.ideal_actuators()) {
    s.sim.plant.actuators = hb::ideal_actuators(s.sim.plant.rig.arm);
    s.sim.plant.model_error = hb::ModelError{0.0, 0.0, 0.0, 1};
  }
  const config::BimanualArmConfig* arms[2] = {&c.right(), &c.left()};
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const config::BimanualArmConfig& ac = *arms[a];
    const auto handle = hb::handle_from_string(ac.handle());
    if (!handle) throw std::invalid_argument("unknown handle '" + ac.handle() + "'");
    s.sim.plant.handles[k] = *handle;
    s.sim.control[k] = arm_params(ac, c.collision_activation_m());
    if (c.human_co_contracting()) s.sim.plant.humans[k] = hb::co_contracting_human(0.0);
    s.sim.plant.humans[k].max_voluntary_force = c.human_voluntary_force_n();
    HandEnvironment& e = s.env[k];
    e.plane_point_H = Eigen::Vector3d(ac.plane_point_x(), ac.plane_point_y(), ac.plane_point_z());
    e.plane_normal_H = Eigen::Vector3d(ac.plane_normal_x(), ac.plane_normal_y(), ac.plane_normal_z()).normalized();
    e.plane_stiffness = ac.plane_stiffness_n_per_m();
    e.plane_damping = ac.plane_damping_ns_per_m();
    e.grip_object = ac.has_grip_object_at_m();
    e.grip_object_at_m = ac.grip_object_at_m();
    e.grip_object_stiffness = ac.grip_object_stiffness_n_per_m();
  }
  if (auto e = hb::validate(s.sim)) throw std::invalid_argument(*e);
  return s;
}

}  // namespace hemm::op
