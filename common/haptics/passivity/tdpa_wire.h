#pragma once
// The TDPA's edge: an arm's port to and from proto/wire.proto PassivityPort,
// and the TDPA parameters from the stations' configs. Not for the 1 kHz
// thread (protobuf allocates): the network thread fills and reads the
// messages and hands the six energies over through the project's mailbox
// (docs/telemanipulation_passivity.md, "Where each end calls what").
#include <cstdint>
#include <string>

#include "common/haptics/passivity/tdpa_arm.h"

namespace hemm::wire {
class PassivityPort;
}
namespace hemm::config {
class OperatorPassivityConfig;
class RobotPassivityConfig;
}  // namespace hemm::config

namespace hemm::haptics::tdpa {

// The port of arm `index` as this end reports it.
void fill(wire::PassivityPort* out, std::uint32_t index, const ArmSide& s, PcMode mode);

// The peer's input energies carried by a PassivityPort: six finite values,
// or `error` says why not (the message is then to be counted and dropped).
bool read_energy_in(const wire::PassivityPort& in, Vec6* energy_in_J, std::string* error);

// The thresholds and controller mode of each end's config (checked by
// config::validate_operator_config).
ModeThresholds thresholds_from(const config::OperatorPassivityConfig& c);
PcMode pc_mode_from(const config::OperatorPassivityConfig& c);
PcMode pc_mode_from(const config::RobotPassivityConfig& c);

}  // namespace hemm::haptics::tdpa
