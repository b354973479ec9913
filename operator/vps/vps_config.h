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

// The device the VPS session runs: the scene's SIMULATED scripted hands when
// vps.hands is set, else device.type: "sim-omni" (SIMULATED Omni whose hand
// follows vps.omni_waypoints) or "replay" (`replay_file`). Throws
// std::invalid_argument / std::runtime_error with a one-line message.
std::unique_ptr<device::HapticDevice> make_vps_device(const config::OperatorConfig& cfg,
                                                      const std::string& replay_file);

}  // namespace hemm::op
