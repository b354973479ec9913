#include "common/net/link_stats.h"

#include <cstdio>
#include <sstream>

#include "common/config/config.h"
#include "report.pb.h"

namespace hemm::net {
namespace {

double ms(int64_t ns) { return static_cast<double>(ns) * 1e-6; }

std::string ms_text(int64_t ns) {
  char b[64];
  std::snprintf(b, sizeof b, "%.3f", ms(ns));
  return b;
}

}  // namespace

report::Link to_report(const LinkStatistics& s) {
  report::Link r;
  r.set_role(s.role);
  r.set_session_open(s.session_open);
  r.set_link_up(s.link_up);
  r.set_sessions_opened(s.sessions_opened);
  r.set_sessions_refused(s.sessions_refused);
  r.set_handshakes_failed(s.handshakes_failed);
  r.set_handshakes_evicted(s.handshakes_evicted);
  r.set_accept_errors(s.accept_errors);
  r.set_link_lost_events(s.link_lost_events);
  r.set_link_restored_events(s.link_restored_events);
  r.set_since_last_rx_ms(s.since_last_rx_ms);
  r.set_clock_valid(s.clock.valid);
  r.set_clock_offset_ms(ms(s.clock.offset_ns));
  r.set_rtt_last_ms(ms(s.clock.rtt_last_ns));
  r.set_rtt_min_ms(ms(s.clock.rtt_min_ns));
  r.set_rtt_median_ms(ms(s.clock.rtt_median_ns));
  r.set_clock_samples(s.clock.samples);
  r.set_sent(s.sent);
  r.set_send_errors(s.send_errors);
  r.set_pings_sent(s.pings_sent);
  r.set_pongs_received(s.pongs_received);
  const StreamCounters& c = s.rx;
  r.set_received(c.received);
  r.set_delivered(c.delivered);
  r.set_lost(c.lost);
  r.set_reordered(c.reordered);
  r.set_late(c.late);
  r.set_duplicated(c.duplicated);
  r.set_rejected_bad_size(c.rejected_bad_size);
  r.set_rejected_bad_magic(c.rejected_bad_magic);
  r.set_rejected_bad_version(c.rejected_bad_version);
  r.set_rejected_unknown_session(c.rejected_unknown_session);
  r.set_rejected_bad_tag(c.rejected_bad_tag);
  r.set_rejected_replay(c.rejected_replay);
  r.set_rejected_bad_payload(c.rejected_bad_payload);
  const PathCounters& pc = s.path;
  r.set_path_challenges_sent(pc.challenges_sent);
  r.set_paths_validated(pc.validated);
  r.set_path_copies_ignored(pc.ignored);
  r.set_path_challenges_rate_limited(pc.rate_limited);
  r.set_path_responses_unmatched(pc.responses_unmatched);
  r.set_path_responses_refused(pc.responses_refused);
  return r;
}

std::string to_json(const LinkStatistics& s) { return config::to_json(to_report(s)); }

std::string to_log_fields(const LinkStatistics& s) {
  // The report's scalar fields by reflection, so a log line and the JSON file
  // can never disagree on a name. Milliseconds to the microsecond.
  const report::Link r = to_report(s);
  const google::protobuf::Reflection& rf = *r.GetReflection();
  const google::protobuf::Descriptor& d = *r.GetDescriptor();
  std::ostringstream os;
  char b[64];
  for (int i = 0; i < d.field_count(); ++i) {
    using FD = google::protobuf::FieldDescriptor;
    const FD& f = *d.field(i);
    if (f.cpp_type() == FD::CPPTYPE_MESSAGE) continue;  // the robot's object: not part of the link's line
    os << (i > 0 ? " " : "") << f.name() << '=';
    switch (f.cpp_type()) {
      case FD::CPPTYPE_STRING: os << rf.GetString(r, &f); break;
      case FD::CPPTYPE_BOOL: os << (rf.GetBool(r, &f) ? "true" : "false"); break;
      case FD::CPPTYPE_INT64: os << rf.GetInt64(r, &f); break;
      case FD::CPPTYPE_UINT64: os << rf.GetUInt64(r, &f); break;
      case FD::CPPTYPE_DOUBLE:
        std::snprintf(b, sizeof b, "%.3f", rf.GetDouble(r, &f));
        os << b;
        break;
      default: os << '?'; break;  // no other types in Link
    }
  }
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
  os << "  rtt ms: last " << ms_text(s.clock.rtt_last_ns) << ", min " << ms_text(s.clock.rtt_min_ns) << ", median "
     << ms_text(s.clock.rtt_median_ns) << "; clock offset ms " << ms_text(s.clock.offset_ns) << " (" << s.clock.samples
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
     << pc.responses_unmatched << " unmatched responses, " << pc.responses_refused
     << " refused (the current path was not silent)\n";
  return os.str();
}

}  // namespace hemm::net
