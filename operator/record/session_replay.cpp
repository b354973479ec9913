#include "operator/record/session_replay.h"

#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <thread>

#include <google/protobuf/text_format.h>

#include "common/clock/steady_clock.h"
#include "common/config/config.h"
#include "config_operator.pb.h"
#include "report.pb.h"

namespace hemm::op {
namespace {


// Hands the model exactly what the recorded step took, then steps it.
void apply_step(const rec::ModelStep& s, ModelThread& model) {
  for (const rec::SentCommand& c : s.commands()) model.record_command(SentCommand{c.t_ns(), c.v(), c.omega()});
  if (s.has_state()) model.submit_state(s.state());
  for (const wire::RangeScan& scan : s.scans()) model.submit_scan(std::make_shared<const wire::RangeScan>(scan));
  model.set_clock_offset(s.clock_offset_ns());
  model.set_command_delay(s.command_delay_ns());
  model.step(s.now_ns());
}

}  // namespace

SessionReplayResult replay_session(const Recording& rec, const SessionReplayOptions& o) {
  if (!(o.speed >= 0.0) || !std::isfinite(o.speed)) throw std::invalid_argument("replay speed must be >= 0");
  SessionReplayResult r;
  config::OperatorConfig recorded_config;
  if (google::protobuf::TextFormat::ParseFromString(rec.header.config_text(), &recorded_config) &&
      recorded_config.probe_3d().enabled())
    r.warning = "a 3D session (probe_3d): the replay does not rebuild the live voxmap from the recorded depth "
                "chunks, so its 3D forces are not reproduced";
  const int ees = rec.header.end_effectors();
  servo::ModelChannel channel;
  ModelThreadParams mp;
  mp.shapes.enabled = !rec.header.shape_completion_off();
  ModelThread model(channel, mp);
  if (o.on_snapshot) model.set_snapshot_observer(o.on_snapshot);
  OperatorTaskParams tp;
  tp.proxy.period = static_cast<double>(rec.header.servo_period_ns()) * 1e-9;
  tp.initial_mode = static_cast<math::Mode>(rec.header.initial_mode());
  OperatorView view;
  OperatorServoTask task(tp, nullptr, &view);
  std::atomic<std::uint32_t> presses{0};
  task.set_view_outputs(o.ticks, &presses);
  task.on_servo_start();

  const servo::ModelSnapshot empty;
  ServoTickRecord t;
  servo::TickOutput out;
  std::size_t next_step = 0;
  const std::int64_t wall0 = steady_now_ns();
  const std::int64_t rec0 = rec.ticks.empty() ? 0 : rec.ticks.front().t_ns();
  std::uint64_t prev_tick = 0;
  for (std::size_t i = 0; i < rec.ticks.size(); ++i) {
    if (o.stop != nullptr && o.stop->load(std::memory_order_relaxed)) {
      r.stopped = "stopped";
      break;
    }
    const rec::ServoTick& pt = rec.ticks[i];
    if (auto e = from_proto(pt, ees, &t)) {  // load_recording checked it; a Recording built otherwise may not be
      r.stopped = *e;
      break;
    }
    while (next_step < rec.steps.size() && rec.steps[next_step].version() <= t.model_version)
      apply_step(rec.steps[next_step++], model);
    r.steps = next_step;
    const servo::ModelSnapshot* snap = channel.acquire();
    const servo::ModelSnapshot& m = snap != nullptr ? *snap : empty;
    if (m.version != t.model_version) {
      r.stopped = "tick " + std::to_string(t.tick) + " rendered with model version " +
                  std::to_string(t.model_version) + ", the recorded steps reach version " + std::to_string(m.version);
      break;
    }
    if (o.speed > 0.0) {
      const auto due = wall0 + static_cast<std::int64_t>(static_cast<double>(t.in.t_ns - rec0) / o.speed);
      std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(due)));
    }
    if (i > 0 && t.tick > prev_tick + 1) r.ticks_missing += t.tick - prev_tick - 1;
    prev_tick = t.tick;
    presses.store(t.view_presses, std::memory_order_relaxed);
    servo::prepare_tick_output(t.in, t.tick, out);
    task.tick(t.in, m, out);
    if (o.on_tick) o.on_tick(t.tick, out);
    double err = 0.0;
    for (int k = 0; k < ees; ++k) {
      const auto kk = static_cast<std::size_t>(k);
      err = std::max(err, (out.command.ee[kk].force_H - t.command.ee[kk].force_H).norm());
    }
    if (!(err <= 1e-9)) ++r.force_mismatches;
    if (!(err <= r.max_force_error_N)) {
      r.max_force_error_N = err;
      r.max_error_tick = t.tick;
    }
    if (out.mode != t.mode) ++r.mode_mismatches;
    ++r.ticks;
    r.recorded_s = static_cast<double>(t.in.t_ns - rec0) * 1e-9;
  }
  task.on_servo_stop();
  r.wall_s = static_cast<double>(steady_now_ns() - wall0) * 1e-9;
  return r;
}

report::SessionReplay to_report(const SessionReplayResult& r) {
  report::SessionReplay j;
  j.set_ticks(r.ticks);
  j.set_model_steps(r.steps);
  j.set_ticks_missing(r.ticks_missing);
  j.set_force_mismatches(r.force_mismatches);
  j.set_max_force_error_n(r.max_force_error_N);
  j.set_max_error_tick(r.max_error_tick);
  j.set_mode_mismatches(r.mode_mismatches);
  j.set_recorded_s(r.recorded_s);
  j.set_wall_s(r.wall_s);
  j.set_complete(r.stopped.empty());
  j.set_stopped(r.stopped);
  j.set_ticks_not_compared(r.ticks_not_compared);
  j.set_remote_states(r.remote_states);
  return j;
}

std::string to_json(const SessionReplayResult& r) { return config::to_json(to_report(r)); }

}  // namespace hemm::op
