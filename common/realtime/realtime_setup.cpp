#include "common/realtime/realtime_setup.h"

#include <linux/capability.h>
#include <pthread.h>
#include <sched.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

namespace hemm::rt {
namespace {

std::string errno_text(int e) { return std::strerror(e); }

std::optional<std::string> read_first_line(const std::string& path) {
  std::ifstream f(path);
  if (!f) return std::nullopt;
  std::string line;
  std::getline(f, line);
  if (f.bad()) return std::nullopt;
  return line;
}

std::string cpu_list_text(const cpu_set_t& set) {
  std::string out;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (!CPU_ISSET(c, &set)) continue;
    int e = c;
    while (e + 1 < CPU_SETSIZE && CPU_ISSET(e + 1, &set)) ++e;
    if (!out.empty()) out += ',';
    out += std::to_string(c);
    if (e > c) out += "-" + std::to_string(e);
    c = e;
  }
  return out.empty() ? "none" : out;
}

#ifndef HEMM_SANITIZE
bool memory_lock_unlimited(std::string* why) {
  __user_cap_header_struct hdr{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct caps[2]{};
  if (syscall(SYS_capget, &hdr, caps) == 0 &&
      (caps[CAP_TO_INDEX(CAP_IPC_LOCK)].effective & CAP_TO_MASK(CAP_IPC_LOCK)) != 0)
    return true;
  rlimit lim{};
  if (getrlimit(RLIMIT_MEMLOCK, &lim) == 0 && lim.rlim_cur == RLIM_INFINITY) return true;
  *why = "mlockall skipped: no CAP_IPC_LOCK and RLIMIT_MEMLOCK is " +
         std::to_string(static_cast<unsigned long long>(lim.rlim_cur)) +
         " bytes (locking future memory would make later allocations fail)";
  return false;
}
#endif

}  // namespace

std::optional<std::vector<int>> parse_cpu_list(const std::string& text) {
  std::vector<int> out;
  std::string s = text;
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  if (s.empty()) return out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) {
    auto num = [](const std::string& t, int* v) {
      if (t.empty() || t.size() > 6) return false;
      for (char c : t)
        if (c < '0' || c > '9') return false;
      *v = std::atoi(t.c_str());
      return true;
    };
    const auto dash = item.find('-');
    int a = 0, b = 0;
    if (dash == std::string::npos) {
      if (!num(item, &a)) return std::nullopt;
      b = a;
    } else if (!num(item.substr(0, dash), &a) || !num(item.substr(dash + 1), &b) || b < a) {
      return std::nullopt;
    }
    for (int c = a; c <= b; ++c) out.push_back(c);
  }
  return out;
}

std::optional<std::string> check_cpu(int cpu) {
  if (cpu == -1) return std::nullopt;
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  const bool have_mask = sched_getaffinity(0, sizeof allowed, &allowed) == 0;
  const std::string which = have_mask ? " (this process may run on CPUs " + cpu_list_text(allowed) + ")" : "";
  if (cpu < 0 || cpu >= CPU_SETSIZE)
    return "CPU " + std::to_string(cpu) + " does not exist: a CPU number is -1 (none) or 0.." +
           std::to_string(CPU_SETSIZE - 1) + which;
  if (have_mask && !CPU_ISSET(cpu, &allowed))
    return "CPU " + std::to_string(cpu) + " is not one this process may run on (offline, absent, or taken away by "
           "taskset / a cgroup)" + which;
  return std::nullopt;
}

