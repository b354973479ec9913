// The feasibility table of docs/telemanipulation_tasks.md: each task script
// drives the SIMULATED TwoArmRobot directly (no network, the truth judges;
// tests/robot_side/twoarm/task_feasibility_run.h) at 0, 300, 1000 and 3000 ms
// round trip, 5 % loss each way on the delayed links, over seeds. Prints one
// markdown row per run and a summary per (task, rtt); optionally writes the
// rows as CSV and markdown. Simulated time only: the wall time it prints is
// the machine's, not a result. Moved out of the unit tests for CI's budget.
//
//   twoarm_task_table [--seeds N] [--tasks box,peg,bar] [--rtt-ms 0,300,1000,3000]
//                     [--csv FILE] [--markdown FILE]
#include "tests/csv_fields.h"
#include "tests/robot_side/twoarm/task_feasibility_run.h"

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace tf = hemm::test::twoarm_feasibility;
namespace ht = hemm::twoarm;

namespace {

int table_usage(const std::string& why) {
  std::fprintf(stderr, "twoarm_task_table: %s\nusage: twoarm_task_table [--seeds N] [--tasks box,peg,bar] [--rtt-ms 0,300,1000,3000] [--csv FILE] [--markdown FILE]\n",
               why.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  int seeds = 3;
  std::vector<ht::Task> tasks{ht::Task::kBox, ht::Task::kPeg, ht::Task::kBar};
  std::vector<double> rtts_ms{0, 300, 1000, 3000};
  std::string csv_path, md_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return table_usage("'" + a + "' needs a value");
    const std::string v = argv[++i];
    if (a == "--seeds") {
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (end == v.c_str() || *end != '\0' || n < 1 || n > 100) return table_usage("--seeds wants 1-100, got '" + v + "'");
      seeds = static_cast<int>(n);
    } else if (a == "--tasks") {
      tasks.clear();
      for (const std::string& t : hemm::test::csv_fields(v)) {
        if (t == "box") tasks.push_back(ht::Task::kBox);
        else if (t == "peg") tasks.push_back(ht::Task::kPeg);
        else if (t == "bar") tasks.push_back(ht::Task::kBar);
        else return table_usage("unknown task '" + t + "' (box, peg, bar)");
      }
    } else if (a == "--rtt-ms") {
      rtts_ms.clear();
      for (const std::string& t : hemm::test::csv_fields(v)) {
        char* end = nullptr;
        const double r = std::strtod(t.c_str(), &end);
        if (end == t.c_str() || *end != '\0' || !(r >= 0.0 && r <= 10000.0)) return table_usage("--rtt-ms wants 0-10000 ms, got '" + t + "'");
        rtts_ms.push_back(r);
      }
    } else if (a == "--csv") {
      csv_path = v;
    } else if (a == "--markdown") {
      md_path = v;
    } else {
      return table_usage("unknown option '" + a + "'");
    }
  }
  constexpr double kLoss = 0.05;
  std::string md = tf::feasibility_header();
  std::string csv = "task,rtt_ms,seed,success,completion_s,script_done_s,right_wrist_peak_N,right_wrist_rms_N,left_wrist_peak_N,left_wrist_rms_N,"
                    "right_squeeze_peak_N,left_squeeze_peak_N,object_env_peak_N,wall_s\n";
  std::fputs(md.c_str(), stdout);
  for (ht::Task task : tasks) {
    for (double rtt_ms : rtts_ms) {
      // At 0 delay there is no link to lose messages on: one run.
      const int n = rtt_ms > 0.0 ? seeds : 1;
      int ok = 0;
      for (int seed = 1; seed <= n; ++seed) {
        const auto w0 = std::chrono::steady_clock::now();
        const tf::FeasibilityRun r = tf::feasibility_run(task, 1e-3 * rtt_ms, rtt_ms > 0.0 ? kLoss : 0.0, static_cast<uint64_t>(seed), 150.0);
        const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - w0).count();
        const std::string row = tf::feasibility_row(task, 1e-3 * rtt_ms, static_cast<uint64_t>(seed), r);
        std::fputs(row.c_str(), stdout);
        std::fflush(stdout);
        md += row;
        const ht::TaskVerdict& v = r.verdict;
        char line[512];
        std::snprintf(line, sizeof line, "%s,%.0f,%d,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.1f\n", ht::to_string(task), rtt_ms, seed,
                      v.success ? 1 : 0, v.completion_s, r.script_done_s, v.wrist_peak_N[0], v.wrist_rms_N[0], v.wrist_peak_N[1], v.wrist_rms_N[1],
                      v.hand_squeeze_peak_N[0], v.hand_squeeze_peak_N[1], v.object_env_peak_N, wall_s);
        csv += line;
        ok += v.success ? 1 : 0;
        std::fprintf(stderr, "  (%s at %.0f ms seed %d: %.1f s of wall time, beside whatever else runs)\n", ht::to_string(task), rtt_ms, seed, wall_s);
      }
      std::printf("  -> %s at %.0f ms: %d/%d succeeded\n", ht::to_string(task), rtt_ms, ok, n);
    }
  }
  for (const auto& [path, text] : {std::pair{csv_path, csv}, std::pair{md_path, md}}) {
    if (path.empty()) continue;
    std::ofstream f(path);
    f << text;
    if (!f) {
      std::fprintf(stderr, "twoarm_task_table: %s: cannot be written\n", path.c_str());
      return 1;
    }
  }
  return 0;
}
