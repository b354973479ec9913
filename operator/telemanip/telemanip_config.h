// The telemanipulation block of the operator's config (config_operator.proto
// TelemanipConfig) as the task's and the link's parameters.
#pragma once

#include <string>

#include "config_operator.pb.h"
#include "operator/device/haptic_device.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_task.h"

namespace hemm::op::telemanip {

// Fills *task and *link from `c` for a servo period and the device's limits;
// "telemanip.FIELD: why" (and nothing changed) when a field is out of range.
// `passivity` (OperatorConfig.passivity, checked by validate_operator_config;
// null: its defaults) gives the direct mode's controller.
std::string telemanip_params(const config::TelemanipConfig& c, double period_s, const device::DeviceLimits& limits,
                             TelemanipTaskParams* task, TelemanipLinkParams* link,
                             const config::OperatorPassivityConfig* passivity = nullptr);
// "model" or "direct"; false for anything else.
bool parse_feedback_mode(const std::string& s, FeedbackMode* out);

}  // namespace hemm::op::telemanip
