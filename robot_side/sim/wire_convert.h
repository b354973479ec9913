// Conversions between the robot station's value types and the hemm::wire
// protos. Everything coming from the wire is validated: bad input returns a
// reason and leaves the output untouched.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "robot_side/sim/sim_types.h"
#include "wire.pb.h"

namespace hemm::robot {

inline constexpr size_t kMaxScanPayloadBytes = 1000;

void to_wire(const Pose2& p, proto::Pose2* out);
void to_wire(const Eigen::Isometry3d& T, proto::Pose3* out);
std::optional<std::string> from_wire(const proto::Pose2& p, Pose2* out);
std::optional<std::string> from_wire(const proto::Pose3& p, Eigen::Isometry3d* out);

void to_wire(const RobotStateSim& s, wire::RobotState* out);
std::optional<std::string> from_wire(const wire::RobotState& s, RobotStateSim* out);

// The command as the operator sends it; `seq` is the datagram's sequence number.
void to_wire(const BaseArmCommand& c, wire::Command* out);
std::optional<std::string> from_wire(const wire::Command& c, uint64_t seq, BaseArmCommand* out);

// Splits a scan into messages of at most `max_payload_bytes` serialized bytes
// each (consecutive beams, RangeScan.first_beam set; every chunk carries the
// full pose information). A scan that fits gives one message.
std::vector<wire::RangeScan> to_wire_chunks(const RangeScanData& scan, size_t max_payload_bytes = kMaxScanPayloadBytes);

// One message (a whole scan or a chunk) back to a scan holding its beams:
// `out->ranges[i]` is beam `*first_beam + i` of the whole scan (angle_min and
// angle_step stay those of the whole scan). Checks sizes, limits and poses.
std::optional<std::string> from_wire(const wire::RangeScan& m, RangeScanData* out, uint32_t* first_beam);

}  // namespace hemm::robot
