// The real-time set-up of a periodic thread (the operator's servo loop, a
// SIMULATED device's hardware thread, the robot station's control loop):
// SCHED_FIFO, pinning to one CPU, mlockall, and the checks at start that say
// what on this machine may still make the thread late (docs/realtime.md).
// Everything refused is a warning, never an error: the thread then runs as
// a normal one, and the warnings say why. Only a CPU that cannot exist or is
// not ours is an error (check_cpu), found before anything is changed.
#pragma once

#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace hemm::rt {

struct RealtimeRequest {
  bool fifo = false;        // try SCHED_FIFO
  int fifo_priority = 80;   // clamped to the policy's range
  int cpu = -1;             // pin to this CPU if >= 0
};

struct RealtimeStatus {
  bool fifo = false;
  bool memory_locked = false;
  bool wake_latency_held = false;     // hold_cpu_wake_latency succeeded
  bool pinned = false;
  int cpu = -1;                       // the CPU pinned to, -1: none
  std::vector<std::string> warnings;  // one line each, for the caller to log
};

// Empty if `cpu` is -1 (no pinning) or a CPU this process may run on (in
// [0, CPU_SETSIZE) and in its affinity mask: online, and not taken away by a
// cgroup or taskset); else the error, naming the CPUs that are allowed.
std::optional<std::string> check_cpu(int cpu);

// Sets SCHED_FIFO and the CPU of a started thread as asked; what is refused
// goes into status->warnings. Call from another thread before releasing the
// thread into its loop.
void apply_thread_realtime(std::thread& thread, const RealtimeRequest& r, RealtimeStatus* status);

// mlockall(MCL_CURRENT | MCL_FUTURE), only with CAP_IPC_LOCK or an unlimited
// RLIMIT_MEMLOCK (under a finite limit later allocations anywhere in the
// process would fail); skipped under sanitizers. True if locked (undo with
// unlock_memory); a warning otherwise.
bool lock_memory(RealtimeStatus* status);
void unlock_memory() noexcept;

// Asks the kernel (PM QoS, /dev/cpu_dma_latency) to keep every CPU out of
// idle states slower than 0 us to leave, for as long as the returned
// descriptor stays open: a periodic thread then wakes without a deep idle
// state's exit latency (here, idle on the 2-core VM: the servo's wake p99
// 130 -> 33 us). Costs power on an idle machine. Returns -1 with a warning
// if refused (the file needs root or its group).
int hold_cpu_wake_latency(RealtimeStatus* status, const std::string& path = "/dev/cpu_dma_latency");
void release_cpu_wake_latency(int fd) noexcept;  // -1: nothing

// Where the checks read the kernel's settings: the real /proc and /sys, or a
// copy of those files under a test directory.
struct SystemFiles {
  std::string rt_runtime_us = "/proc/sys/kernel/sched_rt_runtime_us";
  std::string rt_period_us = "/proc/sys/kernel/sched_rt_period_us";
  std::string isolated_cpus = "/sys/devices/system/cpu/isolated";
  std::string cpu_dir = "/sys/devices/system/cpu";  // cpuN/cpufreq/scaling_governor below it
};

// What on this machine may still make a real-time thread late, as warnings:
//  - RT throttling: sched_rt_runtime_us other than -1 lets the kernel stop
//    every SCHED_FIFO thread for the rest of each sched_rt_period_us once
//    they used that much of it (a 50 ms stall at the defaults);
//  - a pinned CPU not in the isolated set (isolcpus): other tasks and
//    interrupts share it;
//  - the CPU's frequency governor, if readable, other than "performance"
//    (waking from a low clock adds tens of microseconds);
//  - (not checked here: refused SCHED_FIFO / mlockall / the wake-latency
//    hold, which the set-up itself reports).
// `fifo`: whether SCHED_FIFO is in use (throttling only matters then);
// `cpu`: the pinned CPU or -1 (then the governor of CPU 0 is read).
std::vector<std::string> system_checks(bool fifo, int cpu, const SystemFiles& files = {});

// "0-2,5,7-8" (the kernel's cpu list format) -> {0,1,2,5,7,8}; nullopt on
// a malformed list; "" or "\n" -> {}.
std::optional<std::vector<int>> parse_cpu_list(const std::string& text);

}  // namespace hemm::rt
