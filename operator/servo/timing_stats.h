// The servo loop's timing statistics: the deadline statistics every real-time
// loop of hemm keeps (common/realtime/timing_stats.h: log-spaced histograms
// of wake lateness, compute and period, the miss counters, the ten worst
// ticks with what ran in them) and, beside them in the summary, the timing of
// a SIMULATED device's hardware thread (operator/device/simulated_hardware.h)
// when the device runs one.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/realtime/timing_stats.h"

namespace hemm::servo {

using LatencyHistogram = rt::LogHistogram;
using rt::HistogramSummary;
using rt::summarize;
using rt::TimingStats;
using rt::WorstTick;

// The simulated hardware's own loop, beside the servo's.
struct SimulatedHardwareSummary {
  std::string device;
  std::string mode;  // "threaded" or "lock-step"
  rt::TimingSummary timing;
  rt::HistogramSummary sample_age;  // servo wake - the newest sample's measurement time
  std::uint64_t commands_new = 0, commands_held = 0;
};

struct TimingSummary : rt::TimingSummary {
  TimingSummary() = default;
  TimingSummary(rt::TimingSummary s) : rt::TimingSummary(std::move(s)) {}  // NOLINT: implicit on purpose
  std::optional<SimulatedHardwareSummary> hardware;  // none: the device runs no hardware thread
};

// One line for logs: the loop's figures and, if any, the simulated hardware's.
std::string to_string(const TimingSummary& s);
// The summary as the "timing" object of the operator's run reports
// (proto/report.proto's ServoTiming, with its simulated_hardware).
void fill(report::ServoTiming* out, const TimingSummary& s);

}  // namespace hemm::servo
