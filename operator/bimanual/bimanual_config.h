// The bimanual device's configuration block (proto/config_operator.proto:
// device.bimanual) turned into the simulation's and the environment's
// parameters, and checked field by field with clear errors: out-of-range
// limits and gains, unknown handles or projectors, a grip object on an arm
// whose handle has no grip lever, a plane stiffer than the device renders.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "common/config/config.h"
#include "config_operator.pb.h"
#include "operator/bimanual/bimanual_task.h"
#include "operator/device/bimanual/simulation.h"

namespace hemm::op {

struct BimanualSetup {
  device::bimanual::SimulationConfig sim;
  std::array<HandEnvironment, device::kMaxEndEffectors> env;
  std::string script = "features";
};

// Issues with full field paths under `prefix` (e.g. "device.bimanual.").
std::vector<config::FieldIssue> validate_bimanual_config(const config::BimanualDeviceConfig& c,
                                                         const std::string& prefix = "device.bimanual.");

// The operator config's own rules plus, when device.type is
// "sim-bimanual", the bimanual block's (a config::Validator).
std::vector<config::FieldIssue> validate_operator_config_with_bimanual(const google::protobuf::Message& m);

// The setup a valid block describes (throws std::invalid_argument if it is not).
BimanualSetup bimanual_setup(const config::BimanualDeviceConfig& c);

}  // namespace hemm::op
