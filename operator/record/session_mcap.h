// A session recording as MCAP (https://mcap.dev/spec) with protobuf schemas,
// for robotics tools (Foxglove Studio, the mcap CLI, any MCAP reader):
// `hemm-operator --export-mcap REC OUT.mcap` writes it, `hemm-operator
// --replay OUT.mcap` replays it as it replays REC (docs/recording.md).
//
// One channel per kind, message encoding "protobuf", each schema the binary
// FileDescriptorSet of its message type with every file it imports:
//   /hemm/recording      hemm.rec.Header        the recording's header (one)
//   /operator/servo      hemm.rec.ServoTick     each servo tick: model version,
//                                               the commanded wrenches, mode
//                                               (its `ee` left empty: below)
//   /operator/device     hemm.rec.DeviceSample  the tick's device samples
//   /operator/model_step hemm.rec.ModelStep     each model step's inputs
//   /robot/state         hemm.wire.RobotState   received
//   /robot/scan          hemm.wire.RangeScan    received
//   /robot/depth         hemm.wire.DepthChunk   received depth frames' chunks
//   /operator/command    hemm.wire.Command      sent
//   /link/stream         hemm.rec.StreamEvent   the other stream messages
//                                               (heartbeats, pings, pongs, ...)
//   /link/session        hemm.rec.SessionEvent  session frames, both ways
// log_time and publish_time: the recording's time of each (operator steady
// clock, ns; a tick's wake time, a step's time, a message's arrival or
// sending). Sequence numbers: the tick number on the servo and device
// channels, the order of arrival on the others.
//
// Reading it back gives the Recording load_recording gives for REC (every
// record's checks are the same ones, session_recording.h), so a replay
// from either renders the same forces.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include "operator/record/session_recording.h"

namespace hemm::op {

struct McapExport {
  std::uint64_t messages = 0, chunks = 0, bytes = 0, uncompressed_bytes = 0;
  std::map<std::string, std::uint64_t> topics;  // messages per topic
};

// Writes `rec` to `path`. Throws std::runtime_error if the file cannot be
// written.
McapExport export_mcap(const Recording& rec, const std::string& path);

// Reads an export back (MCAP reading: mcap_file.h). Errors as
// load_recording's: none (all read); an error with *out untouched (not an
// MCAP file, or no valid /hemm/recording header); or an error with *out
// holding what came before the first bad message.
std::optional<std::string> load_mcap_recording(const std::string& path, Recording* out);

// One line per topic, "topic: N messages", and the file's totals.
std::string to_string(const McapExport& e);

}  // namespace hemm::op
