// The link statistics' JSON (--stats-json of both stations) is proto/report.proto's
// Link printed by config::to_json: it must read back, strictly (no unknown
// keys), into that message with every value as it was, and the event=stats
// log line must carry the same names.
#include "common/net/link_stats.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::net {
namespace {

LinkStatistics populated() {
  LinkStatistics s;
  s.role = "robot";
  s.session_open = true;
  s.link_up = false;
  s.sessions_opened = 3;
  s.handshakes_evicted = 7;
  s.since_last_rx_ms = -1;  // nothing received yet: a negative 64-bit value
  s.clock.valid = true;
  s.clock.offset_ns = -1'234'567;  // -1.234567 ms
  s.clock.rtt_median_ns = 20'500'000;
  s.clock.samples = 256;
  s.sent = std::numeric_limits<uint64_t>::max();  // beyond a double's 53 bits
  s.rx.lost = 11;
  s.rx.rejected_bad_tag = 5;
  s.path.ignored = 3823;
  return s;
}

TEST(LinkStatsJson, ReadsBackIntoTheLinkReportWithEveryValue) {
  const std::string json = to_json(populated());
  const report::Link r = test::read_report_json<report::Link>(json);
  EXPECT_EQ(r.role(), "robot");
  EXPECT_TRUE(r.session_open());
  EXPECT_FALSE(r.link_up());
  EXPECT_EQ(r.sessions_opened(), 3u);
  EXPECT_EQ(r.handshakes_evicted(), 7u);
  EXPECT_EQ(r.since_last_rx_ms(), -1);
  EXPECT_TRUE(r.clock_valid());
  EXPECT_DOUBLE_EQ(r.clock_offset_ms(), -1.234567);
  EXPECT_DOUBLE_EQ(r.rtt_median_ms(), 20.5);
  EXPECT_EQ(r.clock_samples(), 256u);
  EXPECT_EQ(r.sent(), std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(r.lost(), 11u);
  EXPECT_EQ(r.rejected_bad_tag(), 5u);
  EXPECT_EQ(r.path_copies_ignored(), 3823u);
  EXPECT_FALSE(r.has_robot());  // the robot station adds its own object
  // Every field is printed, zeros too, under its proto name (readers look up
  // keys that are zero in a clean run).
  EXPECT_NE(json.find("\"rejected_replay\": \"0\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"rtt_min_ms\": 0"), std::string::npos) << json;
}

TEST(LinkStatsJson, LogLineHasTheReportsNamesAndValues) {
  const std::string line = to_log_fields(populated());
  EXPECT_EQ(line.rfind("role=robot session_open=true link_up=false sessions_opened=3 ", 0), 0u) << line;
  for (const char* kv : {" since_last_rx_ms=-1 ", " clock_offset_ms=-1.235 ", " rtt_median_ms=20.500 ",
                         " sent=18446744073709551615 ", " path_copies_ignored=3823 "})
    EXPECT_NE(line.find(kv), std::string::npos) << kv << "\n" << line;
  EXPECT_EQ(line.back(), '0');  // path_responses_unmatched=0 ends it: no trailing separator
  // One key=value per scalar field of the report, nothing else.
  std::size_t fields = 0;
  for (char c : line) fields += c == '=';
  std::size_t scalars = 0;  // not the stations' own messages ("robot", "twoarm")
  const auto* d = report::Link::descriptor();
  for (int i = 0; i < d->field_count(); ++i)
    scalars += d->field(i)->cpp_type() != google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE ? 1 : 0;
  EXPECT_EQ(fields, scalars);
  EXPECT_EQ(scalars, static_cast<std::size_t>(d->field_count() - 2));
}

}  // namespace
}  // namespace hemm::net
