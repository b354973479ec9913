// hemm-operator's VPS configuration (proto/config_vps.proto) turned into the
// model spec, the task's parameters and the device: checked field by field,
// errors as "field: message", nothing built until everything is valid.
#pragma once

#include <memory>
#include <string>

#include "config_operator.pb.h"
#include "operator/device/haptic_device.h"
#include "operator/vps/vps_model.h"
#include "operator/vps/vps_task.h"

namespace hemm::op {

struct VpsSetup {
  VpsModelSpec model;
  VpsTaskParams task;
};

// Mesh paths are resolved relative to `config_path`. Throws
// std::invalid_argument("field: message") on the first problem.
VpsSetup vps_setup(const config::OperatorConfig& cfg, const std::string& config_path);

// The device the VPS session runs. With vps.hands (a scene's scripted hand
// paths): device.type "sim-bimanual" makes the SIMULATED bimanual interface
// whose humans follow those paths (vps_bimanual.h); any other type, the
// SIMULATED rigid scripted hands as a ReplayDevice. Without: device.type
// "sim-omni" (SIMULATED Omni whose hand follows vps.omni_waypoints) or
// "replay" (`replay_file`). Throws std::invalid_argument /
// std::runtime_error with a one-line message.
std::unique_ptr<device::HapticDevice> make_vps_device(const config::OperatorConfig& cfg,
                                                      const std::string& replay_file);

// How long a run lasts by default: the scripted hands' path and a hold
// (longer for the yielding SIMULATED humans); 0 without vps.hands.
double vps_default_duration_s(const config::OperatorConfig& cfg);

}  // namespace hemm::op
