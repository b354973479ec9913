// The real-time set-up's checks: the kernel's cpu-list format, which CPUs a
// thread may be pinned to (a bad one is an error naming the allowed ones,
// found before anything changes), pinning a thread, and the machine checks
// read from copies of /proc and /sys files (RT throttling, isolated CPUs, the
// frequency governor).
#include "common/realtime/realtime_setup.h"

#include <gtest/gtest.h>
#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

namespace hemm::rt {
namespace {

TEST(ParseCpuList, ReadsTheKernelsFormat) {
  EXPECT_EQ(parse_cpu_list("0-2,5,7-8\n"), (std::vector<int>{0, 1, 2, 5, 7, 8}));
  EXPECT_EQ(parse_cpu_list("3"), (std::vector<int>{3}));
  EXPECT_EQ(parse_cpu_list(""), std::vector<int>{});
  EXPECT_EQ(parse_cpu_list("\n"), std::vector<int>{});
  EXPECT_FALSE(parse_cpu_list("3-1"));
  EXPECT_FALSE(parse_cpu_list("a"));
  EXPECT_FALSE(parse_cpu_list("1,,2"));
  EXPECT_FALSE(parse_cpu_list("-1"));
}

int first_allowed_cpu() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return -1;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (CPU_ISSET(c, &set)) return c;
  return -1;
}

int first_forbidden_cpu() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return -1;
  for (int c = 0; c < CPU_SETSIZE; ++c)
    if (!CPU_ISSET(c, &set)) return c;
  return -1;
}

TEST(CheckCpu, AcceptsNoneOrAnAllowedCpuAndNamesTheAllowedOnesOtherwise) {
  EXPECT_FALSE(check_cpu(-1));
  const int ok = first_allowed_cpu();
  ASSERT_GE(ok, 0);
  EXPECT_FALSE(check_cpu(ok));
  const auto neg = check_cpu(-2);
  ASSERT_TRUE(neg);
  EXPECT_NE(neg->find("does not exist"), std::string::npos) << *neg;
  EXPECT_NE(neg->find("this process may run on CPUs"), std::string::npos) << *neg;
  const auto big = check_cpu(CPU_SETSIZE);
  ASSERT_TRUE(big);
  EXPECT_NE(big->find("does not exist"), std::string::npos) << *big;
  const int bad = first_forbidden_cpu();
  ASSERT_GE(bad, 0);
  const auto off = check_cpu(bad);
  ASSERT_TRUE(off);
  EXPECT_NE(off->find("is not one this process may run on"), std::string::npos) << *off;
}

TEST(ApplyThreadRealtime, PinsAThreadToAnAllowedCpuAndWarnsOnABadOne) {
  const int cpu = first_allowed_cpu();
  ASSERT_GE(cpu, 0);
  std::atomic<bool> go{false};
  std::atomic<int> ran_on{-1};
  std::thread t([&] {
    while (!go.load()) std::this_thread::yield();
    ran_on.store(sched_getcpu());
  });
  RealtimeStatus st;
  apply_thread_realtime(t, RealtimeRequest{false, 80, cpu}, &st);
  go.store(true);
  t.join();
  EXPECT_TRUE(st.pinned);
  EXPECT_EQ(st.cpu, cpu);
  EXPECT_FALSE(st.fifo);
  EXPECT_TRUE(st.warnings.empty());
  EXPECT_EQ(ran_on.load(), cpu);

  std::thread u([] {});
  RealtimeStatus bad;
  apply_thread_realtime(u, RealtimeRequest{false, 80, CPU_SETSIZE + 3}, &bad);
  u.join();
  EXPECT_FALSE(bad.pinned);
  EXPECT_EQ(bad.cpu, -1);
  ASSERT_EQ(bad.warnings.size(), 1u);
  EXPECT_NE(bad.warnings[0].find("pinning to CPU"), std::string::npos);
}

