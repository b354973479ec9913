// Bimanual telemanipulation of the two-arm robot (issue 25; config block
// telemanip, device sim-bimanual): the SIMULATED bimanual device's two hands
// drive the robot's two arms through the mapping (operator/telemanip), feel
// each gripper's pointshell against the live voxmap built from the robot's
// head-camera DepthChunks (model-mediated), and the link streams ArmsCommand
// and takes ArmsState. The SIMULATED humans follow telemanip.human_script
// through the mapping (telemanip_human.h), or with telemanip.task (--task)
// the task script of the two-arm station's box, peg or bar task on the
// believed remote state (task_human.h); the run then ends task_settle_s
// after the script is done. At exit: the telemanip report
// (commands, refusals, per-hand rendered wrench, servo timing, the link) on
// stdout and in --stats-json. This thread is the network thread.
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <google/protobuf/text_format.h>
#include <chrono>
#include <csignal>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/config/config.h"
#include "common/haptics/passivity/tdpa_wire.h"
#include "common/net/link_stats.h"
#include "operator/bimanual/bimanual_config.h"
#include "operator/client/operator_client.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/model/model_thread.h"
#include "operator/record/session_recording.h"
#include "operator/runners/runners.h"
#include "operator/telemanip/telemanip_config.h"
#include "operator/telemanip/telemanip_human.h"
#include "operator/telemanip/telemanip_link.h"
#include "operator/telemanip/telemanip_replay.h"
#include "operator/telemanip/telemanip_report.h"
#include "operator/telemanip/telemanip_task.h"
#include "operator/telemanip/task_human.h"

