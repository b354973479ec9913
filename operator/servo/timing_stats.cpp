#include "operator/servo/timing_stats.h"

#include <cstdio>

#include "report.pb.h"

namespace hemm::servo {

std::string to_string(const TimingSummary& s) {
  std::string out = rt::to_string(s);
  if (s.hardware) {
    const SimulatedHardwareSummary& h = *s.hardware;
    char buf[384];
    std::snprintf(buf, sizeof buf,
                  " | simulated hardware (%s, %s): steps=%llu misses=%llu compute median/p99=%.1f/%.1f us "
                  "period p99=%.1f us sample age median/p99=%.1f/%.1f us commands held=%llu",
                  h.device.c_str(), h.mode.c_str(), static_cast<unsigned long long>(h.timing.ticks),
                  static_cast<unsigned long long>(h.timing.misses), h.timing.compute.median_us,
                  h.timing.compute.p99_us, h.timing.period.p99_us, h.sample_age.median_us, h.sample_age.p99_us,
                  static_cast<unsigned long long>(h.commands_held));
    out += buf;
  }
  return out;
}

void fill(report::ServoTiming* t, const TimingSummary& s) {
  rt::fill(t, static_cast<const rt::TimingSummary&>(s));
  if (s.hardware) {
    const SimulatedHardwareSummary& h = *s.hardware;
    report::SimulatedHardware* r = t->mutable_simulated_hardware();
    r->set_device(h.device);
    r->set_mode(h.mode);
    rt::fill(r->mutable_timing(), h.timing);
    rt::fill(r->mutable_sample_age_us(), h.sample_age);
    r->set_commands_new(h.commands_new);
    r->set_commands_held(h.commands_held);
  }
}

}  // namespace hemm::servo
