#include "robot_side/station/robot_station.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <random>
#include <sstream>
#include <vector>

#include "common/config/config.h"
#include "common/mapping/depth_stream.h"
#include "common/concurrency/newest_mailbox.h"
#include "common/net/station_cli.h"
#include "config_robot.pb.h"
#include "report.pb.h"
#include "robot_side/sim/realtime.h"
#include "robot_side/station/control_pacer.h"

namespace hemm::robot {
namespace {

// Requests from the session channel, applied by the simulation thread.
struct Request {
  // kEStop: from the operator (a session frame); kLocalEStop: at the robot.
  enum class Kind { kMode, kEStop, kLocalEStop } kind = Kind::kMode;
  wire::Mode mode = wire::MODE_UNSPECIFIED;
  uint64_t request_id = 0;
  bool engaged = false;
  std::string reason;
};

// A bound on queued session requests: a flooding peer gets refusals, not memory.
constexpr size_t kMaxQueuedRequests = 64;

bool is_power_of_two(uint64_t n) { return n != 0 && (n & (n - 1)) == 0; }

wire::SessionFrame make_ack(uint64_t request_id, bool ok, const std::string& reason) {
  wire::SessionFrame f;
  auto* a = f.mutable_ack();
  a->set_request_id(request_id);
  a->set_ok(ok);
  a->set_reason(reason);
  return f;
}

}  // namespace

// A command and how much longer than the fastest command it took to arrive
// (held on the path): the watchdog counts from its send time, so it gets
// that much less time.
struct TimedCommand {
  BaseArmCommand command;
  int64_t excess_age_ns = 0;
};

struct RobotStation::Shared {
  RobotServer* server = nullptr;
  asio::io_context* io = nullptr;
  NewestMailbox<TimedCommand> commands;  // network thread -> simulation thread
  std::mutex req_mu;
  std::vector<Request> requests;  // guarded by req_mu
  std::atomic<bool> stop{false};

  mutable std::mutex state_mu;
  RobotStateSim latest;  // guarded by state_mu
  SeenVoxelsStats seen;  // guarded by state_mu
  SimulatedRobot::ArmContactStats arm_contacts;  // guarded by state_mu
  uint64_t arm_refused_last_seq = 0;  // guarded by state_mu