struct FakeSystem {
  FakeSystem() {
    dir = std::filesystem::path(testing::TempDir()) /
          ("realtime_setup_test_" + std::to_string(::getpid()) + "_" +
           testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir / "cpu" / "cpu1" / "cpufreq");
    std::filesystem::create_directories(dir / "cpu" / "cpu0" / "cpufreq");
    files.rt_runtime_us = (dir / "sched_rt_runtime_us").string();
    files.rt_period_us = (dir / "sched_rt_period_us").string();
    files.isolated_cpus = (dir / "isolated").string();
    files.cpu_dir = (dir / "cpu").string();
  }
  ~FakeSystem() { std::filesystem::remove_all(dir); }
  void write(const std::string& path, const std::string& text) const { std::ofstream(path) << text; }
  std::filesystem::path dir;
  SystemFiles files;
};

bool any_contains(const std::vector<std::string>& w, const std::string& what) {
  for (const std::string& s : w)
    if (s.find(what) != std::string::npos) return true;
  return false;
}

TEST(SystemChecks, WarnAboutThrottlingAnUnisolatedCpuAndASlowGovernor) {
  FakeSystem f;
  f.write(f.files.rt_runtime_us, "950000\n");
  f.write(f.files.rt_period_us, "1000000\n");
  f.write(f.files.isolated_cpus, "\n");
  f.write(f.files.cpu_dir + "/cpu1/cpufreq/scaling_governor", "powersave\n");
  const std::vector<std::string> w = system_checks(true, 1, f.files);
  EXPECT_EQ(w.size(), 3u);
  EXPECT_TRUE(any_contains(w, "sched_rt_runtime_us=950000 of sched_rt_period_us=1000000"));
  EXPECT_TRUE(any_contains(w, "CPU 1 is not isolated"));
  EXPECT_TRUE(any_contains(w, "'powersave', not 'performance'"));
  // Without SCHED_FIFO, throttling does not matter; unpinned: no isolation check, CPU 0's governor.
  const std::vector<std::string> n = system_checks(false, -1, f.files);
  EXPECT_TRUE(n.empty()) << n.front();
}

TEST(SystemChecks, ARealTimeReadyMachineGivesNoWarnings) {
  FakeSystem f;
  f.write(f.files.rt_runtime_us, "-1\n");
  f.write(f.files.rt_period_us, "1000000\n");
  f.write(f.files.isolated_cpus, "1-3\n");
  f.write(f.files.cpu_dir + "/cpu1/cpufreq/scaling_governor", "performance\n");
  EXPECT_TRUE(system_checks(true, 1, f.files).empty());
  // Unreadable governor (a VM): nothing said about it; an unreadable isolated list: said.
  std::filesystem::remove(f.files.cpu_dir + "/cpu1/cpufreq/scaling_governor");
  std::filesystem::remove(f.files.isolated_cpus);
  const std::vector<std::string> w = system_checks(true, 1, f.files);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("unreadable"), std::string::npos) << w[0];
}

// The wake-latency hold writes the kernel's binary s32 of 0 us and keeps
// the file open; a file it cannot open is a warning naming it, nothing held.
TEST(HoldCpuWakeLatency, WritesZeroMicrosecondsAndKeepsTheFileOpenOrWarns) {
  FakeSystem f;
  const std::string path = (f.dir / "cpu_dma_latency").string();
  f.write(path, "");
  RealtimeStatus st;
  const int fd = hold_cpu_wake_latency(&st, path);
  ASSERT_GE(fd, 0);
  EXPECT_TRUE(st.wake_latency_held);
  EXPECT_TRUE(st.warnings.empty());
  EXPECT_EQ(::fcntl(fd, F_GETFD), FD_CLOEXEC);  // open until released, not inherited
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes, std::string(4, '\0'));
  release_cpu_wake_latency(fd);
  EXPECT_EQ(::fcntl(fd, F_GETFD), -1);  // closed
  release_cpu_wake_latency(-1);         // nothing to release: no effect

  RealtimeStatus no;
  EXPECT_EQ(hold_cpu_wake_latency(&no, (f.dir / "absent" / "cpu_dma_latency").string()), -1);
  EXPECT_FALSE(no.wake_latency_held);
  ASSERT_EQ(no.warnings.size(), 1u);
  EXPECT_NE(no.warnings[0].find("absent/cpu_dma_latency"), std::string::npos) << no.warnings[0];
}

}  // namespace
}  // namespace hemm::rt
