// The telemanipulation report (proto/report.proto Telemanip): what the link
// sent and received, the robot's refusals, each hand's mapping and rendered
// wrench, the servo timing. Off the servo thread, after the loop stopped.
#pragma once

#include "operator/servo/timing_stats.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_task.h"
#include "report.pb.h"

namespace hemm::op::telemanip {

// `remote` may be null (no state received).
report::Telemanip make_telemanip_report(const TelemanipLinkStats& link, const TelemanipTask& task,
                                        const RemoteArmsState* remote, const servo::TimingSummary* timing);

}  // namespace hemm::op::telemanip
