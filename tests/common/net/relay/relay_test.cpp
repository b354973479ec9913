// hemm-relay's statistics JSON (--stats-json, the "stats" lines) is
// proto/report.proto's Relay printed on one line by config::to_json: it must
// read back, strictly (no unknown keys), into that message with every value.
#include "common/net/relay/relay.h"

#include <gtest/gtest.h>

#include <cmath>

#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::net::relay {
namespace {

TEST(RelayStatsJson, OneLineThatReadsBackIntoTheRelayReport) {
  RelayStats s;
  s.udp_up.received = 20;
  s.udp_up.forwarded = 19;
  s.udp_up.dropped_burst = 1;
  s.udp_down.duplicated = 2;
  s.udp_down.bytes_received = 1'000'000'000'000ULL;  // 1 TB: past 32 bits
  s.tcp_up.held_outage = 4;
  s.tcp_down.bytes_forwarded = 77;
  s.tcp_connections_rejected = 1;
  s.send_errors = 3;
  s.timing.samples = 131072;
  s.timing.median_us = 12.3456789;  // the old writer kept three decimals
  s.timing.max_us = 1e6 / 3;
  const std::string json = stats_to_json(s);
  // One line: the relay logs it ("stats {...}") and the demo filters that line.
  EXPECT_EQ(json.find('\n'), std::string::npos) << json;
  EXPECT_EQ(json.rfind("{\"tcp\":{\"up\":{", 0), 0u) << json;
  const report::Relay r = test::read_report_json<report::Relay>(json);
  EXPECT_EQ(r.udp().up().received(), 20u);
  EXPECT_EQ(r.udp().up().forwarded(), 19u);
  EXPECT_EQ(r.udp().up().dropped_burst(), 1u);
  EXPECT_EQ(r.udp().down().duplicated(), 2u);
  EXPECT_EQ(r.udp().down().bytes_received(), 1'000'000'000'000ULL);
  EXPECT_EQ(r.tcp().up().held_outage(), 4u);
  EXPECT_EQ(r.tcp().down().bytes_forwarded(), 77u);
  EXPECT_EQ(r.relay().tcp_connections_rejected(), 1u);
  EXPECT_EQ(r.relay().send_errors(), 3u);
  EXPECT_EQ(r.timing().samples(), 131072u);
  EXPECT_EQ(r.timing().median_us(), 12.3456789);  // exactly: printed to round-trip
  EXPECT_EQ(r.timing().max_us(), 1e6 / 3);
}

TEST(RelayStatsJson, NoSendsMeasuredReadsAsZeroTiming) {
  // A relay that sent nothing: all zeros, still every key.
  const std::string json = stats_to_json(RelayStats{});
  const report::Relay r = test::read_report_json<report::Relay>(json);
  EXPECT_EQ(r.timing().samples(), 0u);
  EXPECT_EQ(r.timing().p99_us(), 0.0);
  EXPECT_NE(json.find("\"p99_us\":0"), std::string::npos) << json;
  EXPECT_NE(json.find("\"udp_clients_rejected\":\"0\""), std::string::npos) << json;
}

}  // namespace
}  // namespace hemm::net::relay
