// The bimanual paper's peg-in-hole with the device in the loop: hemm-operator
// runs a shipped config on the meshes `hemm-vps scene` writes, checked from
// its 1 kHz log against the scene's geometry: the pins go fully in (plate on
// the block: pins frame 15 mm above the holes frame), the relative motion
// stays on the holes' axis (1 mm play per side), no tunnelling, the
// passivity observer of both arms shows no net generation, and the run ends
// at rest. Two devices play the scene's scripted hands:
//  * deploy/configs/operator_vps_peg.pbtxt: the SIMULATED rigid scripted
//    hands as a two-end-effector device (they do not yield);
//  * deploy/configs/operator_vps_peg_bimanual.pbtxt: the SIMULATED bimanual
//    interface (two 7-DoF arms in MuJoCo) whose SIMULATED humans follow the
//    same paths mapped into the device frame and yield to the rendered wrench.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <utility>

#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"
#include "tests/sanitizer_build.h"

namespace hemm::test {
namespace {

constexpr double mm = 1e-3;
const std::string kBin = std::string(HEMM_BINARY_DIR) + "/bin/";

bool run(const std::vector<std::string>& argv, const std::string& dir, const std::string& name, int timeout_s) {
  ChildProcess p(argv, dir + "/" + name + ".out", dir + "/" + name + ".err");
  const auto rc = p.wait(std::chrono::seconds(timeout_s));
  if (!rc || *rc != 0) {
    ADD_FAILURE() << name << " exit " << (rc ? *rc : -1) << ": " << read_file(dir + "/" + name + ".err");
    return false;
  }
  return true;
}

// One run of a shipped peg-in-hole config, and what its log shows.
struct PegRun {
  CsvColumns c;
  std::string json;
  double max_lateral = 0, max_pen = 0, max_e[2] = {0, 0};
  double drift = 0;  // over the last 200 ticks
  int coarse_at_rest = 0;  // ... those that stopped before the finest level (time-critical budget)
  std::size_t last = 0;
};

// Runs deploy/configs/`config` (its mesh paths pointed at a fresh scene
// directory, no real-time priority on a shared test machine). False (with a
// failure added) if a process failed or the log is short.
// `replace` (if its first is not empty) swaps one piece of the config text.
bool run_peg(const std::string& config, std::size_t min_rows, PegRun* r,
             const std::pair<std::string, std::string>& replace = {}) {
  const std::string dir = make_temp_dir();
  if (!run({kBin + "hemm-vps", "scene", "--name", "peg-in-hole", "--out", dir}, dir, "scene", 60)) return false;
  std::string cfg = read_file(std::string(HEMM_SOURCE_DIR) + "/deploy/configs/" + config);
  if (cfg.empty()) {
    ADD_FAILURE() << "no " << config;
    return false;
  }
  for (std::size_t at; (at = cfg.find("../../out/vps/")) != std::string::npos;) cfg.replace(at, 14, dir + "/");
  if (!replace.first.empty()) {
    const std::size_t at = cfg.find(replace.first);
    if (at == std::string::npos) {
      ADD_FAILURE() << config << " has no '" << replace.first << "'";
      return false;
    }
    cfg.replace(at, replace.first.size(), replace.second);
  }
  cfg += "servo { realtime_priority: false }\n";
  std::ofstream(dir + "/peg.pbtxt") << cfg;
  const std::string log = dir + "/peg.csv";
  if (!run({kBin + "hemm-operator", "--config", dir + "/peg.pbtxt", "--log", log, "--station-json", dir + "/peg.json",
            "--log-level", "warn"},
           dir, "operator", 180))
    return false;
  std::printf("%s", read_file(dir + "/operator.out").c_str());
  r->c = read_csv_columns(log);
  r->json = read_file(dir + "/peg.json");
  const CsvColumns& c = r->c;
  if (!c.ok || c.rows < min_rows) {
    ADD_FAILURE() << config << ": log " << c.error << ", " << c.rows << " rows (want >= " << min_rows << ")";
    return false;
  }
  const auto &rx = c["rel_x"], &ry = c["rel_y"], &rz = c["rel_z"];
  for (std::size_t i = 0; i < c.rows; ++i) {
    if (rz[i] < 40 * mm) r->max_lateral = std::max(r->max_lateral, std::hypot(rx[i], ry[i]));  // pin tips in the holes
    r->max_pen = std::max({r->max_pen, c["pen_rs"][i], c["pen_ls"][i], c["pen_rl"][i]});
    r->max_e[0] = std::max(r->max_e[0], c["energy0"][i]);
    r->max_e[1] = std::max(r->max_e[1], c["energy1"][i]);
  }
  r->last = c.rows - 1;
  const auto& levels = c["levels"];
  const double finest = *std::max_element(levels.begin(), levels.end());
  for (std::size_t i = r->last - 200; i <= r->last; ++i) {
    r->drift = std::max(r->drift, std::abs(rz[i] - rz[r->last]) + std::abs(rx[i] - rx[r->last]) +
                                      std::abs(ry[i] - ry[r->last]));
    if (levels[i] < finest) ++r->coarse_at_rest;
  }
  const std::size_t l = r->last;
  std::printf("%s: pins at %.3f %.3f %.3f mm in the holes frame, lateral <= %.3f mm while inserted, max penetration "
              "%.3f mm, energy to the hands max %.2g / %.2g J, end %.3g / %.3g J, drift over the last 0.2 s %.4f mm "
              "(%d of its ticks stopped before the finest level); right end-effector at z %.3f mm (W); misses %.0f, VPS p99 %.0f us\n",
              config.c_str(), rx[l] / mm, ry[l] / mm, rz[l] / mm, r->max_lateral / mm, r->max_pen / mm, r->max_e[0],
              r->max_e[1], c["energy0"][l], c["energy1"][l], r->drift / mm, r->coarse_at_rest, c["dev0_z"][l] / mm,
              json_number(r->json, "misses").value_or(-1), json_number(r->json, "vps_p99_us").value_or(-1));
  return true;
}

TEST(VpsOperatorLoopback, PegInHoleWithTheDeviceInTheLoopCompletesStably) {
  PegRun r;
  ASSERT_TRUE(run_peg("operator_vps_peg.pbtxt", 2200, &r));  // the path (1.8 s) and half a second of holding
  // Fully in, on the axis.
  EXPECT_NEAR(r.c["rel_z"][r.last], 15 * mm, 0.8 * mm);
  EXPECT_LT(r.max_lateral, 1.0 * mm + r.max_pen + 0.5 * mm);  // play, penetration, the 0.4 degree tilt over the pins
  // No tunnelling.
  EXPECT_LT(r.max_pen, 0.8 * mm);
  // Passivity observer: no net generation on either arm.
  for (int k = 0; k < 2; ++k) EXPECT_LT(r.max_e[k], 1e-3) << k;
  // At rest at the end (stable: no oscillation).
  EXPECT_LT(r.drift, 0.02 * mm);
  EXPECT_EQ(json_number(r.json, "log_dropped").value_or(-1), 0);
}

// The checks both bimanual runs share: completion, no tunnelling, no net
// generation on either arm, rest at the end.
void expect_bimanual_peg_completes(const PegRun& r) {
  EXPECT_NE(r.json.find("simulated-bimanual-lwr"), std::string::npos) << r.json;
  // Fully in: the plate on the block (15 mm), within 0.3 mm (what a 0.1 N
  // disturbance leaves at the relaxed 300 N/m hand), less than the 1 mm play.
  EXPECT_NEAR(r.c["rel_z"][r.last], 15 * mm, 0.3 * mm);
  // On the axis: the play (1 mm per side), the penetration and the 0.4
  // degree tilt over the pins, as with the rigid hands.
  EXPECT_LT(r.max_lateral, 1.0 * mm + r.max_pen + 0.5 * mm);
  // No tunnelling.
  EXPECT_LT(r.max_pen, 0.8 * mm);
  // Passivity observer on both arms: no net generation. One arm may take a
  // little of what the other puts in (the right hand pushes the holes block
  // down in the left one: ~0.3 N over ~0.8 mm, 0.2 mJ); the two together
  // never gain.
  for (int k = 0; k < 2; ++k) EXPECT_LT(r.max_e[k], 1e-3) << k;
  const auto &e0 = r.c["energy0"], &e1 = r.c["energy1"];
  double max_sum = -1.0;
  for (std::size_t i = 0; i < r.c.rows; ++i) max_sum = std::max(max_sum, e0[i] + e1[i]);
  EXPECT_LE(max_sum, 1e-6);
  // At rest at the end (stable: no oscillation).
  EXPECT_LT(r.drift, 0.02 * mm);
  EXPECT_EQ(json_number(r.json, "log_dropped").value_or(-1), 0);
}

// The shipped config: LWR-like actuators (joint friction, ripple, model
// error) and SIMULATED humans that co-contract and add up to 15 N of
// voluntary effort when the motion stalls (human.h). With the relaxed
// spring-only human the pins stop 0.75 mm short and strike a rim (2.2 mm):
// that fails here (README).
TEST(VpsOperatorLoopback, PegInHoleWithTheSimulatedBimanualDeviceInTheLoopCompletesStably) {
  PegRun r;
  // The start held 1 s (kStartHold_s), the path (1.8 s) and 1.5 s of holding.
  ASSERT_TRUE(run_peg("operator_vps_peg_bimanual.pbtxt", 4200, &r));
  expect_bimanual_peg_completes(r);
  // The hands press the plate on: rigid hands end 13 mm apart in z (the
  // pins 2 mm into the block); these are held back by the rendered contact
  // and, with the voluntary effort bounded at 15 N through the 3000 N/m
  // coupling, cannot get closer than 13 - 15/3000 m, nor stay further than
  // the 15 mm of plate on block.
  const double hands_dz = r.c["dev0_z"][r.last] - r.c["dev1_z"][r.last];
  std::printf("right hand %.3f mm above the left at the end (rigid hands: 13)\n", hands_dz / mm);
  EXPECT_GT(hands_dz, 8 * mm);
  EXPECT_LT(hands_dz, 15 * mm);
}

// Ideal actuators, relaxed spring-only humans (the device's own contract):
// the same completion, and the hands yield: rigid hands end 13 mm apart in
// z; these stay about 15 mm apart, their springs carrying the press.
// Release pass only: it runs the code of the shipped bimanual run above with
// other parameters (tests/sanitizer_build.h), and under the sanitizers the
// servo cannot keep its period (a 2-core VM: 37 % of the ticks overran, compute median
// 0.70 ms), so the relaxed hands' insertion is not the device's behaviour
// there (the pins jammed 48 mm off the axis).
TEST(VpsOperatorLoopback, PegInHoleWithTheSimulatedBimanualDeviceIdealActuatorsCompletesStably) {
  if (kSanitizerBuild) GTEST_SKIP() << "release pass only (the shipped bimanual run covers its code here)";
  PegRun r;
  ASSERT_TRUE(run_peg("operator_vps_peg_bimanual.pbtxt", 4200, &r,
                      {"human_voluntary_force_n: 15\n    human_co_contracting: true", "ideal_actuators: true"}));
  expect_bimanual_peg_completes(r);
  const double hands_dz = r.c["dev0_z"][r.last] - r.c["dev1_z"][r.last];
  std::printf("right hand %.3f mm above the left at the end (rigid hands: 13)\n", hands_dz / mm);
  EXPECT_GT(hands_dz, 14 * mm);
}

}  // namespace
}  // namespace hemm::test
