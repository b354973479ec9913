// Link statistics of one station, as a value (snapshot), with text and JSON
// renderings for logs, the exit summary and tests (--stats-json).
#pragma once

#include <cstdint>
#include <string>

#include "common/net/clock_sync.h"
#include "common/net/path_validation.h"
#include "common/net/stream_receiver.h"

namespace hemm::report {
class Link;  // report.pb.h
}

namespace hemm::net {

struct LinkStatistics {
  std::string role;               // "robot" / "operator"
  bool session_open = false;      // authenticated TCP session up
  bool link_up = false;           // authenticated datagrams within link_timeout
  uint64_t sessions_opened = 0;
  uint64_t sessions_refused = 0;  // robot: refused (control taken); operator: 0
  uint64_t handshakes_failed = 0;
  uint64_t handshakes_evicted = 0;  // robot: pending handshakes closed to make room (per-source limits)
  uint64_t accept_errors = 0;       // robot: failed accepts (backed off)
  uint64_t link_lost_events = 0;
  uint64_t link_restored_events = 0;
  int64_t since_last_rx_ms = -1;  // -1: nothing received yet
  uint64_t sent = 0;              // datagrams sent
  uint64_t send_errors = 0;
  uint64_t pings_sent = 0;
  uint64_t pongs_received = 0;
  ClockEstimate clock;            // operator: robot clock minus ours; robot: operator's minus ours
  StreamCounters rx;
  PathCounters path;              // robot: path validation of the operator's address
};

// The statistics as the report message proto/report.proto's Link (no robot
// object); to_json prints it (config::to_json).
report::Link to_report(const LinkStatistics& s);
std::string to_json(const LinkStatistics& s);
// One line of key=value fields: the report's fields, in its order.
std::string to_log_fields(const LinkStatistics& s);
// A human-readable multi-line summary.
std::string to_summary(const LinkStatistics& s);

}  // namespace hemm::net
