// hemm-operator with the SIMULATED bimanual interface: the device, its local
// environment task and the 1 kHz servo loop (absolute deadlines, the same
// ServoLoop as with the Omni), the 1 kHz log, and a summary (servo timing,
// the device's counters, the smallest arm-arm and arm-table gaps, MuJoCo's
// contact count, each arm's state at the end). No robot: until VPS arrives
// the environment is local (bimanual_task.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "operator/bimanual/bimanual_config.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/servo/servo_loop.h"
#include "operator/view/device_view_record.h"

namespace hemm::report {
class BimanualSession;  // report.pb.h
}

namespace hemm::op {

struct BimanualSessionOptions {
  BimanualSetup setup;
  servo::ServoConfig servo;
  std::string log_path;     // 1 kHz servo CSV; empty: none
  double duration_s = 0.0;  // 0: the script's own length
  DeviceViewTaps view;      // a live view, if any
};

struct BimanualSessionSummary {
  servo::TimingSummary timing;
  device::bimanual::BimanualDeviceCounters counters;
  double sim_time_s = 0.0;
  double min_arm_arm_m = 0.0;
  double min_arm_table_m = 0.0;
  std::uint64_t arm_arm_contact_steps = 0;
  std::uint64_t arm_table_contact_steps = 0;
  std::array<bool, device::bimanual::kArms> enabled{};
  std::array<bool, device::bimanual::kArms> attached{};
  std::uint64_t log_written = 0, log_dropped = 0;
  std::string script;
};

std::string to_string(const BimanualSessionSummary& s);
// As proto/report.proto's BimanualSession, and that printed (config::to_json).
report::BimanualSession to_report(const BimanualSessionSummary& s);
std::string to_json(const BimanualSessionSummary& s);

// Runs until the duration has passed on the wall clock or *stop becomes true
// (checked every 10 ms; may be null). Throws on a bad setup or an unwritable
// log. `on_started` (may be empty) gets the real-time status.
BimanualSessionSummary run_bimanual_session(const BimanualSessionOptions& o, const std::atomic<bool>* stop,
                                            void (*on_started)(const servo::RealtimeStatus&) = nullptr);

}  // namespace hemm::op
