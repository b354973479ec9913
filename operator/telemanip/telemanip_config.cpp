#include "operator/telemanip/telemanip_config.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/haptics/passivity/tdpa_wire.h"

namespace hemm::op::telemanip {

bool parse_feedback_mode(const std::string& s, FeedbackMode* out) {
  if (s == "model") {
    *out = FeedbackMode::kModel;
  } else if (s == "direct") {
    *out = FeedbackMode::kDirect;
  } else {
    return false;
  }
  return true;
}

std::string telemanip_params(const config::TelemanipConfig& c, double period_s, const device::DeviceLimits& limits,
                             TelemanipTaskParams* task, TelemanipLinkParams* link,
                             const config::OperatorPassivityConfig* passivity) {
  if (!(std::isfinite(c.yaw_a_d_deg()) && std::abs(c.yaw_a_d_deg()) <= 360.0))
    return "telemanip.yaw_a_d_deg: must be finite, within +-360";
  if (std::string e = check_scales(c.translation_scale(), c.rotation_scale()); !e.empty()) return "telemanip." + e;
  if (!(c.max_speed_mps() > 0.0 && c.max_speed_mps() <= 5.0)) return "telemanip.max_speed_mps: must be in (0, 5]";
  if (!(c.max_rate_radps() > 0.0 && c.max_rate_radps() <= 20.0)) return "telemanip.max_rate_radps: must be in (0, 20]";
  if (limits.end_effectors != kTeleArms) return "telemanip: the device must have two end-effectors (sim-bimanual)";
  TelemanipTaskParams t;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(c.yaw_a_d_deg() * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ())
                                .toRotationMatrix();
  const config::TelemanipArmConfig* arms[kTeleArms] = {&c.right(), &c.left()};
  const char* names[kTeleArms] = {"right", "left"};
  for (int k = 0; k < kTeleArms; ++k) {
    ArmMappingParams& m = t.mapping[static_cast<std::size_t>(k)];
    const config::TelemanipArmConfig& a = *arms[k];
    m.R_A_D = R;
    m.translation_scale = c.translation_scale();
    m.rotation_scale = c.rotation_scale();
    m.max_step_m = c.max_speed_mps() * period_s;
    m.max_step_rad = c.max_rate_radps() * period_s;
    if (a.deadman_ee() > 1) return std::string("telemanip.") + names[k] + ".deadman_ee: must be 0 or 1";
    m.deadman_ee = static_cast<int>(a.deadman_ee());
    if (a.clutch_button() > 8) return std::string("telemanip.") + names[k] + ".clutch_button: must be 0 (none) or 1-8";
    m.clutch_button = static_cast<int>(a.clutch_button());
    m.opening_open_m = a.opening_open_m();
    m.opening_closed_m = a.opening_closed_m();
    m.force_open_n = a.force_open_n();
    m.force_closed_n = a.force_closed_n();
    for (double o : {m.opening_open_m, m.opening_closed_m})
      if (!(o >= 0.0 && o <= 0.22)) return std::string("telemanip.") + names[k] + ": openings must be in [0, 0.22] m";
    for (double f : {m.force_open_n, m.force_closed_n})
      if (!(f >= 0.0 && f <= 100.0)) return std::string("telemanip.") + names[k] + ": forces must be in [0, 100] N";
    if (std::string e = validate(m); !e.empty()) return std::string("telemanip.") + names[k] + ": " + e;
    t.limits[static_cast<std::size_t>(k)] = limits.ee[static_cast<std::size_t>(k)];
  }
  if (!parse_feedback_mode(c.mode(), &t.mode)) return "telemanip.mode: \"model\" or \"direct\"";
  if (!(std::isfinite(c.direct_fade_s()) && c.direct_fade_s() > 0.0 && c.direct_fade_s() <= 2.0))
    return "telemanip.direct_fade_s: must be in (0, 2]";
  const config::OperatorPassivityConfig pc_default;
  const tdpa::PcMode pc = tdpa::pc_mode_from(passivity != nullptr ? *passivity : pc_default);
  for (int k = 0; k < kTeleArms; ++k) {
    DirectHandParams& d = t.direct[static_cast<std::size_t>(k)];
    const ArmMappingParams& m = t.mapping[static_cast<std::size_t>(k)];
    d.R_A_D = m.R_A_D;
    d.translation_scale = m.translation_scale;
    d.rotation_scale = m.rotation_scale;
    d.max_speed_mps = c.max_speed_mps();
    d.max_rate_radps = c.max_rate_radps();
    d.fade_s = c.direct_fade_s();
    d.peak_force_n = std::max(0.0, limits.ee[static_cast<std::size_t>(k)].peak_force);
    d.renders_torque = limits.ee[static_cast<std::size_t>(k)].renders_torque;
    d.peak_torque_nm = std::max(0.0, limits.ee[static_cast<std::size_t>(k)].peak_torque);
    d.pc_mode = pc;
  }
  // The direct mode feels the robot's wrench, not the model: no VPS, no live voxmap.
  t.render = t.mode == FeedbackMode::kModel && c.render();
  t.contact_stiffness = c.contact_stiffness();
  t.tick_budget_ns = c.tick_budget_ns();
  t.period_s = period_s;
  const config::TelemanipHeldConfig& h = c.held();
  t.held.weight = h.weight();
  t.held.coupling = h.coupling();
  t.held.stiffness_n_per_m = h.stiffness_n_per_m();
  t.held.damping_ns_per_m = h.damping_ns_per_m();
  t.held.rot_stiffness_nm_per_rad = h.rot_stiffness_nm_per_rad();
  t.held.max_force_n = h.max_force_n();
  t.held.max_torque_nm = h.max_torque_nm();
  t.held.coupling_fade_s = h.coupling_fade_s();
  t.grasp_palm_contact = h.palm_contact();
  t.held.weight_filter_s = h.weight_filter_s();
  t.held.weight_rate_n_per_s = h.weight_rate_n_per_s();
  t.held.max_weight_n = h.max_weight_n();
  if (std::string e = validate(t.held); !e.empty()) return "telemanip.held: " + e;
  if (std::string e = validate(t); !e.empty()) return "telemanip: " + e;
  TelemanipLinkParams l;
  l.rate_hz = c.command_rate_hz();
  l.pc_mode = pc;
  if (!(l.rate_hz >= 100.0 && l.rate_hz <= 1000.0)) return "telemanip.command_rate_hz: must be in [100, 1000]";
  if (c.human_script() != "demo" && c.human_script() != "idle") return "telemanip.human_script: demo or idle";
  *task = t;
  *link = l;
  return {};
}

}  // namespace hemm::op::telemanip
