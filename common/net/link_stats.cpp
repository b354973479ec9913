#include "common/net/link_stats.h"

#include <cstdio>
#include <sstream>

namespace hemm::net {
namespace {

std::string ms(int64_t ns) {
  char b[64];
  std::snprintf(b, sizeof b, "%.3f", static_cast<double>(ns) * 1e-6);
  return b;
}

template <class F>
void fields(const LinkStatistics& s, F&& emit) {
  emit("session_open", s.session_open ? "true" : "false");
  emit("link_up", s.link_up ? "true" : "false");
  emit("sessions_opened", std::to_string(s.sessions_opened));
  emit("sessions_refused", std::to_string(s.sessions_refused));
  emit("handshakes_failed", std::to_string(s.handshakes_failed));
  emit("handshakes_evicted", std::to_string(s.handshakes_evicted));
  emit("accept_errors", std::to_string(s.accept_errors));
  emit("link_lost_events", std::to_string(s.link_lost_events));
  emit("link_restored_events", std::to_string(s.link_restored_events));
  emit("since_last_rx_ms", std::to_string(s.since_last_rx_ms));
  emit("clock_valid", s.clock.valid ? "true" : "false");
  emit("clock_offset_ms", ms(s.clock.offset_ns));
  emit("rtt_last_ms", ms(s.clock.rtt_last_ns));
  emit("rtt_min_ms", ms(s.clock.rtt_min_ns));
  emit("rtt_median_ms", ms(s.clock.rtt_median_ns));
  emit("clock_samples", std::to_string(s.clock.samples));
  emit("sent", std::to_string(s.sent));
  emit("send_errors", std::to_string(s.send_errors));
  emit("pings_sent", std::to_string(s.pings_sent));
  emit("pongs_received", std::to_string(s.pongs_received));
  const StreamCounters& c = s.rx;
  emit("received", std::to_string(c.received));
  emit("delivered", std::to_string(c.delivered));
  emit("lost", std::to_string(c.lost));
  emit("reordered", std::to_string(c.reordered));
  emit("late", std::to_string(c.late));
  emit("duplicated", std::to_string(c.duplicated));
  emit("rejected_bad_size", std::to_string(c.rejected_bad_size));
  emit("rejected_bad_magic", std::to_string(c.rejected_bad_magic));
  emit("rejected_bad_version", std::to_string(c.rejected_bad_version));
  emit("rejected_unknown_session", std::to_string(c.rejected_unknown_session));
  emit("rejected_bad_tag", std::to_string(c.rejected_bad_tag));
  emit("rejected_replay", std::to_string(c.rejected_replay));
  emit("rejected_bad_payload", std::to_string(c.rejected_bad_payload));
  const PathCounters& pc = s.path;
  emit("path_challenges_sent", std::to_string(pc.challenges_sent));
  emit("paths_validated", std::to_string(pc.validated));
  emit("path_copies_ignored", std::to_string(pc.ignored));
  emit("path_challenges_rate_limited", std::to_string(pc.rate_limited));
  emit("path_responses_unmatched", std::to_string(pc.responses_unmatched));
}

}  // namespace

std::string to_json(const LinkStatistics& s) {
  std::ostringstream os;
  os << "{\n  \"role\": \"" << s.role << "\"";
  fields(s, [&](const char* k, const std::string& v) { os << ",\n  \"" << k << "\": " << v; });
  os << "\n}\n";
  return os.str();
}

std::string to_log_fields(const LinkStatistics& s) {
  std::ostringstream os;
  os << "role=" << s.role;
  fields(s, [&](const char* k, const std::string& v) { os << ' ' << k << '=' << v; });
  return os.str();
}

std::string to_summary(const LinkStatistics& s) {
  std::ostringstream os;
  os << "link statistics (" << s.role << ")\n";
  os << "  session open " << (s.session_open ? "yes" : "no") << ", link " << (s.link_up ? "up" : "down")
     << ", sessions " << s.sessions_opened << ", refused " << s.sessions_refused << ", handshakes failed "
     << s.handshakes_failed << ", evicted " << s.handshakes_evicted << ", accept errors " << s.accept_errors
     << ", link lost " << s.link_lost_events << "x, restored " << s.link_restored_events
     << "x\n";
  os << "  rtt ms: last " << ms(s.clock.rtt_last_ns) << ", min " << ms(s.clock.rtt_min_ns) << ", median "
     << ms(s.clock.rtt_median_ns) << "; clock offset ms " << ms(s.clock.offset_ns) << " (" << s.clock.samples
     << " samples" << (s.clock.valid ? "" : ", not valid") << ")\n";
  const StreamCounters& c = s.rx;
  os << "  sent " << s.sent << " (errors " << s.send_errors << "), pings " << s.pings_sent << ", pongs "
     << s.pongs_received << "\n";
  os << "  received " << c.received << ", delivered " << c.delivered << ", lost " << c.lost << ", reordered "
     << c.reordered << ", late " << c.late << ", duplicated " << c.duplicated << "\n";
  os << "  rejected: size " << c.rejected_bad_size << ", magic " << c.rejected_bad_magic << ", version "
     << c.rejected_bad_version << ", unknown session " << c.rejected_unknown_session << ", tag "
     << c.rejected_bad_tag << ", replay " << c.rejected_replay << ", payload " << c.rejected_bad_payload << "\n";
  const PathCounters& pc = s.path;
  os << "  paths: " << pc.validated << " validated, " << pc.challenges_sent << " challenges ("
     << pc.rate_limited << " rate-limited), " << pc.ignored << " datagrams from other addresses ignored, "
     << pc.responses_unmatched << " unmatched responses\n";
  return os.str();
}

}  // namespace hemm::net
