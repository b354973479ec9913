#include "operator/bimanual/bimanual_session.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <thread>

#include "operator/bimanual/bimanual_scripts.h"
#include "operator/bimanual/bimanual_task.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

namespace {

std::string num(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace

std::string to_string(const BimanualSessionSummary& s) {
  std::ostringstream o;
  o << "servo: " << servo::to_string(s.timing) << "\n"
    << "bimanual (SIMULATED, script " << s.script << "): sim_time_s=" << s.sim_time_s
    << " writes=" << s.counters.writes << " nonfinite=" << s.counters.nonfinite_commands
    << " missing_input=" << s.counters.missing_input_commands << " limited=" << s.counters.limited_commands
    << " disabled=" << s.counters.disabled_commands << "\n"
    << "gaps: min_arm_arm_m=" << s.min_arm_arm_m << " min_arm_table_m=" << s.min_arm_table_m
    << " contact_steps arm_arm=" << s.arm_arm_contact_steps << " arm_table=" << s.arm_table_contact_steps << "\n"
    << "arms: right enabled=" << s.enabled[0] << " attached=" << s.attached[0] << ", left enabled=" << s.enabled[1]
    << " attached=" << s.attached[1] << "\n"
    << "log: written=" << s.log_written << " dropped=" << s.log_dropped << "\n";
  return o.str();
}

std::string to_json(const BimanualSessionSummary& s) {
  auto hist = [](const servo::HistogramSummary& h) {
    return "{\"count\": " + std::to_string(h.count) + ", \"median\": " + num(h.median_us) + ", \"p99\": " +
           num(h.p99_us) + ", \"max\": " + num(h.max_us) + ", \"mean\": " + num(h.mean_us) + "}";
  };
  std::ostringstream o;
  o << "{\n  \"timing\": {\"ticks\": " << s.timing.ticks << ", \"misses\": " << s.timing.misses
    << ", \"overruns\": " << s.timing.overruns << ", \"late_wakes\": " << s.timing.late_wakes
    << ", \"skipped_periods\": " << s.timing.skipped_periods << ",\n    \"period_us\": " << hist(s.timing.period)
    << ",\n    \"wake_latency_us\": " << hist(s.timing.wake_latency) << ",\n    \"compute_us\": " << hist(s.timing.compute)
    << "},\n  \"bimanual\": {\"script\": \"" << s.script << "\", \"sim_time_s\": " << num(s.sim_time_s)
    << ", \"writes\": " << s.counters.writes << ", \"nonfinite_commands\": " << s.counters.nonfinite_commands
    << ", \"missing_input_commands\": " << s.counters.missing_input_commands
    << ", \"limited_commands\": " << s.counters.limited_commands
    << ", \"disabled_commands\": " << s.counters.disabled_commands << ",\n    \"min_arm_arm_m\": " << num(s.min_arm_arm_m)
    << ", \"min_arm_table_m\": " << num(s.min_arm_table_m) << ", \"arm_arm_contact_steps\": " << s.arm_arm_contact_steps
    << ", \"arm_table_contact_steps\": " << s.arm_table_contact_steps << ",\n    \"right\": {\"enabled\": "
    << (s.enabled[0] ? "true" : "false") << ", \"attached\": " << (s.attached[0] ? "true" : "false")
    << "}, \"left\": {\"enabled\": " << (s.enabled[1] ? "true" : "false")
    << ", \"attached\": " << (s.attached[1] ? "true" : "false") << "}},\n  \"logs\": {\"servo_written\": "
    << s.log_written << ", \"servo_dropped\": " << s.log_dropped << "}\n}\n";
  return o.str();
}

BimanualSessionSummary run_bimanual_session(const BimanualSessionOptions& o, const std::atomic<bool>* stop,
                                            void (*on_started)(const servo::RealtimeStatus&)) {
  const BimanualHands hands = make_bimanual_hands(o.setup.script, o.setup.sim);
  hb::SimulatedBimanualDevice device(o.setup.sim, hands.hands);
  BimanualTask task(o.setup.env);
  servo::ModelChannel models;  // no model: the environment is the task's
  std::unique_ptr<servo::ServoLogger> log;
  if (!o.log_path.empty()) {
    log = std::make_unique<servo::ServoLogger>(16384, servo::servo_log_header(device.limits().end_effectors),
                                               &servo::format_servo_log_record);
    if (auto e = log->start(o.log_path)) throw std::runtime_error(*e);
  }
  servo::ServoLoop loop(device, task, models, o.servo, log.get());
  const servo::RealtimeStatus rt = loop.start();
  if (on_started) on_started(rt);
  const double duration = o.duration_s > 0.0 ? o.duration_s : hands.duration_s;
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < duration &&
         !(stop && stop->load(std::memory_order_relaxed))) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  loop.stop();
  BimanualSessionSummary s;
  if (log) {
    log->stop();
    s.log_written = log->written();
    s.log_dropped = log->dropped();
  }
  // The servo thread has stopped: the device is ours to read.
  s.timing = loop.summary();
  s.counters = device.counters();
  s.script = o.setup.script;
  s.sim_time_s = device.simulation().time_s();
  s.min_arm_arm_m = device.min_arm_arm_m();
  s.min_arm_table_m = device.min_arm_table_m();
  s.arm_arm_contact_steps = device.simulation().truth().arm_arm_contact_steps;
  s.arm_table_contact_steps = device.simulation().truth().arm_table_contact_steps;
  for (int a = 0; a < hb::kArms; ++a) {
    s.enabled[static_cast<std::size_t>(a)] = device.simulation().enabled(static_cast<hb::ArmSide>(a));
    s.attached[static_cast<std::size_t>(a)] = device.simulation().reading(static_cast<hb::ArmSide>(a)).attached;
  }
  return s;
}

}  // namespace hemm::op
