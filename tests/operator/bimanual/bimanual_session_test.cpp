// hemm-operator with the SIMULATED bimanual device, through the real binary
// on this machine's clock: the 1 kHz servo loop holds its period (median,
// misses) with two arms' controllers and the MuJoCo plant in every tick; a
// bad device.bimanual block or --hands without the device is a usage error
// (exit 2) with the field named. Its --station-json is proto/report.proto's
// BimanualSession and reads back into it.
#include <gtest/gtest.h>
#include <sched.h>

#include <cmath>
#include <limits>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "operator/bimanual/bimanual_session.h"
#include "report.pb.h"
#include "tests/common/config/report_json.h"
#include "tests/integration/link/child_process.h"

namespace {

using hemm::test::json_number;
using hemm::test::read_file;

const std::string kOperator = std::string(HEMM_BINARY_DIR) + "/bin/hemm-operator";

using RunResult = hemm::test::ProcessResult;

// Runs the binary with the given arguments, stdout/stderr into files in dir.
RunResult run(const std::string& dir, std::vector<std::string> args) {
  args.insert(args.begin(), kOperator);
  return hemm::test::run_to_completion(std::move(args), dir, std::chrono::seconds(40));
}

// A number inside the JSON object that follows "section".
std::optional<double> in_section(const std::string& json, const std::string& section, const std::string& key) {
  const auto at = json.find("\"" + section + "\"");
  if (at == std::string::npos) return std::nullopt;
  return json_number(json.substr(at), key);
}

}  // namespace

TEST(BimanualSession, HoldsOneKilohertzWithTheDeviceInTheLoop) {
  const std::string d = hemm::test::make_temp_dir();
  const RunResult r = run(d, {"--device", "sim-bimanual", "--hands", "features", "--duration", "4", "--station-json",
                        d + "/s.json", "--log", d + "/servo.csv", "--log-level", "warn"});
  ASSERT_EQ(r.rc, 0) << r.err;
  const std::string j = read_file(d + "/s.json");
  const double ticks = json_number(j, "ticks").value_or(0);
  const double misses = json_number(j, "misses").value_or(1e9);
  const double median = in_section(j, "period_us", "median").value_or(0);
  const double p99 = in_section(j, "period_us", "p99").value_or(0);
  const double compute = in_section(j, "compute_us", "median").value_or(1e9);
  std::printf("hemm-operator + sim-bimanual, 4 s: %.0f ticks, period median %.1f us p99 %.1f us, misses %.0f, "
              "compute median %.1f us\n",
              ticks, median, p99, misses, compute);
  EXPECT_GT(ticks, 100);
#ifndef HEMM_SANITIZE
  // Wall clock, uninstrumented builds only (the sanitizers slow MuJoCo and
  // the controllers several-fold).
  EXPECT_GE(ticks, 3600);
  EXPECT_NEAR(median, 1000.0, 20.0);
  EXPECT_LT(misses, 0.05 * ticks);  // a shared, loaded machine: misses happen, few
  EXPECT_LT(compute, 500.0);
#endif
  EXPECT_EQ(json_number(j, "nonfinite_commands").value_or(-1), 0);
  EXPECT_EQ(json_number(j, "arm_arm_contact_steps").value_or(-1), 0);
  // As shipped, the plant and the humans ran on their own thread, reported
  // beside the servo loop with their own histograms.
  const auto rep = hemm::test::read_report_json<hemm::report::BimanualSession>(j);
  ASSERT_TRUE(rep.timing().has_simulated_hardware()) << j.substr(0, 2000);
  EXPECT_EQ(rep.timing().simulated_hardware().mode(), "threaded");
  EXPECT_EQ(rep.timing().simulated_hardware().device(), "simulated-bimanual-lwr");
  EXPECT_GT(rep.timing().simulated_hardware().timing().ticks(), 0.5 * ticks);
  EXPECT_GT(rep.timing().compute_us().bin_count_size(), 0);
  EXPECT_EQ(rep.timing().worst_ticks_size(), 10);
  EXPECT_EQ(rep.timing().period_target_us(), 1000.0);
  // The log has both end-effectors.
  const std::string header = read_file(d + "/servo.csv").substr(0, 4000);
  EXPECT_NE(header.find("ee1_dev_x"), std::string::npos);
}

