#include "operator/bimanual/bimanual_session.h"

#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>

#include "common/config/config.h"
#include "operator/bimanual/bimanual_scripts.h"
#include "operator/bimanual/bimanual_task.h"
#include "report.pb.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

std::string to_string(const BimanualSessionSummary& s) {
  std::ostringstream o;
  o << "servo: " << servo::to_string(s.timing) << "\n"
    << "servo worst ticks: " << rt::worst_ticks_text(s.timing.worst) << "\n"
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

report::BimanualSession to_report(const BimanualSessionSummary& s) {
  report::BimanualSession r;
  servo::fill(r.mutable_timing(), s.timing);
  report::Bimanual& b = *r.mutable_bimanual();
  b.set_script(s.script);
  b.set_sim_time_s(s.sim_time_s);
  b.set_writes(s.counters.writes);
  b.set_nonfinite_commands(s.counters.nonfinite_commands);
  b.set_missing_input_commands(s.counters.missing_input_commands);
  b.set_limited_commands(s.counters.limited_commands);
  b.set_disabled_commands(s.counters.disabled_commands);
  // Infinite until the first step measured them: left out, not "Infinity".
  if (std::isfinite(s.min_arm_arm_m)) b.set_min_arm_arm_m(s.min_arm_arm_m);
  if (std::isfinite(s.min_arm_table_m)) b.set_min_arm_table_m(s.min_arm_table_m);
  b.set_arm_arm_contact_steps(s.arm_arm_contact_steps);
  b.set_arm_table_contact_steps(s.arm_table_contact_steps);
  b.mutable_right()->set_enabled(s.enabled[0]);
  b.mutable_right()->set_attached(s.attached[0]);
  b.mutable_left()->set_enabled(s.enabled[1]);
  b.mutable_left()->set_attached(s.attached[1]);
  r.mutable_logs()->set_servo_written(s.log_written);
  r.mutable_logs()->set_servo_dropped(s.log_dropped);
  return r;
}

std::string to_json(const BimanualSessionSummary& s) { return config::to_json(to_report(s)); }

BimanualSessionSummary run_bimanual_session(const BimanualSessionOptions& o, const std::atomic<bool>* stop,
                                            void (*on_started)(const servo::RealtimeStatus&)) {
  const BimanualHands hands = make_bimanual_hands(o.setup.script, o.setup.sim);
  hb::SimulatedBimanualDevice device(o.setup.sim, hands.hands);
  BimanualTask task(o.setup.env);
  if (o.view.ticks != nullptr) task.set_view(o.view.ticks, &device);
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
  if (o.view.started) o.view.started(loop.stats());
  const double duration = o.duration_s > 0.0 ? o.duration_s : hands.duration_s;
  const auto t0 = std::chrono::steady_clock::now();
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < duration &&
         !(stop && stop->load(std::memory_order_relaxed))) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  loop.stop();
  if (o.view.stopped) o.view.stopped();
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
