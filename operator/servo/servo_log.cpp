#include "operator/servo/servo_log.h"

#include <array>
#include <stdexcept>

#include "operator/device/csv_row.h"

namespace hemm::servo {
namespace {

// End-effector 0's columns of the original one-end-effector log, and the
// columns added with the 6-DoF device API; further end-effectors carry both
// lists with an "ee<k>_" prefix.
constexpr const char* kLegacyColumns[] = {"dev_x",  "dev_y",  "dev_z",  "dev_vx", "dev_vy", "dev_vz", "proxy_x",
                                          "proxy_y", "proxy_z", "ip_x",  "ip_y",   "ip_z",   "fx",     "fy",
                                          "fz",     "buttons"};
constexpr const char* kExtraColumns[] = {"dev_qw", "dev_qx",  "dev_qy",  "dev_qz", "dev_wx", "dev_wy", "dev_wz",
                                         "tx",     "ty",      "tz",      "grip_force", "enabled", "inputs",
                                         "deadman", "grip",   "grip_v",  "joy_x",  "joy_y",  "switch", "attached"};

void add_columns(std::string& h, const char* const* names, std::size_t n, const std::string& prefix) {
  for (std::size_t i = 0; i < n; ++i) h += "," + prefix + names[i];
}

std::string make_header(int end_effectors) {
  std::string h = "t_ns,tick,wake_latency_ns,compute_ns";
  add_columns(h, kLegacyColumns, std::size(kLegacyColumns), "");
  h += ",mode,model_age_ns,model_version,link_rtt_ns,link_offset_ns";
  add_columns(h, kExtraColumns, std::size(kExtraColumns), "");
  for (int k = 1; k < end_effectors; ++k) {
    const std::string prefix = "ee" + std::to_string(k) + "_";
    add_columns(h, kLegacyColumns, std::size(kLegacyColumns), prefix);
    add_columns(h, kExtraColumns, std::size(kExtraColumns), prefix);
  }
  return h;
}

// Must write exactly kLegacyColumns / kExtraColumns, in their order.
void put_legacy(device::CsvRowWriter& w, const ServoLogEndEffector& e) {
  w.put_vector(e.position);
  w.put_vector(e.velocity);
  w.put_vector(e.proxy_position);
  w.put_vector(e.interaction_point);
  w.put_vector(e.force);
  w.put(e.buttons);
}
void put_extra(device::CsvRowWriter& w, const ServoLogEndEffector& e) {
  w.put_vector(e.orientation);
  w.put_vector(e.angular_velocity);
  w.put_vector(e.torque);
  w.put(e.grip_force);
  w.put(e.enabled);
  w.put(e.inputs);
  w.put(e.deadman);
  w.put(e.grip_position);
  w.put(e.grip_velocity);
  w.put_vector(e.joystick);
  w.put(e.switch_on);
  w.put(e.attached);
}

}  // namespace

const std::string& servo_log_header(int end_effectors) {
  static const std::array<std::string, device::kMaxEndEffectors> headers = [] {
    std::array<std::string, device::kMaxEndEffectors> a;
    for (int n = 1; n <= device::kMaxEndEffectors; ++n) a[static_cast<std::size_t>(n - 1)] = make_header(n);
    return a;
  }();
  if (end_effectors < 1 || end_effectors > device::kMaxEndEffectors)
    throw std::invalid_argument("servo_log_header: end_effectors out of range");
  return headers[static_cast<std::size_t>(end_effectors - 1)];
}

std::size_t format_servo_log_record(const ServoLogRecord& r, char* buf, std::size_t size) {
  if (r.end_effectors < 1 || r.end_effectors > device::kMaxEndEffectors) return 0;
  device::CsvRowWriter w(buf, size);
  w.put(r.t_ns);
  w.put(r.tick);
  w.put(r.wake_latency_ns);
  w.put(r.compute_ns);
  put_legacy(w, r.ee[0]);
  w.put(r.mode);
  w.put(r.model_age_ns);
  w.put(r.model_version);
  w.put(r.link_rtt_ns);
  w.put(r.link_offset_ns);
  put_extra(w, r.ee[0]);
  for (int k = 1; k < r.end_effectors; ++k) {
    put_legacy(w, r.ee[k]);
    put_extra(w, r.ee[k]);
  }
  return w.finish();
}

}  // namespace hemm::servo