namespace hemm::op::runner {

namespace hb = hemm::device::bimanual;
namespace tele = hemm::op::telemanip;

namespace {

// The feedback mode's part of the report (issue 25 part 5): the mode the
// link's measured round trip and loss suggest, and the direct hands' lines.
void telemanip_mode_report(const config::OperatorConfig& cfg, const tele::TelemanipTask& task,
                           const net::LinkStatistics& st, report::Telemanip* r) {
  const double rtt_s = st.clock.valid ? 1e-9 * static_cast<double>(st.clock.rtt_median_ns)
                                      : std::numeric_limits<double>::quiet_NaN();
  const double seen = static_cast<double>(st.rx.delivered + st.rx.lost);
  const double loss = seen > 0 ? static_cast<double>(st.rx.lost) / seen : 0.0;
  tele::set_suggested_mode(r, task.params().mode, rtt_s, loss, haptics::tdpa::thresholds_from(cfg.passivity()));
  std::cout << tele::direct_summary(*r);
  if (task.params().mode == tele::FeedbackMode::kDirect)
    for (int k = 0; k < tele::kTeleArms; ++k)
      std::cout << "telemanip: direct hand " << k << ": the hand's G went up to "
                << task.direct_hand(k).stats.max_commanded_travel_m << " m from its start, the remote G up to "
                << task.direct_hand(k).stats.max_remote_travel_m << " m\n";
}

// The device, the servo task's and the link's parameters from a telemanip
// config with servo period period_ns: "" or the reason it is refused.
std::string telemanip_setup(const config::OperatorConfig& cfg, std::int64_t period_ns, BimanualSetup* setup,
                            tele::TelemanipTaskParams* tp, tele::TelemanipLinkParams* lp) {
  if (cfg.device().type() != "sim-bimanual") return "telemanip needs device.type \"sim-bimanual\"";
  if (const auto issues = validate_bimanual_config(cfg.device().bimanual()); !issues.empty())
    return issues.front().field + ": " + issues.front().message;
  const double period_s = static_cast<double>(period_ns) * 1e-9;
  *setup = bimanual_setup(cfg.device().bimanual());
  setup->sim.plant.control_period_s = period_s;
  if (std::string e = tele::telemanip_params(cfg.telemanip(), period_s, hb::bimanual_limits(setup->sim), tp, lp,
                                             &cfg.passivity());
      !e.empty())
    return e;
  for (int k = 0; k < hb::kArms; ++k) {
    const tele::ArmMappingParams& m = tp->mapping[static_cast<std::size_t>(k)];
    const hb::HandleKind gate = setup->sim.plant.handles[static_cast<std::size_t>(m.deadman_ee)];
    if (m.clutch_button > 0 && !hb::has_input(gate, hb::HandleInput::kButtons))
      return std::string("telemanip.") + (k == 0 ? "right" : "left") + ".clutch_button: the " + hb::to_string(gate) +
             " handle of end-effector " + std::to_string(m.deadman_ee) + " (deadman_ee) has no buttons";
  }
  return {};
}

}  // namespace

int replay_telemanip_recording(const Recording& rec, const OperatorArgs& a) {
  config::OperatorConfig cfg;
  if (!google::protobuf::TextFormat::ParseFromString(rec.header.config_text(), &cfg)) {
    std::cerr << "hemm-operator: --replay: the recording's config does not parse\n";
    return net::kExitUsage;
  }
  BimanualSetup setup;
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  if (std::string e = telemanip_setup(cfg, rec.header.servo_period_ns(), &setup, &tp, &lp); !e.empty()) {
    std::cerr << "hemm-operator: --replay: the recording's config: " << e << "\n";
    return net::kExitUsage;
  }
  // Its voxmap is not rebuilt (telemanip_replay.h): no work-rate calibration.
  tp.tick_budget_ns = 0;
  std::unique_ptr<tele::TelemanipTask> task;
  try {
    task = std::make_unique<tele::TelemanipTask>(tp);
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: --replay: " << e.what() << "\n";
    return net::kExitUsage;
  }
  asio::io_context io;  // never run: the link's state checks only
  tele::TelemanipLink link(io, task->setpoints(), task->remote(), [](const wire::StreamMessage&) { return true; },
                           &steady_now_ns, lp);
  const SessionReplayResult r = tele::replay_telemanip(rec, *task, link);
  if (!r.warning.empty()) std::cerr << "hemm-operator: --replay: " << r.warning << "\n";
  std::cout << "replay (telemanip, " << rec.header.telemanip_mode() << "): ticks=" << r.ticks
            << " remote_states=" << r.remote_states << " ticks_missing=" << r.ticks_missing
            << " ticks_not_compared=" << r.ticks_not_compared << " force_mismatches=" << r.force_mismatches
            << " max_force_error_N=" << r.max_force_error_N << " mode_mismatches=" << r.mode_mismatches
            << " recorded_s=" << r.recorded_s << " wall_s=" << r.wall_s
            << (r.stopped.empty() ? "" : " stopped=\"" + r.stopped + "\"") << "\n";
  std::string error;
  if (!a.replay_json.empty() && !net::write_text_file(a.replay_json, to_json(r), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    return net::kExitInternal;
  }
  return r.stopped.empty() ? net::kExitOk : net::kExitUsage;
}

int run_telemanip(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  // The networked station's output this runner does not have: said, not
  // silently skipped.
  if (!a.servo_log.empty()) {
    std::cerr << "hemm-operator: --log: the telemanip servo writes no CSV log; --stats-json reports its ticks\n";
    return net::kExitUsage;
  }
  const servo::ServoConfig sc = servo_config(cfg);
  BimanualSetup setup;
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  if (std::string e = telemanip_setup(cfg, sc.period_ns, &setup, &tp, &lp); !e.empty()) {
    std::cerr << "hemm-operator: bad config: " << e << "\n";
    return net::kExitUsage;
  }
  const std::string robot_address = a.robot.empty() ? cfg.net().robot_address() : a.robot;
  const auto key =
      net::load_station_key("hemm-operator", a.key_path, a.config_path, cfg.link().key_file(), robot_address);
  if (!key) return net::kExitKey;

  // The hand trace's file, tried now (its header): a path that cannot be
  // written is refused before the run, not found out after it.
  if (std::string e; !a.hand_trace.empty() && !net::write_text_file(a.hand_trace, tele::hand_trace_csv({}), &e)) {
    std::cerr << "hemm-operator: --hand-trace: " << e << "\n";
    return net::kExitUsage;
  }
  // --record: the session (ticks of both hands, every stream message and
  // session frame) into one file, as the HEMM station records its own;
  // opened now, so a path that cannot be written is refused before the run.
  std::unique_ptr<SessionRecorder> recorder;
  if (!a.record_path.empty()) {
    rec::Header h;
    h.set_start_ns(steady_now_ns());
    h.set_servo_period_ns(sc.period_ns);
    h.set_initial_mode(2);  // manipulation
    h.set_script(cfg.telemanip().task().empty() ? cfg.telemanip().human_script() : "task " + cfg.telemanip().task());
    h.set_end_effectors(hb::kArms);
    h.set_telemanip_mode(tele::to_string(tp.mode));
    google::protobuf::TextFormat::PrintToString(cfg, h.mutable_config_text());
    try {
      recorder = std::make_unique<SessionRecorder>(a.record_path, h);
    } catch (const std::exception& e) {
      std::cerr << "hemm-operator: --record: " << e.what() << "\n";
      return net::kExitUsage;
    }
  }
  std::string task_scene;
  if (std::string e = tele::check_task_config(cfg.telemanip(), a.config_path, &task_scene); !e.empty()) {
    std::cerr << "hemm-operator: bad config: " << e << "\n";
    return net::kExitUsage;
  }
  // The task's plan from its scene, before anything costly is built: a bad
  // scene is refused at once (under the sanitizers the servo task's
  // calibration alone takes tens of seconds).
  std::optional<twoarm_tasks::TaskScript> plan;
  if (!cfg.telemanip().task().empty()) {
    try {
      plan = tele::task_plan(cfg.telemanip().task(), task_scene);
    } catch (const std::exception& e) {
      std::cerr << "hemm-operator: bad config: " << e.what() << "\n";
      return net::kExitUsage;
    }
  }
  std::unique_ptr<tele::TaskHumanBrain> brain;  // the task's SIMULATED human, if any
  std::unique_ptr<tele::TelemanipTask> task;
  std::unique_ptr<hb::SimulatedBimanualDevice> device;
  servo::ModelChannel channel;
  ModelThreadParams mp;
  // The live voxmap of the workbench from the head camera, kept in a cube
  // that follows the grippers (A = W).
  mp.live_voxmap = tp.render;
  mp.voxmap_roi = VoxmapRoi::kProbe;
  mp.voxmap_probe_roi.size = 1.2;
  mp.voxmap_probe_roi.margin = 0.3;
  std::unique_ptr<ModelThread> model;
  // The robot's newest status (the link writes it): the SIMULATED humans
  // press their dead-man when the robot is there and asks for it.
  std::atomic<std::uint32_t> robot_safety{tele::kNoRobotState};
  try {
    task = std::make_unique<tele::TelemanipTask>(tp);
    task->set_trace(!a.hand_trace.empty());
    model = std::make_unique<ModelThread>(channel, mp);
    task->set_roi_out(&model->probe_positions());
    if (plan) {
      brain = std::make_unique<tele::TaskHumanBrain>(std::move(*plan), tp.mapping);
      if (tp.mode == tele::FeedbackMode::kDirect) {
        // The direct mode: the human corrects the drift it sees (task_human.h).
        tele::DriftCorrectionParams d;
        d.gain_per_s = 0.25;
        d.wait_s = cfg.link().rtt_ms() / 1000.0 + 0.5;
        brain->set_drift_correction(d);
      }
      device = std::make_unique<hb::SimulatedBimanualDevice>(
          setup.sim, tele::task_hands(setup.sim, tp.mapping, {&task->anchors(0), &task->anchors(1)}, *brain, &robot_safety));
    }
    const auto rest = hb::BimanualSimulation(setup.sim).resting_targets();
    const bool demo = cfg.telemanip().human_script() == "demo";
    const double travel = hb::handle_spec(setup.sim.plant.handles[0]).grip_travel;
    auto right = std::make_shared<const tele::MappedHumanScript>(
        rest[0], tp.mapping[0], demo && travel > 0 ? tele::demo_right_route(travel) : std::vector<tele::GRouteKey>{},
        &task->anchors(0), 0.5, &robot_safety);
    auto left = std::make_shared<const tele::MappedHumanScript>(rest[1], tp.mapping[1], std::vector<tele::GRouteKey>{},
                                                                &task->anchors(1), 0.5, &robot_safety);
    if (!device)
      device = std::make_unique<hb::SimulatedBimanualDevice>(
          setup.sim, std::array<std::shared_ptr<const hb::HumanScript>, hb::kArms>{right, left});
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    return net::kExitUsage;
  }
  if (recorder) {
    task->set_tick_tap(&recorder->ticks());
    recorder->start();
  }
  SessionRecorder* const rec_out = recorder.get();
  servo::ServoLoop loop(*device, *task, channel, sc);

  asio::io_context io;
  OperatorClient client(io, client_options(cfg, a, robot_address, *key));
  tele::TelemanipLink link(
      io, task->setpoints(), task->remote(),
      [&client, rec_out](const wire::StreamMessage& m) {
        if (rec_out != nullptr) rec_out->stream(steady_now_ns(), true, m);
        return client.streams().send(m);
      },
      &steady_now_ns, lp, [&client] { return client.link_up(); });
  link.set_safety_out(&robot_safety);
  tele::TelemanipLink::ReceivedTap state_tap;
  if (rec_out != nullptr)
    state_tap = [rec_out](std::uint64_t seq, std::int64_t recv_ns, const wire::StreamMessage& m) {
      rec_out->stream(recv_ns, false, m, seq);
    };
  tele::TelemanipLink::Accepted believe;
  if (brain) believe = [b = brain.get()](const wire::ArmsState& s) { b->believed().publish(s); };
  link.attach(client.streams(), std::move(state_tap), std::move(believe));
  client.streams().on(wire::StreamMessage::kDepthChunk,
                      [&model, rec_out](const net::DatagramHeader& dh, std::int64_t recv_ns, const wire::StreamMessage& m) {
                        if (rec_out != nullptr) rec_out->stream(recv_ns, false, m, dh.seq);
                        model->submit_depth_chunk(std::make_shared<const wire::DepthChunk>(m.depth_chunk()));
                      });
  if (rec_out != nullptr)
    client.set_session_frame_tap([rec_out](const wire::SessionFrame& f) { rec_out->session(steady_now_ns(), false, f); });
  int exit_code = net::kExitOk;
  bool stopping = false;
  asio::signal_set signals(io, SIGINT, SIGTERM);
  asio::steady_timer duration(io);
  asio::steady_timer clock_timer(io);
  asio::steady_timer task_timer(io);
  asio::steady_timer trace_timer(io);
  const auto shutdown = [&](const std::string& why) {
    if (stopping) return;
    stopping = true;
    spdlog::info("event=station_stopping reason=\"{}\"", why);
    link.stop();
    signals.cancel();
    duration.cancel();
    clock_timer.cancel();
    task_timer.cancel();
    trace_timer.cancel();
    client.stop(why);
  };
  // The depth chunks' robot stamps on our clock: the link's estimate, to the model thread.
  std::function<void()> clock_tick = [&] {
    clock_timer.expires_after(std::chrono::milliseconds(100));
    clock_timer.async_wait([&](const asio::error_code& ec) {
      if (ec || stopping) return;
      const net::LinkStatistics st = client.statistics();
      if (st.clock.valid) {
        model->set_clock_offset(st.clock.offset_ns);
        loop.set_link_stats(st.clock.rtt_last_ns, st.clock.offset_ns);
      }
      clock_tick();
    });
  };
  std::string error;
  if (!client.start(
          [&](int code, const std::string& why) {
            spdlog::error("event=link_failed code={} reason=\"{}\"", code, why);
            exit_code = code;
            shutdown(why);
          },
          &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    return net::kExitUsage;
  }
  model->start();
  link.start();
  const servo::RealtimeStatus rt = loop.start();
  for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
  spdlog::info("event=station_started device=sim-bimanual mode=telemanip fifo={} memory_locked={} shells={}", rt.fifo,
               rt.memory_locked, task->grippers().tools.size());
  signals.async_wait([&](const asio::error_code& ec, int sig) {
    if (!ec) shutdown(sig == SIGINT ? "SIGINT" : "SIGTERM");
  });
  clock_tick();
  // The task script done: the run ends task_settle_s later (the robot's judge
  // sees the object come to rest).
  std::function<void()> task_tick = [&] {
    task_timer.expires_after(std::chrono::milliseconds(100));
    task_timer.async_wait([&](const asio::error_code& ec) {
      if (ec || stopping) return;
      if (!brain->done()) return task_tick();
      spdlog::info("event=task_script_done task={} settle_s={}", cfg.telemanip().task(), cfg.telemanip().task_settle_s());
      task_timer.expires_after(std::chrono::milliseconds(static_cast<int64_t>(cfg.telemanip().task_settle_s() * 1000)));
      task_timer.async_wait([&](const asio::error_code& ec2) {
        if (!ec2) shutdown("task script done");
      });
    });
  };
  if (brain) {
    brain->start();
    task_tick();
  }
  // The hand trace: the servo's newest sample every 10 ms (the first 20 minutes).
  std::vector<tele::HandTraceSample> trace_rows;
  constexpr std::size_t kTraceRows = 20 * 60 * 100;
  std::function<void()> trace_tick = [&] {
    trace_timer.expires_after(std::chrono::milliseconds(10));
    trace_timer.async_wait([&](const asio::error_code& ec) {
      if (ec || stopping) return;
      if (const tele::HandTraceSample* t = task->trace().take(); t != nullptr && trace_rows.size() < kTraceRows)
        trace_rows.push_back(*t);
      trace_tick();
    });
  };
  if (!a.hand_trace.empty()) {
    trace_rows.reserve(kTraceRows);
    trace_tick();
  }
  if (a.duration_s > 0) {
    duration.expires_after(std::chrono::milliseconds(static_cast<int64_t>(a.duration_s * 1000)));
    duration.async_wait([&](const asio::error_code& ec) {
      if (!ec) shutdown("duration reached");
    });
  }
  io.run();
  if (brain) brain->stop();
  loop.stop();
  model->stop();
  if (recorder) {
    client.set_session_frame_tap(nullptr);
    recorder->stop();
    spdlog::info("event=recorded file=\"{}\" records={} ticks_dropped={} write_failed={}", a.record_path,
                 recorder->records(), recorder->ticks_dropped(), recorder->write_failed());
    std::cout << "telemanip: recorded " << recorder->records() << " records to " << a.record_path << " ("
              << recorder->ticks_dropped() << " ticks dropped)\n";
    if (recorder->write_failed()) {
      std::cerr << "hemm-operator: writing " << a.record_path << " failed\n";
      exit_code = net::kExitInternal;
    }
  }

  const servo::TimingSummary timing = loop.summary();
  report::Telemanip r = tele::make_telemanip_report(link.stats(), *task, task->latest_remote(), &timing);
  *r.mutable_link() = net::to_report(client.statistics());
  if (brain) {
    const tele::TaskProgress p = brain->progress();
    tele::fill_task_report(p, r.mutable_task());
    std::cout << "telemanip: task " << p.task << " (SIMULATED human): " << (p.done ? "script done" : "script NOT done")
              << " after " << p.done_s << " s, step " << p.steps_done << " of " << p.steps << " (" << p.last_step
              << "), searches " << p.searches << ", clutch presses " << p.clutch_presses << " (the plan waited " << p.indexing_pause_s << " s)"
              << (tp.mode == tele::FeedbackMode::kDirect ? ", drift corrected up to " + std::to_string(p.drift_offset_max_m[0]) + " / " + std::to_string(p.drift_offset_max_m[1]) + " m" : "")
              << (p.error.empty() ? "" : ", error: " + p.error) << "\n";
  }
  telemanip_mode_report(cfg, *task, client.statistics(), &r);
  const hb::BimanualDeviceCounters& dc = device->counters();  // the plant's thread has stopped
  for (report::TelemanipHand& h : *r.mutable_hand()) {
    if (h.index() >= static_cast<std::uint32_t>(hb::kArms)) continue;
    const std::size_t k = h.index();
    h.set_device_joint_limit_ticks(dc.joint_limit_writes[k]);
    h.set_device_wall_ticks(dc.wall_writes[k]);
    h.set_device_collision_ticks(dc.collision_writes[k]);
    h.set_device_peak_joint_limit_nm(dc.peak_joint_limit_nm[k]);
    h.set_device_peak_wall_n(dc.peak_wall_n[k]);
    h.set_device_peak_collision_nm(dc.peak_collision_nm[k]);
    h.set_device_stretched_ticks(dc.stretched_writes[k]);
  }
  std::cout << "telemanip: commands " << r.commands_sent() << " (dead-man pressed " << r.deadman_pressed()
            << "), states " << r.states_in() << " (rejected " << r.states_rejected() << "), refusals "
            << r.refusals().refused() << " (last " << r.refusals().last_reason() << ")\n";
  for (const report::TelemanipHand& h : r.hand())
    std::cout << "telemanip: hand " << h.index() << ": presses " << h.presses() << ", engaged ticks "
              << h.engaged_ticks() << ", clutch ticks " << h.clutch_ticks() << ", contact ticks " << h.contact_ticks() << ", grasp ticks (contact not rendered) " << h.grasp_ticks() << ", peak force " << h.peak_force_n()
              << " N; the device's own limits engaged: joint range " << h.device_joint_limit_ticks() << " ticks (peak "
              << h.device_peak_joint_limit_nm() << " N m), walls " << h.device_wall_ticks() << " (peak "
              << h.device_peak_wall_n() << " N), avoidance " << h.device_collision_ticks() << " (peak "
              << h.device_peak_collision_nm() << " N m), elbow stretched " << h.device_stretched_ticks() << "\n";
  std::cout << servo::to_string(timing) << "\n" << net::to_summary(client.statistics()) << std::flush;
  if (!a.hand_trace.empty() && !net::write_text_file(a.hand_trace, tele::hand_trace_csv(trace_rows), &error)) {
    std::cerr << "hemm-operator: --hand-trace: " << error << "\n";
    if (exit_code == net::kExitOk) exit_code = net::kExitInternal;
  }
  if (!a.stats_json.empty() && !net::write_text_file(a.stats_json, config::to_json(r), &error)) {
    std::cerr << "hemm-operator: " << error << "\n";
    if (exit_code == net::kExitOk) exit_code = net::kExitInternal;
  }
  return exit_code;
}

}  // namespace hemm::op::runner
