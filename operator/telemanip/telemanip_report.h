// The telemanipulation report (proto/report.proto Telemanip): what the link
// sent and received, the robot's refusals, each hand's mapping and rendered
// wrench, the servo timing. Off the servo thread, after the loop stopped.
#pragma once

#include <string>

#include "operator/servo/timing_stats.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_task.h"
#include "report.pb.h"

namespace hemm::op::telemanip {

// `remote` may be null (no state received).
report::Telemanip make_telemanip_report(const TelemanipLinkStats& link, const TelemanipTask& task,
                                        const RemoteArmsState* remote, const servo::TimingSummary* timing);
// The mode tdpa::suggest_mode gives for the measured link (round trip in s,
// lost share 0..1), from the mode in use, into r's fields 31-33.
void set_suggested_mode(report::Telemanip* r, FeedbackMode in_use, double round_trip_s, double loss,
                        const haptics::tdpa::ModeThresholds& t);
// The report's direct-mode lines for the runner's summary (empty in the model mode).
std::string direct_summary(const report::Telemanip& r);

}  // namespace hemm::op::telemanip
