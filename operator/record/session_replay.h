// Replays a recorded operator session (hemm-operator --replay FILE with a
// recording): rebuilds the local model by stepping a ModelThread (not
// started: on the caller's thread) with each recorded step's inputs at its
// recorded time, and runs an OperatorServoTask on the recorded ticks -- the
// recorded hand's device samples, the snapshot version each tick rendered
// with, the view's key presses -- comparing every commanded force with the
// recorded one. The model and the task are deterministic given these inputs,
// so the forces match to the last bit; the replay reports the largest
// difference.
//
// The task and model parameters are the built-in defaults, with the servo
// period and initial mode from the header (what hemm-operator uses); a
// recording from a build with other defaults replays with differences, which
// the result reports.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "operator/record/session_recording.h"

namespace hemm::report {
class SessionReplay;  // report.pb.h
}

namespace hemm::op {

struct SessionReplayOptions {
  // Replay time per recorded time: 1 real time, 10 ten times faster; 0 as
  // fast as it goes.
  double speed = 1.0;
  // Optional taps, as a live view attaches to a station (operator/view):
  // every snapshot the model publishes, every tick's W-frame record.
  ModelThread::SnapshotObserver on_snapshot;
  NewestMailbox<StationLogRecord>* ticks = nullptr;
  const std::atomic<bool>* stop = nullptr;  // set: ends the replay early
  // Every replayed tick's output (its forces), right after the tick.
  std::function<void(std::uint64_t tick, const servo::TickOutput& out)> on_tick;
};

struct SessionReplayResult {
  std::uint64_t ticks = 0;           // replayed
  std::uint64_t steps = 0;           // model steps applied
  std::uint64_t ticks_missing = 0;   // gaps in the recorded tick numbers (dropped when recording)
  std::uint64_t force_mismatches = 0;  // ticks whose force differs by more than 1e-9 N
  double max_force_error_N = 0.0;    // largest |F_replay - F_recorded| over ticks and end-effectors
  std::uint64_t max_error_tick = 0;
  std::uint64_t mode_mismatches = 0;
  double recorded_s = 0.0;           // recorded time spanned by the replayed ticks
  double wall_s = 0.0;               // the replay's own time
  std::string stopped;               // why it stopped before the last tick, if it did
  // Telemanipulation (telemanip_replay.h): ticks replayed that rendered
  // against the live voxmap, not compared; the ArmsStates handed over.
  std::uint64_t ticks_not_compared = 0;
  std::uint64_t remote_states = 0;
  // What the replay does not rebuild, when the recording needs it: a 3D
  // session's live voxmap (its depth chunks are recorded, the voxmap's build
  // times are not), so its 3D forces differ from the recorded ones.
  std::string warning;
};

// Throws std::invalid_argument on bad options. A recording whose ticks
// reference a model version its steps do not reach ends there (stopped says so).
SessionReplayResult replay_session(const Recording& rec, const SessionReplayOptions& o);

// As proto/report.proto's SessionReplay, and that printed (config::to_json).
report::SessionReplay to_report(const SessionReplayResult& r);
std::string to_json(const SessionReplayResult& r);

}  // namespace hemm::op