TEST(BimanualSession, BadConfigsAreUsageErrors) {
  const std::string d = hemm::test::make_temp_dir();
  std::ofstream(d + "/bad.pbtxt") << "device {\n  type: \"sim-bimanual\"\n  bimanual {\n    right { peak_force_n: 900 }\n  }\n}\n";
  RunResult r = run(d, {"--config", d + "/bad.pbtxt", "--duration", "1"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("bad.pbtxt:4:13: device.bimanual.right.peak_force_n: must be in (0, 300] N"), std::string::npos)
      << r.err;
  std::ofstream(d + "/grip.pbtxt") << "device { type: \"sim-bimanual\" bimanual { left { grip_object_at_m: 0.01 } } }\n";
  r = run(d, {"--config", d + "/grip.pbtxt", "--duration", "1"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("device.bimanual.left.grip_object_at_m: the magnetic_clutch handle has no grip"),
            std::string::npos)
      << r.err;
  r = run(d, {"--device", "sim-omni", "--hands", "idle", "--duration", "1"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--hands needs the sim-bimanual device"), std::string::npos) << r.err;
  r = run(d, {"--device", "sim-bimanual", "--hands", "dance"});
  EXPECT_EQ(r.rc, 2);
  r = run(d, {"--device", "sim-bimanual", "--script", "idle", "--duration", "1"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("takes --hands"), std::string::npos) << r.err;
}

// --servo-cpu: a CPU this process may run on pins the servo thread (the
// report says which); any other is a usage error naming the allowed CPUs,
// before anything runs.
TEST(BimanualSession, ServoCpuIsAcceptedOrRefused) {
  const std::string d = hemm::test::make_temp_dir();
  RunResult r = run(d, {"--device", "sim-bimanual", "--hands", "idle", "--duration", "1", "--servo-cpu", "4096"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--servo-cpu 4096: CPU 4096 does not exist"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("this process may run on CPUs"), std::string::npos) << r.err;
  std::ofstream(d + "/bad_cpu.pbtxt") << "servo { cpu: -3 }\n";
  r = run(d, {"--config", d + "/bad_cpu.pbtxt", "--device", "sim-bimanual", "--duration", "1"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("servo.cpu: must be -1 (not pinned) or a CPU number"), std::string::npos) << r.err;
  cpu_set_t set;
  CPU_ZERO(&set);
  ASSERT_EQ(sched_getaffinity(0, sizeof set, &set), 0);
  int cpu = 0;
  while (!CPU_ISSET(cpu, &set)) ++cpu;
  r = run(d, {"--device", "sim-bimanual", "--hands", "idle", "--duration", "1", "--servo-cpu", std::to_string(cpu),
              "--simulated-hardware", "lock-step", "--station-json", d + "/pinned.json", "--log-level", "warn"});
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto rep = hemm::test::read_report_json<hemm::report::BimanualSession>(read_file(d + "/pinned.json"));
  EXPECT_EQ(rep.timing().cpu(), cpu);
  EXPECT_FALSE(rep.timing().has_simulated_hardware());  // lock-step: stepped in the servo tick
  EXPECT_GT(rep.timing().ticks(), 100u);
}

TEST(BimanualSessionJson, ReadsBackIntoTheBimanualSessionReport) {
  hemm::op::BimanualSessionSummary s;
  s.timing.ticks = 4000;
  s.timing.misses = 2;
  s.timing.period.median_us = 1000.25;
  s.timing.compute.p99_us = 1.0 / 3.0;  // the old writer kept 9 digits
  s.counters.writes = 3999;
  s.counters.limited_commands = 17;
  s.sim_time_s = 4.0;
  s.min_arm_arm_m = 0.0425;
  s.min_arm_table_m = std::numeric_limits<double>::infinity();  // never measured
  s.arm_table_contact_steps = 5;
  s.enabled = {true, false};
  s.attached = {false, true};
  s.log_written = 4000;
  s.script = "features";
  const std::string json = hemm::op::to_json(s);
  const auto r = hemm::test::read_report_json<hemm::report::BimanualSession>(json);
  EXPECT_EQ(r.timing().ticks(), 4000u);
  EXPECT_EQ(r.timing().misses(), 2u);
  EXPECT_EQ(r.timing().period_us().median(), 1000.25);
  EXPECT_EQ(r.timing().compute_us().p99(), 1.0 / 3.0);
  EXPECT_EQ(r.bimanual().script(), "features");
  EXPECT_EQ(r.bimanual().writes(), 3999u);
  EXPECT_EQ(r.bimanual().limited_commands(), 17u);
  EXPECT_EQ(r.bimanual().min_arm_arm_m(), 0.0425);
  EXPECT_FALSE(r.bimanual().has_min_arm_table_m());  // left out, not "Infinity"
  EXPECT_EQ(json.find("Infinity"), std::string::npos) << json;
  EXPECT_EQ(r.bimanual().arm_table_contact_steps(), 5u);
  EXPECT_TRUE(r.bimanual().right().enabled());
  EXPECT_FALSE(r.bimanual().left().enabled());
  EXPECT_TRUE(r.bimanual().left().attached());
  EXPECT_EQ(r.logs().servo_written(), 4000u);
}
