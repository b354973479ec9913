// The bimanual paper's peg-in-hole with the device in the loop: hemm-operator
// runs the shipped config (deploy/configs/operator_vps_peg.pbtxt) on the
// meshes `hemm-vps scene` writes, with the scene's SIMULATED scripted hands
// as a two-end-effector device. Checked from its 1 kHz log against the
// scene's geometry: the pins go fully in (plate on the block: pins frame
// 15 mm above the holes frame), the relative motion stays on the holes' axis
// (1 mm play per side), no tunnelling, the passivity observer of both arms
// shows no net generation, and the run ends at rest.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "tests/integration/latency/csv_columns.h"
#include "tests/integration/link/child_process.h"

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

TEST(VpsOperatorLoopback, PegInHoleWithTheDeviceInTheLoopCompletesStably) {
  const std::string dir = make_temp_dir();
  ASSERT_TRUE(run({kBin + "hemm-vps", "scene", "--name", "peg-in-hole", "--out", dir}, dir, "scene", 60));
  // The shipped config, its mesh paths pointed at this directory.
  std::string cfg = read_file(std::string(HEMM_SOURCE_DIR) + "/deploy/configs/operator_vps_peg.pbtxt");
  ASSERT_FALSE(cfg.empty());
  for (std::size_t at; (at = cfg.find("../../out/vps/")) != std::string::npos;) cfg.replace(at, 14, dir + "/");
  // No real-time priority on a shared test machine.
  cfg += "servo { realtime_priority: false }\n";
  std::ofstream(dir + "/peg.pbtxt") << cfg;
  const std::string log = dir + "/peg.csv";
  ASSERT_TRUE(run({kBin + "hemm-operator", "--config", dir + "/peg.pbtxt", "--log", log, "--station-json",
                   dir + "/peg.json", "--log-level", "warn"},
                  dir, "operator", 180));
  std::printf("%s", read_file(dir + "/operator.out").c_str());
  const CsvColumns c = read_csv_columns(log);
  ASSERT_TRUE(c.ok) << c.error;
  ASSERT_GE(c.rows, 2200u);  // the path (1.8 s) and half a second of holding
  const auto &rx = c["rel_x"], &ry = c["rel_y"], &rz = c["rel_z"];
  double max_lateral = 0, max_pen = 0, max_e[2] = {0, 0};
  for (std::size_t i = 0; i < c.rows; ++i) {
    if (rz[i] < 40 * mm) max_lateral = std::max(max_lateral, std::hypot(rx[i], ry[i]));  // pin tips in the holes
    max_pen = std::max({max_pen, c["pen_rs"][i], c["pen_ls"][i], c["pen_rl"][i]});
    max_e[0] = std::max(max_e[0], c["energy0"][i]);
    max_e[1] = std::max(max_e[1], c["energy1"][i]);
  }
  const std::size_t last = c.rows - 1;
  double drift = 0;  // over the last 200 ticks
  for (std::size_t i = last - 200; i <= last; ++i)
    drift = std::max(drift, std::abs(rz[i] - rz[last]) + std::abs(rx[i] - rx[last]) + std::abs(ry[i] - ry[last]));
  const std::string json = read_file(dir + "/peg.json");
  std::printf("peg-in-hole in hemm-operator: pins at %.3f %.3f %.3f mm in the holes frame, lateral <= %.3f mm while "
              "inserted, max penetration %.3f mm, energy to the hands max %.2g / %.2g J, end %.3g / %.3g J, drift "
              "over the last 0.2 s %.4f mm; misses %.0f, VPS p99 %.0f us\n",
              rx[last] / mm, ry[last] / mm, rz[last] / mm, max_lateral / mm, max_pen / mm, max_e[0], max_e[1],
              c["energy0"][last], c["energy1"][last], drift / mm, json_number(json, "misses").value_or(-1),
              json_number(json, "vps_p99_us").value_or(-1));
  // Fully in, on the axis.
  EXPECT_NEAR(rz[last], 15 * mm, 0.8 * mm);
  EXPECT_LT(max_lateral, 1.0 * mm + max_pen + 0.5 * mm);  // play, penetration, the 0.4 degree tilt over the pins
  // No tunnelling.
  EXPECT_LT(max_pen, 0.8 * mm);
  // Passivity observer: no net generation on either arm.
  for (int k = 0; k < 2; ++k) EXPECT_LT(max_e[k], 1e-3) << k;
  // At rest at the end (stable: no oscillation).
  EXPECT_LT(drift, 0.02 * mm);
  EXPECT_EQ(json_number(json, "log_dropped").value_or(-1), 0);
}

}  // namespace
}  // namespace hemm::test
