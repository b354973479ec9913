// The one clock of hemm: nanoseconds of the steady clock, the time base of
// every wire time stamp, log and deadline (never the wall clock, which jumps).
// On Linux it is CLOCK_MONOTONIC read through the vDSO (no system call), the
// clock of the servo loop's clock_nanosleep deadlines; safe on the servo thread.
#pragma once

#include <chrono>
#include <cstdint>

namespace hemm {

inline std::int64_t steady_now_ns() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace hemm
