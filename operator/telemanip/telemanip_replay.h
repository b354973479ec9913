// The servo side of a recorded telemanipulation session (hemm-operator
// --record with telemanip), replayed without a robot: each recorded tick's
// device sample (both hands) goes through a TelemanipTask built from the
// recorded config, after the ArmsState that tick took (by its datagram
// sequence, ServoTick.remote_seq) has been handed to the task through the
// link's own checks (TelemanipLink::on_arms_state); the wrench is compared
// with the recorded one.
//
// What it rebuilds exactly: the mapping, the dead-man and clutch, the
// direct mode's passivity (operator end) and the held objects' weight and
// coupling. What it does not: the live voxmap (its depth chunks are in the
// recording, but it is built on a thread of its own at times not recorded),
// so ticks that rendered against one are replayed without it and counted
// in ticks_not_compared, not compared.
#pragma once

#include "operator/record/session_recording.h"
#include "operator/record/session_replay.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_task.h"

namespace hemm::op::telemanip {

// task and link: built from the recording's config (link unstarted: only its
// state checks are used). A tick whose ArmsState is not in the recording
// stops the replay there (stopped says so); recorded gaps in the tick
// numbers count as ticks_missing.
SessionReplayResult replay_telemanip(const Recording& rec, TelemanipTask& task, TelemanipLink& link);

}  // namespace hemm::op::telemanip