  std::atomic<uint64_t> sim_steps{0}, contact_steps{0}, guard_states{0};
  PacingCounters pacing;  // the control loop's (simulation thread)
  std::atomic<uint64_t> commands_received{0}, commands_without_control{0}, commands_malformed{0},
      commands_mode_mismatch{0}, commands_stale{0}, commands_applied{0}, commands_rejected{0};
  std::atomic<uint64_t> arm_refused_floor{0}, arm_refused_base{0}, arm_refused_scene{0};
  std::atomic<uint64_t> states_sent{0}, scans_sent{0}, scan_chunks_sent{0}, send_failures{0};
  std::atomic<uint64_t> depth_frames_sent{0}, depth_chunks_sent{0}, depth_frames_skipped{0}, depth_bytes_sent{0};
  std::atomic<uint64_t> mode_changes{0}, estop_changes{0}, requests_refused{0};
  std::atomic<bool> estop{false}, estop_local{false};
  std::atomic<int> mode{0};
  std::atomic<uint32_t> safety{0};
  rt::RealtimeStatus rt_status;  // set before the thread is released
};

namespace {

using SharedPtr = std::shared_ptr<RobotStation::Shared>;

// Network thread only.
void send_now(RobotStation::Shared& sh, const wire::SessionFrame& f) { sh.server->send_session_frame(f); }

void post_frame(const SharedPtr& sh, wire::SessionFrame f) {
  asio::post(*sh->io, [sh, f = std::move(f)] { send_now(*sh, f); });
}

void refuse(RobotStation::Shared& sh, uint64_t request_id, const std::string& why) {
  ++sh.requests_refused;
  spdlog::warn("event=request_refused request_id={} reason=\"{}\"", request_id, why);
}

// Network thread: queue a request for the simulation thread, or refuse it.
void queue_request(const SharedPtr& sh, Request r) {
  std::lock_guard<std::mutex> lk(sh->req_mu);
  if (sh->requests.size() >= kMaxQueuedRequests) {
    // An e-stop is never refused. The robot's own always queues. An
    // operator's engaging one queues past the bound unless the queue's last
    // operator e-stop already engages: then this one is that one (acked now;
    // the simulation thread engages at its next step). So a flood of them
    // adds at most one entry per release queued before the queue filled.
    if (r.kind == Request::Kind::kEStop && r.engaged) {
      const auto last = std::find_if(sh->requests.rbegin(), sh->requests.rend(),
                                     [](const Request& q) { return q.kind == Request::Kind::kEStop; });
      if (last != sh->requests.rend() && last->engaged) {
        send_now(*sh, make_ack(r.request_id, true, "e-stop engaged"));
        return;
      }
    } else if (r.kind != Request::Kind::kLocalEStop) {
      refuse(*sh, r.request_id, "too many pending requests");
      send_now(*sh, make_ack(r.request_id, false, "too many pending requests"));
      return;
    }
  }
  sh->requests.push_back(std::move(r));
}

}  // namespace

report::RobotStation to_report(const RobotStationStatistics& s) {
  report::RobotStation r;
  r.set_sim_steps(s.sim_steps);
  r.set_late_steps(s.late_steps);
  r.set_resyncs(s.resyncs);
  r.set_contact_steps(s.contact_steps);
  r.set_guard_states(s.guard_states);
  r.set_max_lateness_ns(s.max_lateness_ns);
  r.set_mean_lateness_ns(s.mean_lateness_ns);
  r.set_commands_received(s.commands_received);
  r.set_commands_without_control(s.commands_without_control);
  r.set_commands_malformed(s.commands_malformed);
  r.set_commands_mode_mismatch(s.commands_mode_mismatch);
  r.set_commands_stale(s.commands_stale);
  r.set_commands_applied(s.commands_applied);
  r.set_commands_rejected(s.commands_rejected);
  r.set_arm_refused_floor(s.arm_refused_floor);
  r.set_arm_refused_base(s.arm_refused_base);
  r.set_arm_refused_scene(s.arm_refused_scene);
  r.set_arm_refused_last_seq(s.arm_refused_last_seq);
  r.set_seen_voxels(s.seen_voxels);
  r.set_seen_voxel_bytes(s.seen_voxel_bytes);
  r.set_seen_integrate_max_us(s.seen_integrate_max_us);
  r.set_arm_check_max_us(s.arm_check_max_us);
  r.set_arm_check_mean_us(s.arm_check_mean_us);
  r.set_arm_contact_steps(s.arm_contact_steps);
  r.set_tool_min_clearance_m(s.tool_min_clearance_m);
  r.set_states_sent(s.states_sent);
  r.set_scans_sent(s.scans_sent);
  r.set_scan_chunks_sent(s.scan_chunks_sent);
  r.set_send_failures(s.send_failures);
  r.set_depth_frames_sent(s.depth_frames_sent);
  r.set_depth_chunks_sent(s.depth_chunks_sent);
  r.set_depth_frames_skipped(s.depth_frames_skipped);
  r.set_depth_bytes_sent(s.depth_bytes_sent);
  r.set_mode_changes(s.mode_changes);
  r.set_estop_changes(s.estop_changes);
  r.set_requests_refused(s.requests_refused);
  r.set_estop(s.estop);
  r.set_estop_local(s.estop_local);
  r.set_mode(s.mode);
  r.set_safety(s.safety);
  rt::fill(r.mutable_control_timing(), s.control_timing);
  return r;
}

std::string to_log_fields(const RobotStationStatistics& s) {
  std::ostringstream os;
  os << "sim_steps=" << s.sim_steps << " late_steps=" << s.late_steps << " resyncs=" << s.resyncs
     << " contact_steps=" << s.contact_steps << " guard_states=" << s.guard_states
     << " max_lateness_us=" << s.max_lateness_ns / 1000 << " mean_lateness_us=" << s.mean_lateness_ns / 1000.0
     << " commands_received=" << s.commands_received << " commands_applied=" << s.commands_applied
     << " commands_rejected=" << s.commands_rejected << " arm_refused_floor=" << s.arm_refused_floor
     << " arm_refused_base=" << s.arm_refused_base << " arm_refused_scene=" << s.arm_refused_scene
     << " arm_refused_last_seq=" << s.arm_refused_last_seq << " seen_voxels=" << s.seen_voxels
     << " arm_check_max_us=" << s.arm_check_max_us << " arm_contact_steps=" << s.arm_contact_steps
     << " tool_min_clearance_m=" << s.tool_min_clearance_m
     << " commands_without_control=" << s.commands_without_control
     << " commands_malformed=" << s.commands_malformed << " commands_mode_mismatch=" << s.commands_mode_mismatch
     << " commands_stale=" << s.commands_stale
     << " states_sent=" << s.states_sent << " scans_sent=" << s.scans_sent
     << " scan_chunks_sent=" << s.scan_chunks_sent << " depth_frames_sent=" << s.depth_frames_sent
     << " depth_chunks_sent=" << s.depth_chunks_sent << " depth_frames_skipped=" << s.depth_frames_skipped
     << " depth_bytes_sent=" << s.depth_bytes_sent << " send_failures=" << s.send_failures
     << " mode_changes=" << s.mode_changes << " estop_changes=" << s.estop_changes
     << " requests_refused=" << s.requests_refused << " estop=" << s.estop << " estop_local=" << s.estop_local
     << " mode=" << s.mode
     << " safety=" << s.safety;
  return os.str();
}

std::string to_summary(const RobotStationStatistics& s) {
  std::ostringstream os;
  os << "robot (SIMULATED): " << s.sim_steps << " sim steps, " << s.late_steps << " late (>1 period), "
     << s.resyncs << " resyncs, lateness mean " << s.mean_lateness_ns / 1000.0 << " us max "
     << s.max_lateness_ns / 1000 << " us\n"
     << "  control loop: " << rt::to_string(s.control_timing) << "\n"
     << "  control loop worst ticks: " << rt::worst_ticks_text(s.control_timing.worst) << "\n"
     << "  safety: " << s.contact_steps << " steps touching the scene, " << s.guard_states
     << " states with the collision guard limiting the base\n"
     << "  commands: " << s.commands_received << " received, " << s.commands_applied << " applied, "
     << s.commands_rejected << " rejected by the robot, " << s.commands_without_control << " without control, "
     << s.commands_malformed << " malformed, " << s.commands_mode_mismatch << " wrong mode, " << s.commands_stale
     << " stale\n"
     << "  arm targets refused: " << s.arm_refused_floor << " into the floor, " << s.arm_refused_base
     << " into the base, " << s.arm_refused_scene << " into seen geometry; " << s.seen_voxels
     << " seen voxels, arm check max " << s.arm_check_max_us << " us\n"
     << "  arm (SIMULATION ONLY): " << s.arm_contact_steps << " steps touching the scene, tool clearance min "
     << s.tool_min_clearance_m << " m\n"
     << "  sent: " << s.states_sent << " states, " << s.scans_sent << " scans (" << s.scan_chunks_sent
     << " chunks), " << s.send_failures << " send failures\n"
     << "  session: " << s.mode_changes << " mode changes, " << s.estop_changes << " e-stop changes, "
     << s.requests_refused << " requests refused; e-stop " << (s.estop ? "engaged" : "released")
     << (s.estop_local ? " (at the robot)" : "") << "\n";
  return os.str();
}

RobotStation::RobotStation(asio::io_context& io, RobotServer& server, RobotStationOptions o)
    : io_(io), server_(server), o_(o), shared_(std::make_shared<Shared>()) {
  std::random_device rd;
  while (frame_epoch_ == 0) frame_epoch_ = (static_cast<uint64_t>(rd()) << 32) ^ rd();
  shared_->server = &server_;
  shared_->io = &io_;
}

RobotStation::~RobotStation() { stop(); }

std::optional<std::string> RobotStation::load(const config::RobotConfig& config, const std::string& scene_path) {
  if (running()) return "the station is running";
  if (o_.state_rate_hz == 0 || o_.state_rate_hz > 10000) return "state rate must be in 1..10000 Hz";
  if (auto err = robot_.load(config, scene_path)) return err;
  laser_on_ = config.laser().enabled();
  sonar_on_ = config.sonar().enabled();
  depth_on_ = config.depth_camera().enabled();
  if (depth_on_) {
    if (auto err = robot_.enable_depth_camera(depth_camera_params_from_config(config),
                                              SimulatedRobot::DepthCasting::kWorker))
      return err;
  }
  return std::nullopt;
}

bool RobotStation::start(std::string* error) {
  if (!robot_.loaded()) {
    *error = "robot station: no scene loaded";
    return false;
  }
  if (running() || attached_) {
    *error = "robot station: already started";
    return false;
  }
  if (auto why = rt::check_cpu(o_.control_thread.cpu)) {
    *error = "robot station: control thread cpu: " + *why;
    return false;
  }
  attached_ = true;
  const SharedPtr sh = shared_;

  server_.streams().on(wire::StreamMessage::kCommand,
                       [sh](const net::DatagramHeader& h, int64_t recv_ns, const wire::StreamMessage& m) {
                         ++sh->commands_received;
                         // The server only delivers datagrams of the authenticated
                         // session; that session must also hold control.
                         if (!sh->server->operator_in_control()) {
                           const uint64_t n = ++sh->commands_without_control;
                           if (is_power_of_two(n)) {
                             spdlog::warn("event=command_dropped why=no_control count={}", n);
                           }
                           return;
                         }
                         TimedCommand c;
                         if (auto err = from_wire(m.command(), h.seq, &c.command)) {
                           const uint64_t n = ++sh->commands_malformed;
                           if (is_power_of_two(n)) {
                             spdlog::warn("event=command_malformed count={} error=\"{}\"", n, *err);
                           }
                           return;
                         }
                         // Something on the path may hold commands and release
                         // them later: judge the command's age, not its arrival.
                         const net::MessageAge age = sh->server->message_age(m.command().stamp_ns(), recv_ns);
                         if (age.stale) {
                           const uint64_t n = ++sh->commands_stale;
                           if (is_power_of_two(n)) {
                             spdlog::warn("event=command_dropped why=stale age_ms={} known={} count={}",
                                          age.age_ns / 1'000'000, age.known, n);
                           }
                           return;
                         }
                         c.excess_age_ns = age.excess_ns;
                         sh->commands.publish(c);
                       });

  server_.on_session_frame(wire::SessionFrame::kModeChange, [sh](const wire::SessionFrame& f) {
    const wire::ModeChange& mc = f.mode_change();
    if (!sh->server->operator_in_control()) {
      refuse(*sh, mc.request_id(), "mode change without control");
      send_now(*sh, make_ack(mc.request_id(), false, "not the controlling operator"));
      return;
    }
    if (mc.mode() < wire::MODE_IDLE || mc.mode() > wire::MODE_EXPLORATION) {
      refuse(*sh, mc.request_id(), "unknown mode");
      send_now(*sh, make_ack(mc.request_id(), false, "unknown mode " + std::to_string(static_cast<int>(mc.mode()))));
      return;
    }
    Request r;
    r.kind = Request::Kind::kMode;
    r.mode = mc.mode();
    r.request_id = mc.request_id();
    queue_request(sh, std::move(r));
  });

  server_.on_session_frame(wire::SessionFrame::kEstop, [sh](const wire::SessionFrame& f) {
    const wire::EStop& e = f.estop();
    // Anyone authenticated may stop the robot; only the controller may release it.
    if (!e.engaged() && !sh->server->operator_in_control()) {
      refuse(*sh, e.request_id(), "e-stop release without control");
      send_now(*sh, make_ack(e.request_id(), false, "only the controlling operator may release the e-stop"));
      return;
    }
    Request r;
    r.kind = Request::Kind::kEStop;
    r.request_id = e.request_id();
    r.engaged = e.engaged();
    r.reason = net::printable_text(e.reason());
    queue_request(sh, std::move(r));
  });

  shared_->stop.store(false, std::memory_order_release);
  start_control_thread(thread_, [this] { run(); }, o_.control_thread, &shared_->rt_status, &wake_latency_fd_,
                       "");
  return true;
}

void RobotStation::local_estop(bool engaged, const std::string& reason) {
  Request r;
  r.kind = Request::Kind::kLocalEStop;
  r.engaged = engaged;
  r.reason = net::printable_text(reason);
  queue_request(shared_, std::move(r));
}

void RobotStation::stop() {
  shared_->stop.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  rt::release_cpu_wake_latency(wake_latency_fd_);
  wake_latency_fd_ = -1;
}

RobotStationStatistics RobotStation::statistics() const {
  const Shared& sh = *shared_;
  RobotStationStatistics s;
  s.sim_steps = sh.sim_steps.load();
  s.late_steps = sh.pacing.late_steps.load();
  s.contact_steps = sh.contact_steps.load();
  s.guard_states = sh.guard_states.load();
  s.resyncs = sh.pacing.resyncs.load();
  s.max_lateness_ns = sh.pacing.max_lateness_ns.load();
  s.mean_lateness_ns = sh.pacing.mean_lateness_ns();
  s.commands_received = sh.commands_received.load();
  s.commands_without_control = sh.commands_without_control.load();
  s.commands_malformed = sh.commands_malformed.load();
  s.commands_mode_mismatch = sh.commands_mode_mismatch.load();
  s.commands_stale = sh.commands_stale.load();
  s.commands_applied = sh.commands_applied.load();
  s.commands_rejected = sh.commands_rejected.load();
  s.arm_refused_floor = sh.arm_refused_floor.load();
  s.arm_refused_base = sh.arm_refused_base.load();
  s.arm_refused_scene = sh.arm_refused_scene.load();
  {
    std::lock_guard<std::mutex> lk(sh.state_mu);
    s.arm_refused_last_seq = sh.arm_refused_last_seq;
    s.seen_voxels = sh.seen.voxels;
    s.seen_voxel_bytes = sh.seen.memory_bytes;
    s.seen_integrate_max_us = sh.seen.max_integrate_us;
    s.arm_check_max_us = sh.seen.max_check_us;
    s.arm_check_mean_us = sh.seen.checks ? sh.seen.sum_check_us / static_cast<double>(sh.seen.checks) : 0.0;
    s.arm_contact_steps = sh.arm_contacts.contact_steps;
    s.tool_min_clearance_m = sh.arm_contacts.tool_min_clearance;
  }
  s.states_sent = sh.states_sent.load();
  s.scans_sent = sh.scans_sent.load();
  s.scan_chunks_sent = sh.scan_chunks_sent.load();
  s.send_failures = sh.send_failures.load();
  s.depth_frames_sent = sh.depth_frames_sent.load();
  s.depth_chunks_sent = sh.depth_chunks_sent.load();
  s.depth_frames_skipped = sh.depth_frames_skipped.load();
  s.depth_bytes_sent = sh.depth_bytes_sent.load();
  s.mode_changes = sh.mode_changes.load();
  s.estop_changes = sh.estop_changes.load();
  s.requests_refused = sh.requests_refused.load();
  s.estop = sh.estop.load();
  s.estop_local = sh.estop_local.load();
  s.mode = sh.mode.load();
  s.safety = sh.safety.load();
  s.control_timing = pacing_summary(sh.pacing, robot_.timestep_ns(), o_.late_wake_threshold_ns, sh.rt_status);
  return s;
}

RobotStateSim RobotStation::latest_state() const {
  std::lock_guard<std::mutex> lk(shared_->state_mu);
  return shared_->latest;
}

void RobotStation::run() {
  Shared& sh = *shared_;
  const SharedPtr sp = shared_;
  RobotServer& server = server_;
  const int64_t dt = robot_.timestep_ns();
  const int64_t state_period = std::max<int64_t>(1, 1'000'000'000 / static_cast<int64_t>(o_.state_rate_hz));

  ControlPacer pacer(dt, o_.max_catch_up_ns, o_.late_wake_threshold_ns, steady_now_ns());
  robot_.set_time_origin_ns(pacer.anchor_ns());
  int64_t next_state_ns = robot_.time_ns();
  wire::Mode session_mode = wire::MODE_UNSPECIFIED;
  wire::Mode exec_mode = wire::MODE_IDLE;  // mode of the last command applied
  uint64_t last_seq = 0;
  bool was_in_control = false;
  std::vector<Request> requests;
  // The e-stop has two sources: the operator's and the robot's own (local);
  // the robot is stopped while either is engaged, and each is released only
  // where it was engaged.
  bool remote_estop = false, local_estop = false;
  auto apply_estop = [&](const std::string& why) {
    const bool engaged = remote_estop || local_estop;
    const bool was = robot_.estop();
    robot_.set_estop(engaged);
    sh.estop.store(engaged);
    sh.estop_local.store(local_estop);
    if (was != engaged) ++sh.estop_changes;
    spdlog::warn("event=estop engaged={} local={} remote={} reason=\"{}\"", engaged, local_estop, remote_estop, why);
    // Report the state to the operator (who may not be the one who changed it).
    wire::SessionFrame rep;
    rep.mutable_estop()->set_engaged(engaged);
    rep.mutable_estop()->set_reason(why);
    post_frame(sp, std::move(rep));
  };
  SimViewFrame view_frame;  // the live view's buffers (swapped with the feed's)

  while (!sh.stop.load(std::memory_order_acquire)) {
    pacer.set_what("step");
    if (o_.realtime) {
      if (const int64_t late = pacer.wait(sh.pacing); late > 0) {
        robot_.set_time_origin_ns(pacer.anchor_ns());  // skipped ahead: the clock jumps forward
        spdlog::warn("event=sim_resync late_ms={}", late / 1'000'000);
      }
    }

    // Link and control first: a request or command must see the current state.
    const bool link_up = server.link_up();
    const bool in_control = link_up && server.operator_in_control();
    robot_.set_operator_in_control(in_control);
    robot_.set_link_lost(!link_up);
    if (!in_control && was_in_control) {
      session_mode = wire::MODE_UNSPECIFIED;
      sh.mode.store(session_mode);
    }
    was_in_control = in_control;

    // Session requests (never block on the network thread's lock).
    if (sh.req_mu.try_lock()) {
      requests.swap(sh.requests);
      sh.req_mu.unlock();
    }
    for (const Request& r : requests) {
      if (r.kind == Request::Kind::kMode) {
        if (!in_control) {
          refuse(sh, r.request_id, "mode change without control");
          post_frame(sp, make_ack(r.request_id, false, "not the controlling operator"));
          continue;
        }
        if (r.mode != exec_mode) {
          // Stop what the old mode was doing until a command of the new one
          // (the robot's own neutral command: it re-arms nothing).
          robot_.stop_commanded_motion(last_seq);
          exec_mode = wire::MODE_IDLE;
        }
        if (r.mode != session_mode) ++sh.mode_changes;
        session_mode = r.mode;
        sh.mode.store(session_mode);
        spdlog::info("event=mode_change mode={} request_id={}", wire::Mode_Name(r.mode), r.request_id);
        post_frame(sp, make_ack(r.request_id, true, "mode " + wire::Mode_Name(r.mode)));
      } else if (r.kind == Request::Kind::kLocalEStop) {
        if (r.engaged == local_estop) continue;
        local_estop = r.engaged;
        apply_estop((r.engaged ? "engaged at the robot: " : "released at the robot: ") + r.reason);
      } else {
        if (!r.engaged && !in_control) {
          refuse(sh, r.request_id, "e-stop release without control");
          post_frame(sp, make_ack(r.request_id, false, "only the controlling operator may release the e-stop"));
          continue;
        }
        if (!r.engaged && local_estop) {
          refuse(sh, r.request_id, "e-stop engaged at the robot");
          post_frame(sp, make_ack(r.request_id, false, "the e-stop is engaged at the robot: only the robot can release it"));
          continue;
        }
        post_frame(sp, make_ack(r.request_id, true, r.engaged ? "e-stop engaged" : "e-stop released"));
        if (r.engaged != remote_estop) {
          remote_estop = r.engaged;
          apply_estop((r.engaged ? "engaged by operator: " : "released by operator: ") + r.reason);
        }
      }
    }
    requests.clear();

    // The newest command (older ones were superseded in the mailbox).
    if (const TimedCommand* tc = sh.commands.take()) {
      const BaseArmCommand* c = &tc->command;
      if (!in_control) {
        ++sh.commands_without_control;  // arrived before control or the link was lost
      } else if (session_mode != wire::MODE_UNSPECIFIED && c->mode != session_mode) {
        const uint64_t n = ++sh.commands_mode_mismatch;
        if (is_power_of_two(n)) {
          spdlog::warn("event=command_dropped why=mode_mismatch mode={} session_mode={} count={}",
                       wire::Mode_Name(c->mode), wire::Mode_Name(session_mode), n);
        }
      } else if (auto err = robot_.set_command(*c, robot_.time_ns() - tc->excess_age_ns)) {
        const uint64_t n = ++sh.commands_rejected;
        const SimulatedRobot::ArmRefusals ar = robot_.arm_refusals();
        sh.arm_refused_floor.store(ar.floor);
        sh.arm_refused_base.store(ar.base);
        sh.arm_refused_scene.store(ar.scene);
        if (is_power_of_two(n)) spdlog::warn("event=command_rejected count={} error=\"{}\"", n, *err);
      } else {
        ++sh.commands_applied;
        exec_mode = c->mode;
        last_seq = c->seq;
      }
    }

    robot_.step(1);
    pacer.stepped();
    sh.sim_steps.fetch_add(1, std::memory_order_relaxed);
    if (robot_.robot_contacts_sim() > 0) sh.contact_steps.fetch_add(1, std::memory_order_relaxed);

    // Streams go out while the link is up: the peer's endpoint is known
    // (learned from its datagrams) and someone is listening.
    const bool streaming = link_up;
    const int64_t now = robot_.time_ns();
    if (now >= next_state_ns) {
      next_state_ns += state_period;
      if (next_state_ns <= now) next_state_ns = now + state_period;  // after a resync
      const RobotStateSim st = robot_.state();
      {
        const SeenVoxelsStats seen = robot_.seen_voxels_stats();
        const SimulatedRobot::ArmContactStats ac = robot_.arm_contacts_sim();
        std::lock_guard<std::mutex> lk(sh.state_mu);
        sh.latest = st;
        sh.seen = seen;
        sh.arm_contacts = ac;
        sh.arm_refused_last_seq = st.last_refused_seq;
      }
      sh.safety.store(st.safety);
      pacer.set_what("state");
      if (view_ && view_->due(now)) {
        robot_.view_frame_sim(&view_frame);
        view_frame.state = st;
        view_frame.link_up = link_up;
        view_frame.in_control = in_control;
        view_->publish(view_frame);
      }
      if (st.safety & wire::SAFETY_COLLISION_GUARD) sh.guard_states.fetch_add(1, std::memory_order_relaxed);
      if (streaming) {
        wire::StreamMessage m;
        to_wire(st, m.mutable_robot_state());
        m.mutable_robot_state()->set_frame_epoch(frame_epoch_);
        asio::post(io_, [sp, m = std::move(m)] {
          Shared& s = *sp;
          if (!s.server->link_up()) return;
          if (s.server->streams().send(m)) {
            ++s.states_sent;
          } else {
            ++s.send_failures;
          }
        });
      }
    }

    std::vector<RangeScanData> scans = robot_.take_scans();
    if (!scans.empty()) pacer.set_what("scan");
    if (view_) view_->publish_scans(scans);
    if (streaming) {
      for (const RangeScanData& scan : scans) {
        std::vector<wire::StreamMessage> msgs;
        for (wire::RangeScan& chunk : to_wire_chunks(scan, o_.max_scan_payload_bytes)) {
          chunk.set_frame_epoch(frame_epoch_);
          msgs.emplace_back();
          *msgs.back().mutable_range_scan() = std::move(chunk);
        }
        asio::post(io_, [sp, msgs = std::move(msgs)] {
          Shared& s = *sp;
          if (!s.server->link_up()) return;
          bool all = true;
          for (const wire::StreamMessage& m : msgs) {
            if (s.server->streams().send(m)) {
              ++s.scan_chunks_sent;
            } else {
              ++s.send_failures;
              all = false;
            }
          }
          if (all) ++s.scans_sent;
        });
      }
    }

    if (depth_on_) {
      std::vector<mapping::DepthImage> frames = robot_.take_depth_images();
      sh.depth_frames_skipped.store(robot_.depth_frames_skipped(), std::memory_order_relaxed);
      // Only the newest frame is worth sending; the chunks are cut on the
      // network thread (protobuf work off the simulation thread).
      if (streaming && !frames.empty()) {
        asio::post(io_, [sp, img = std::move(frames.back()), epoch = frame_epoch_] {
          Shared& s = *sp;
          if (!s.server->link_up()) return;
          std::vector<wire::DepthChunk> chunks;
          if (auto err = mapping::encode_depth_chunks(img, "depth", mapping::DepthStreamParams{}, &chunks)) {
            spdlog::warn("event=depth_encode_failed error=\"{}\"", *err);
            return;
          }
          bool all = true;
          wire::StreamMessage m;
          for (wire::DepthChunk& c : chunks) {
            c.set_frame_epoch(epoch);
            *m.mutable_depth_chunk() = std::move(c);
            if (s.server->streams().send(m)) {
              ++s.depth_chunks_sent;
              s.depth_bytes_sent += m.ByteSizeLong();
            } else {
              ++s.send_failures;
              all = false;
            }
          }
          if (all) ++s.depth_frames_sent;
        });
      }
    }
    if (o_.realtime) pacer.record(sh.pacing);
  }
}

}  // namespace hemm::robot