void apply_thread_realtime(std::thread& thread, const RealtimeRequest& r, RealtimeStatus* status) {
  if (r.fifo) {
    sched_param sp{};
    const int lo = sched_get_priority_min(SCHED_FIFO), hi = sched_get_priority_max(SCHED_FIFO);
    sp.sched_priority = r.fifo_priority < lo ? lo : (r.fifo_priority > hi ? hi : r.fifo_priority);
    const int rc = pthread_setschedparam(thread.native_handle(), SCHED_FIFO, &sp);
    if (rc == 0) {
      status->fifo = true;
    } else {
      status->warnings.push_back("SCHED_FIFO refused (" + errno_text(rc) +
                                 "): the thread runs as a normal one (needs CAP_SYS_NICE or an RLIMIT_RTPRIO of " +
                                 std::to_string(sp.sched_priority) + ")");
    }
  }
  if (r.cpu >= 0) {
    int rc = EINVAL;
    if (r.cpu < CPU_SETSIZE) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(r.cpu, &set);
      rc = pthread_setaffinity_np(thread.native_handle(), sizeof set, &set);
    }
    if (rc == 0) {
      status->pinned = true;
      status->cpu = r.cpu;
    } else {
      status->warnings.push_back("pinning to CPU " + std::to_string(r.cpu) + " failed (" + errno_text(rc) + ")");
    }
  }
}

bool lock_memory(RealtimeStatus* status) {
#ifdef HEMM_SANITIZE
  // The sanitizers reserve terabytes of shadow memory: locking it all fails
  // or takes the machine down.
  status->warnings.push_back("mlockall skipped: sanitizer build");
  return false;
#else
  std::string why;
  if (!memory_lock_unlimited(&why)) {
    status->warnings.push_back(why);
    return false;
  }
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    status->warnings.push_back("mlockall failed (" + errno_text(errno) + "): memory may page out");
    return false;
  }
  status->memory_locked = true;
  return true;
#endif
}

void unlock_memory() noexcept { munlockall(); }

int hold_cpu_wake_latency(RealtimeStatus* status, const std::string& path) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0) {
    status->warnings.push_back("CPU wake latency not held (" + path + ": " + errno_text(errno) +
                               "): idle CPUs may sleep deeply and wake the thread late");
    return -1;
  }
  const std::int32_t zero_us = 0;  // the kernel reads a binary s32 of microseconds
  if (::write(fd, &zero_us, sizeof zero_us) != static_cast<ssize_t>(sizeof zero_us)) {
    status->warnings.push_back("CPU wake latency not held (writing " + path + ": " + errno_text(errno) + ")");
    ::close(fd);
    return -1;
  }
  status->wake_latency_held = true;
  return fd;
}

void release_cpu_wake_latency(int fd) noexcept {
  if (fd >= 0) ::close(fd);  // closing the file ends the request
}

std::vector<std::string> system_checks(bool fifo, int cpu, const SystemFiles& files) {
  std::vector<std::string> w;
  if (fifo) {
    const auto runtime = read_first_line(files.rt_runtime_us);
    const auto period = read_first_line(files.rt_period_us);
    if (runtime && *runtime != "-1") {
      w.push_back("RT throttling is on: sched_rt_runtime_us=" + *runtime + " of sched_rt_period_us=" +
                  (period ? *period : std::string("?")) +
                  ": the kernel stops every SCHED_FIFO thread for the rest of each period once they used that much "
                  "(sysctl kernel.sched_rt_runtime_us=-1 turns it off; docs/realtime.md)");
    }
  }
  if (cpu >= 0) {
    const auto iso = read_first_line(files.isolated_cpus);
    const auto list = iso ? parse_cpu_list(*iso) : std::nullopt;
    bool isolated = false;
    if (list)
      for (int c : *list) isolated = isolated || c == cpu;
    if (!isolated)
      w.push_back("CPU " + std::to_string(cpu) + " is not isolated (" + files.isolated_cpus + ": " +
                  (iso ? (iso->empty() ? std::string("none") : *iso) : std::string("unreadable")) +
                  "): other tasks and interrupts share it (isolcpus=, irqaffinity=; docs/realtime.md)");
  }
  const std::string gov_path =
      files.cpu_dir + "/cpu" + std::to_string(cpu >= 0 ? cpu : 0) + "/cpufreq/scaling_governor";
  if (const auto gov = read_first_line(gov_path); gov && *gov != "performance")
    w.push_back("CPU frequency governor of CPU " + std::to_string(cpu >= 0 ? cpu : 0) + " is '" + *gov +
                "', not 'performance': waking from a low clock adds latency (cpupower frequency-set -g performance)");
  return w;
}

}  // namespace hemm::rt
