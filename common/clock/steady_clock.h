// The one clock of hemm: nanoseconds of the steady clock, the time base of
// every wire time stamp, log and deadline (never the wall clock, which jumps).
#pragma once

#include <chrono>
#include <cstdint>

namespace hemm {

inline std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace hemm
