#include "operator/telemanip/telemanip_replay.h"

#include <algorithm>
#include <string>
#include <vector>

#include "common/clock/steady_clock.h"
#include "operator/servo/servo_loop.h"

namespace hemm::op::telemanip {

SessionReplayResult replay_telemanip(const Recording& rec, TelemanipTask& task, TelemanipLink& link) {
  SessionReplayResult r;
  const std::int64_t wall0 = steady_now_ns();
  // The ArmsStates received, in arrival (file) order.
  std::vector<const rec::StreamEvent*> states;
  for (const rec::StreamEvent& e : rec.streams)
    if (!e.outgoing() && e.message().body_case() == wire::StreamMessage::kArmsState) states.push_back(&e);
  std::size_t next = 0;
  std::uint64_t handed = 0;  // the sequence of the last state handed over
  const int ees = std::min(rec.header.end_effectors(), static_cast<int>(device::kMaxEndEffectors));
  const std::int64_t period_ns = rec.header.servo_period_ns() > 0 ? rec.header.servo_period_ns() : 1'000'000;
  OperatorModelSnapshot none;  // version 0: no voxmap
  ServoTickRecord t;
  servo::TickOutput out;
  const std::int64_t rec0 = rec.ticks.empty() ? 0 : rec.ticks.front().t_ns();
  std::uint64_t prev_tick = 0;
  for (std::size_t i = 0; i < rec.ticks.size(); ++i) {
    if (auto e = from_proto(rec.ticks[i], ees, &t)) {
      r.stopped = *e;
      break;
    }
    if (t.remote_seq != 0 && t.remote_seq != handed) {
      // The first state with that sequence from here on (sequences restart
      // with a session, later in the file).
      std::size_t j = next;
      while (j < states.size() && states[j]->seq() != t.remote_seq) ++j;
      if (j == states.size()) {
        r.stopped = "tick " + std::to_string(t.tick) + " took ArmsState " + std::to_string(t.remote_seq) +
                    ", which the recording does not have";
        break;
      }
      link.on_arms_state(states[j]->seq(), states[j]->t_ns(), states[j]->message().arms_state());
      handed = t.remote_seq;
      next = j + 1;
      ++r.remote_states;
    }
    if (i > 0 && t.tick > prev_tick + 1) r.ticks_missing += t.tick - prev_tick - 1;
    prev_tick = t.tick;
    servo::prepare_tick_output(t.in, t.tick, out);
    out.deadline_ns = t.in.t_ns + period_ns;
    task.tick(t.in, none, out);
    ++r.ticks;
    r.recorded_s = static_cast<double>(t.in.t_ns - rec0) * 1e-9;
    if (t.mode != (task.params().mode == FeedbackMode::kDirect ? 1u : 0u)) ++r.mode_mismatches;  // the feedback mode
    if (t.model_version != 0) {  // rendered against the live voxmap: not rebuilt
      ++r.ticks_not_compared;
      continue;
    }
    double err = 0.0;
    for (int k = 0; k < ees; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      err = std::max({err, (out.command.ee[kk].force_H - t.command.ee[kk].force_H).norm(),
                      (out.command.ee[kk].torque_H - t.command.ee[kk].torque_H).norm()});
    }
    if (!(err <= 1e-9)) ++r.force_mismatches;
    if (!(err <= r.max_force_error_N)) {
      r.max_force_error_N = err;
      r.max_error_tick = t.tick;
    }
  }
  if (r.ticks_not_compared > 0)
    r.warning = "a model-mediated session: " + std::to_string(r.ticks_not_compared) +
                " ticks rendered against the live voxmap, which the replay does not rebuild (replayed without it, not "
                "compared)";
  r.wall_s = static_cast<double>(steady_now_ns() - wall0) * 1e-9;
  return r;
}

}  // namespace hemm::op::telemanip
