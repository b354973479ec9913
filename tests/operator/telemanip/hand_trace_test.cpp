// The hand trace's CSV (operator/telemanip/hand_trace.h): a header naming
// every column, one line per sample with the values as given, the clocks to
// the microsecond whatever the uptime, t_s from the first sample.
#include "operator/telemanip/hand_trace.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "tests/csv_fields.h"

namespace tele = hemm::op::telemanip;

TEST(HandTrace, CsvHasAHeaderAndOneLinePerSample) {
  std::vector<tele::HandTraceSample> rows(2);
  rows[0].t_ns = 86'400'000'000'000;  // a day of uptime
  rows[1].t_ns = rows[0].t_ns + 10'000'000;
  rows[1].remote_ns = rows[1].t_ns - 1'500'000'250;
  rows[1].direct = true;
  rows[1].squeeze_n = -2.5;
  rows[1].arm[1].pressed = true;
  rows[1].arm[1].holding = true;
  rows[1].arm[1].felt_A = {0.5, -1.25, 9.81};
  rows[1].arm[1].held_A.z() = -19.62;
  rows[1].arm[0].remote_force_A.x() = 3.0;
  rows[1].arm[0].commanded_opening_m = 0.218;
  const std::string csv = tele::hand_trace_csv(rows);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);
  std::istringstream in(csv);
  std::string header, r0, r1;
  ASSERT_TRUE(std::getline(in, header) && std::getline(in, r0) && std::getline(in, r1));
  const std::vector<std::string> h = hemm::test::csv_fields(header), v0 = hemm::test::csv_fields(r0), v = hemm::test::csv_fields(r1);
  ASSERT_EQ(h.size(), 5u + 2u * 20u);  // per arm: 3 flags, 5 vectors, 2 openings
  ASSERT_EQ(v0.size(), h.size());
  ASSERT_EQ(v.size(), h.size());
  const auto col = [&](const std::vector<std::string>& row, const std::string& name) {
    const auto it = std::find(h.begin(), h.end(), name);
    EXPECT_NE(it, h.end()) << name;
    return it == h.end() ? std::string() : row.at(static_cast<std::size_t>(it - h.begin()));
  };
  EXPECT_EQ(col(v0, "t_s"), "0.000000");
  EXPECT_EQ(col(v0, "mode"), "model");
  EXPECT_EQ(col(v0, "remote_clock_s"), "0.000000");  // no state yet
  EXPECT_EQ(col(v, "t_s"), "0.010000");
  EXPECT_EQ(col(v, "clock_s"), "86400.010000");
  EXPECT_EQ(col(v, "remote_clock_s"), "86398.510000");
  EXPECT_EQ(col(v, "mode"), "direct");
  EXPECT_EQ(col(v, "squeeze_N"), "-2.5");
  EXPECT_EQ(col(v, "left_pressed"), "1");
  EXPECT_EQ(col(v, "left_holding"), "1");
  EXPECT_EQ(col(v, "right_pressed"), "0");
  EXPECT_EQ(col(v, "left_felt_x"), "0.5");
  EXPECT_EQ(col(v, "left_felt_y"), "-1.25");
  EXPECT_EQ(col(v, "left_felt_z"), "9.81");
  EXPECT_EQ(col(v, "left_held_z"), "-19.62");
  EXPECT_EQ(col(v, "right_remote_force_x"), "3");
  EXPECT_EQ(col(v, "right_cmd_opening_m"), "0.218");
  // No samples: the header alone (what --hand-trace writes first, to try the path).
  const std::string empty = tele::hand_trace_csv({});
  EXPECT_EQ(empty, header + "\n");
}
