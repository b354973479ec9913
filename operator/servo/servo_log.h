// The servo loop's 1 kHz log record: fixed size, trivially copyable, plain
// numbers only (frame H, SI units, ns), so the servo thread can copy it into
// a ring without allocating.
//
// The CSV has the columns the one-end-effector log always had, with their
// names, for end-effector 0 (readers find columns by name: the plots, the
// latency suite), then end-effector 0's further columns, then one full group
// per further end-effector, its names prefixed "ee<k>_":
//   t_ns,tick,wake_latency_ns,compute_ns,
//   dev_x,dev_y,dev_z,dev_vx,dev_vy,dev_vz,proxy_x,proxy_y,proxy_z,ip_x,ip_y,ip_z,fx,fy,fz,buttons,
//   mode,model_age_ns,model_version,link_rtt_ns,link_offset_ns,
//   dev_qw,dev_qx,dev_qy,dev_qz,dev_wx,dev_wy,dev_wz,tx,ty,tz,grip_force,
//   enabled,inputs,deadman,grip,grip_v,joy_x,joy_y,switch,attached
//   [,ee1_dev_x,...,ee1_buttons,ee1_dev_qw,...,ee1_attached]
// (dev_q* the orientation quaternion, dev_w* the angular velocity, t* the
// commanded torque, inputs the handle's kHas* bits, then its inputs).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>

#include "operator/device/haptic_device.h"
#include "operator/servo/csv_logger.h"

namespace hemm::servo {

// One end-effector in a log record.
struct ServoLogEndEffector {
  double position[3] = {0, 0, 0};
  double orientation[4] = {1, 0, 0, 0};  // w, x, y, z
  double velocity[3] = {0, 0, 0};
  double angular_velocity[3] = {0, 0, 0};
  double proxy_position[3] = {0, 0, 0};
  double interaction_point[3] = {0, 0, 0};
  double force[3] = {0, 0, 0};   // as commanded to the device
  double torque[3] = {0, 0, 0};  // as commanded
  double grip_force = 0.0;       // as commanded
  std::uint32_t buttons = 0;
  std::uint32_t inputs = 0;  // device::kHas* bits
  int enabled = 1;
  int deadman = 0;
  int switch_on = 0;
  int attached = 1;
  double grip_position = 0.0;
  double grip_velocity = 0.0;
  double joystick[2] = {0, 0};
};

struct ServoLogRecord {
  std::int64_t t_ns = 0;  // tick wake time (steady clock)
  std::uint64_t tick = 0;
  std::int64_t wake_latency_ns = 0;
  std::int64_t compute_ns = 0;  // wake -> just before this record was pushed
  std::uint32_t mode = 0;
  std::int64_t model_age_ns = -1;  // -1: no snapshot yet
  std::uint64_t model_version = 0;
  std::int64_t link_rtt_ns = -1;  // -1: unknown
  std::int64_t link_offset_ns = 0;
  int end_effectors = 1;  // valid entries of ee[]
  ServoLogEndEffector ee[device::kMaxEndEffectors];
};
static_assert(std::is_trivially_copyable_v<ServoLogRecord>);

// The header for a device with `end_effectors` end-effectors (1 ..
// kMaxEndEffectors; throws std::invalid_argument otherwise).
const std::string& servo_log_header(int end_effectors = 1);
// Writes r.end_effectors groups; 0 if buf is too small or the count is out of range.
std::size_t format_servo_log_record(const ServoLogRecord& r, char* buf, std::size_t size);

using ServoLogger = CsvLogger<ServoLogRecord>;
// A logger for the servo log of a device with `end_effectors` end-effectors.
inline ServoLogger make_servo_logger(std::size_t capacity = 8192, int end_effectors = 1) {
  return ServoLogger(capacity, servo_log_header(end_effectors), &format_servo_log_record);
}

}  // namespace hemm::servo
