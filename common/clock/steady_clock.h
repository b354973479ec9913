// The one clock of hemm: nanoseconds of the steady clock, the time base of
// every wire time stamp, log and deadline (never the wall clock, which jumps).
// On Linux it is CLOCK_MONOTONIC read through the vDSO (no system call), the
// clock of the servo loop's clock_nanosleep deadlines; safe on the servo thread.
#pragma once

#include <time.h>

#include <chrono>
#include <cstdint>

namespace hemm {

inline std::int64_t steady_now_ns() noexcept {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Seconds of CPU time the calling thread has used (benchmarks and reports:
// a thread's own cost stays meaningful on a loaded machine, where wall time
// includes the wait for a core). Not a time base.
inline double thread_cpu_s() noexcept {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

}  // namespace hemm
