// One servo tick as the session recorder keeps it (operator/record), for
// any servo task that records (the HEMM station's, telemanipulation's).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "operator/device/haptic_device.h"
#include "operator/servo/spsc_ring.h"

namespace hemm::op {

// What the task read, the snapshot version it rendered with (telemanip:
// the live voxmap's build), the wrench it commanded, the view's key presses
// it took. Fixed size: copied into a preallocated ring on the servo thread.
struct ServoTickRecord {
  std::uint64_t tick = 0;
  device::DeviceSample in;
  std::uint64_t model_version = 0;
  device::DeviceCommand command;
  std::uint32_t view_presses = 0;
  std::uint32_t mode = 0;
  std::uint64_t remote_seq = 0;  // telemanip: the ArmsState's datagram sequence it rendered with
};
// The servo thread's side of the recorder: a full ring drops the record and counts it.
struct ServoTickTap {
  explicit ServoTickTap(std::size_t capacity) : ring(capacity) {}
  void push(const ServoTickRecord& r) noexcept {
    if (!ring.try_push(r)) dropped.fetch_add(1, std::memory_order_relaxed);
  }
  servo::SpscRing<ServoTickRecord> ring;
  std::atomic<std::uint64_t> dropped{0};
};

}  // namespace hemm::op
