// The servo loop's 1 kHz log record: fixed size, trivially copyable, plain
// numbers only (frame H, SI units, ns), so the servo thread can copy it into
// a ring without allocating.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "operator/servo/csv_logger.h"

namespace hemm::servo {

struct ServoLogRecord {
  std::int64_t t_ns = 0;  // tick wake time (steady clock)
  std::uint64_t tick = 0;
  std::int64_t wake_latency_ns = 0;
  std::int64_t compute_ns = 0;  // wake -> just before this record was pushed
  double device_position[3] = {0, 0, 0};
  double device_velocity[3] = {0, 0, 0};
  double proxy_position[3] = {0, 0, 0};
  double interaction_point[3] = {0, 0, 0};
  double force[3] = {0, 0, 0};  // as commanded to the device
  std::uint32_t buttons = 0;
  std::uint32_t mode = 0;
  std::int64_t model_age_ns = -1;  // -1: no snapshot yet
  std::uint64_t model_version = 0;
  std::int64_t link_rtt_ns = -1;  // -1: unknown
  std::int64_t link_offset_ns = 0;
};
static_assert(std::is_trivially_copyable_v<ServoLogRecord>);

const char* servo_log_header();
std::size_t format_servo_log_record(const ServoLogRecord& r, char* buf, std::size_t size);

using ServoLogger = CsvLogger<ServoLogRecord>;
// A logger for the servo log with the header and formatter above.
inline ServoLogger make_servo_logger(std::size_t capacity = 8192) {
  return ServoLogger(capacity, servo_log_header(), &format_servo_log_record);
}

}  // namespace hemm::servo
