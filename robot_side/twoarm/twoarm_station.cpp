#include "robot_side/twoarm/twoarm_station.h"

#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <functional>
#include <mutex>
#include <random>
#include <iomanip>
#include <sstream>

#include "common/clock/steady_clock.h"
#include "common/concurrency/newest_mailbox.h"
#include "common/haptics/passivity/tdpa_wire.h"
#include "common/mapping/depth_stream.h"
#include "common/net/station_cli.h"
#include "common/sim/mujoco_owner.h"
#include "config_robot.pb.h"
#include "report.pb.h"
#include "robot_side/sim/depth_camera.h"
#include "robot_side/sim/mujoco_ray_caster.h"
#include "robot_side/sim/sim_contact.h"
#include "robot_side/sim/simulated_robot.h"
#include "robot_side/station/control_pacer.h"

namespace hemm::twoarm {

namespace {

// The first time, then at every doubling: a flood does not flood the log.
bool twoarm_log_count(uint64_t n) { return std::has_single_bit(n); }

// SIMULATION ONLY: the live view's frame, on the control thread (fixed-size
// copies only): the first kMaxContacts contacts in MuJoCo's order, and the
// count of all of them.
void fill_view_frame(const WorkbenchSim& sim, const TwoArmSnapshot& snap, const TaskTruthData* judged, bool link_up,
                     bool in_control, int64_t now_ns, robot::TwoArmViewFrame& f) noexcept {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  f.t_ns = now_ns;
  f.nq = m->nq;  // <= kMaxQpos: attach_view checked
  std::copy(d->qpos, d->qpos + m->nq, f.qpos.begin());
  f.ncontacts = 0;
  f.contacts_seen = d->ncon;
  for (int i = 0; i < d->ncon && f.ncontacts < robot::TwoArmViewFrame::kMaxContacts; ++i)
    if (robot::sim_contact(m, d, i, &f.contacts[static_cast<std::size_t>(f.ncontacts)])) ++f.ncontacts;
  f.snapshot = snap;
  f.link_up = link_up;
  f.in_control = in_control;
  f.has_task = judged != nullptr;
  if (judged != nullptr) {
    f.task = judged->last;
    f.lifted = judged->lifted;
    f.dropped = judged->dropped;
  }
}

wire::SessionFrame twoarm_ack(uint64_t request_id, bool ok, const std::string& reason) {
  wire::SessionFrame f;
  auto* a = f.mutable_ack();
  a->set_request_id(request_id);
  a->set_ok(ok);
  a->set_reason(reason);
  return f;
}

// A scene's geoms the depth worker's job buffer holds (workbench.xml: 51).
constexpr int kTwoArmMaxGeoms = 1024;
constexpr int64_t kStatePollNs = 1'000'000;  // the network thread looks for a new snapshot this often

// SIMULATION ONLY: one truth-trace row from the judge's sample and the robot.
void fill_truth_row(const TaskTruthSample& s, const TwoArmRobot& robot, TruthTraceRow& row) noexcept {
  row.t_s = s.t_s;
  row.clock_s = 1e-9 * static_cast<double>(robot.time_ns());
  for (std::size_t a = 0; a < kArms; ++a) {
    const Eigen::Isometry3d G = robot.sim().grasp_site_A(a == 0 ? Side::kRight : Side::kLeft);
    const Eigen::Isometry3d& T = robot.active_targets().T_A_G[a];
    row.G_A[a] = G.translation();
    row.target_A[a] = T.translation();
    row.G_rot_A[a] = rotation_vector(G.linear());
    row.target_rot_A[a] = rotation_vector(T.linear());
    row.force_A[a] = s.gripper_force_A[a];
    row.squeeze_N[a] = s.hand_squeeze_N[a];
    row.pads_on_object[a] = s.pads_on_object[a];
  }
  row.object_env_N = s.object_env_force_N;
  row.on_start = s.on_start_support;
  row.on_goal = s.on_goal_support;
  row.on_other = s.on_other;
  row.goal_xy_err_m = s.goal_xy_err_m;
  row.goal_z_err_m = s.goal_z_err_m;
  row.tilt_rad = s.tilt_rad;
}

}  // namespace

TwoArmRobotOptions two_arm_robot_options(const config::RobotConfig& c) {
  const config::TwoArmConfig& t = c.twoarm();
  TwoArmRobotOptions o;
  for (ImpedanceParams& p : o.control.arm) {
    p.stiffness_N_per_m = t.stiffness_n_per_m();
    p.damping_Ns_per_m = t.damping_ns_per_m();
    p.rot_stiffness_Nm_per_rad = t.rot_stiffness_nm_per_rad();
    p.rot_damping_Nms_per_rad = t.rot_damping_nms_per_rad();
    p.force_limit_N = t.force_limit_n();
    p.torque_limit_Nm = t.torque_limit_nm();
    p.null_stiffness_Nm_per_rad = t.null_stiffness_nm_per_rad();
    p.null_damping_Nms_per_rad = t.null_damping_nms_per_rad();
    p.joint_limit_margin_rad = t.joint_limit_margin_rad();
  }
  o.control.avoid = t.avoidance();
  o.control.avoidance.activation_m = t.avoidance_activation_m();
  o.control.avoidance.stiffness_N_per_m = t.avoidance_stiffness_n_per_m();
  o.limits.max_target_jump_m = t.max_target_jump_m();
  o.limits.reach_margin_m = t.reach_margin_m();
  o.limits.reach_margin_rad = t.reach_margin_rad();
  o.control.gripper.max_speed_mps = t.gripper_approach_speed_mps();
  o.control.relative_stiffness_ratio = t.relative_stiffness_ratio();
  o.watchdog_ns = static_cast<int64_t>(c.safety().watchdog_ms()) * 1'000'000;
  o.pc_mode = haptics::tdpa::pc_mode_from(t.passivity());
  o.direct_feedback_measured = t.direct_feedback_measured();
  o.direct_twist_hold_ns = std::isfinite(t.direct_twist_hold_ms())
                               ? static_cast<int64_t>(std::llround(t.direct_twist_hold_ms() * 1e6))
                               : 0;  // refused by TwoArmRobot
  return o;
}

struct TwoArmStation::Shared {
  // A command validated on the network thread, for the control thread.
  struct TimedArmsCommand {
    ValidatedArmsCommand command;
    uint64_t seq = 0;
    int64_t excess_age_ns = 0;  // held on the path this much longer than the fastest: the watchdog gets that less
  };
  robot::RobotServer* server = nullptr;
  asio::io_context* io = nullptr;
  TwoArmModel model;  // a copy: handlers may outlive the station
  ArmsCommandLimits limits;
  uint64_t frame_epoch = 0;
  std::atomic<bool> stop{false};

  NewestMailbox<TimedArmsCommand> commands;  // network thread -> control thread
  NewestMailbox<TwoArmSnapshot> states;      // control thread -> network thread
  mutable NewestMailbox<TwoArmTruthSim> truth;  // control thread -> truth_sim() (SIMULATION ONLY)
  mutable std::mutex truth_mu;               // the readers' side only: the control thread never takes it
  mutable TwoArmTruthSim truth_latest;       // guarded by truth_mu
  mutable bool have_truth = false;           // guarded by truth_mu
  // SIMULATION ONLY: the task judge's accumulated data (control thread -> statistics()).
  mutable NewestMailbox<TaskTruthData> task_data;
  mutable std::mutex task_mu;        // the readers' side only
  mutable TaskTruthData task_latest;  // guarded by task_mu
  mutable bool have_task = false;     // guarded by task_mu

  // Network thread only.
  TwoArmSnapshot latest;
  bool have_latest = false;
  wire::StreamMessage msg;
  std::unique_ptr<asio::steady_timer> poll;
  int64_t next_poll_ns = 0;
  bool estop_reported = false;
  rt::LogHistogram validate_ns;  // written on the network thread
  // The operator's newest energies taken (a command whose energy went down is
  // refused), reset when a new controlling session begins (control_epoch).
  PeerEnergyRecord energy_record;
  uint64_t energy_seq = 0;
  uint32_t energy_epoch = 0;

  // Set by the network thread (and local_estop), read by the control thread.
  std::atomic<bool> remote_estop{false}, local_estop{false};
  std::atomic<int> session_mode{wire::MODE_UNSPECIFIED};
  std::atomic<uint32_t> mode_epoch{0};
  std::atomic<int> exec_mode{wire::MODE_IDLE};  // the control thread's: mode of the last command applied
  std::atomic<uint32_t> control_epoch{0};       // the control thread's: +1 each time an operator takes control

  // The newest snapshot's direct-mode figures (network thread writes, statistics() reads).
  mutable std::mutex passivity_mu;
  std::array<haptics::tdpa::ArmPortSummary, kArms> passivity{};  // guarded by passivity_mu
  uint64_t direct_commands = 0, direct_stale_ticks = 0, peer_old = 0, peer_refused = 0;  // guarded by passivity_mu

  std::atomic<uint64_t> sim_steps{0};
  robot::PacingCounters pacing;  // the control loop's (realtime pacing)
  std::atomic<uint64_t> commands_received{0}, commands_without_control{0}, commands_stale{0},
      commands_mode_mismatch{0}, commands_refused{0}, commands_accepted{0}, commands_applied{0};
  std::array<std::atomic<uint64_t>, kArmsRefusalReasons> refused_by_reason{};
  std::atomic<int> last_refusal{0};
  std::atomic<uint64_t> last_refused_seq{0};
  std::atomic<uint32_t> last_refused_index{0};
  mutable std::mutex detail_mu;
  std::string last_refusal_detail;  // guarded by detail_mu (network thread writes, statistics() reads)
  uint64_t targets_at_reach_edge = 0;                         // guarded by detail_mu
  double max_reach_error_m = 0.0, max_reach_error_rad = 0.0;  // guarded by detail_mu
  std::atomic<uint64_t> states_sent{0}, send_failures{0};
  std::atomic<uint64_t> depth_frames_sent{0}, depth_chunks_sent{0}, depth_bytes_sent{0};
  std::atomic<uint64_t> mode_changes{0}, estop_changes{0}, requests_refused{0};
  std::atomic<uint32_t> safety{0};
  std::atomic<bool> armed{false}, following{false};
  rt::RealtimeStatus rt_status;
};

// The SIMULATED head depth camera, cast on its own thread: one frame is
// thousands of mj_ray calls, which would make the 1 kHz step late. The
// control thread copies the geoms' poses of its step into the job buffer
// (mj_ray reads only geom_xpos / geom_xmat and the const model) and
// hands it over with one atomic store; a frame due while the last is still
// being cast is skipped, never waited for.
struct TwoArmStation::DepthWorker {
  enum Phase : int { kIdle = 0, kJob = 1, kStop = 2 };
  const mjModel* m = nullptr;
  sim::MjDataPtr d;
  robot::SimDepthCameraParams params;
  int camera = -1;
  std::mt19937_64 rng;
  std::function<void(mapping::DepthImage&&)> deliver;  // worker thread
  // The job (written by the control thread while kIdle, read by the worker while kJob).
  std::array<double, 3 * kTwoArmMaxGeoms> xpos{};
  std::array<double, 9 * kTwoArmMaxGeoms> xmat{};
  int64_t stamp_ns = 0;
  uint32_t cloud_id = 0;
  Eigen::Isometry3d T_A_S = Eigen::Isometry3d::Identity();
  std::atomic<int> phase{kIdle};
  std::atomic<uint64_t> skipped{0};
  std::thread thread;

  DepthWorker(const mjModel* model, const robot::SimDepthCameraParams& p, int cam, uint64_t seed)
      : m(model), d(sim::make_data(model)), params(p), camera(cam), rng(seed) {}
  ~DepthWorker() { halt(); }
  void start() { thread = std::thread([this] { run(); }); }
  void halt() {
    phase.store(kStop, std::memory_order_release);
    phase.notify_one();
    if (thread.joinable()) thread.join();
  }

  // Control thread: allocation-free, never blocks.
  void submit(const mjData* src, int64_t stamp, uint32_t id) noexcept {
    if (phase.load(std::memory_order_acquire) != kIdle) {
      skipped.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    std::copy_n(src->geom_xpos, 3 * m->ngeom, xpos.data());
    std::copy_n(src->geom_xmat, 9 * m->ngeom, xmat.data());
    // MuJoCo's camera looks along its -z with y up; the optical frame S
    // looks along z with y down.
    Eigen::Matrix3d R_A_cam;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R_A_cam(r, c) = src->cam_xmat[9 * camera + 3 * r + c];
    T_A_S.linear() = R_A_cam * Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
    T_A_S.translation() = Eigen::Vector3d(src->cam_xpos[3 * camera], src->cam_xpos[3 * camera + 1],
                                          src->cam_xpos[3 * camera + 2]);
    stamp_ns = stamp;
    cloud_id = id;
    phase.store(kJob, std::memory_order_release);
    phase.notify_one();
  }

  void run() {
    for (;;) {
      phase.wait(kIdle, std::memory_order_acquire);
      if (phase.load(std::memory_order_acquire) == kStop) return;
      std::copy_n(xpos.data(), 3 * m->ngeom, d->geom_xpos);
      std::copy_n(xmat.data(), 9 * m->ngeom, d->geom_xmat);
      robot::MujocoRayCaster caster(m, d.get());
      mapping::DepthImage img = robot::simulate_depth_image(params, caster, T_A_S, rng);
      img.stamp_ns = stamp_ns;
      img.cloud_id = cloud_id;
      img.T_W_S = T_A_S;  // A = W; the head is rigid on the torso: no estimate to err
      img.T_W_S_truth = T_A_S;
      int expected = kJob;
      if (deliver) deliver(std::move(img));
      phase.compare_exchange_strong(expected, kIdle, std::memory_order_acq_rel);
    }
  }
};

namespace {

using SharedPtr = std::shared_ptr<TwoArmStation::Shared>;

void twoarm_refuse_request(TwoArmStation::Shared& sh, uint64_t request_id, const std::string& why) {
  ++sh.requests_refused;
  spdlog::warn("event=request_refused request_id={} reason=\"{}\"", request_id, why);
  sh.server->send_session_frame(twoarm_ack(request_id, false, why));
}

// Network thread: count, log and report an e-stop source that changed.
void twoarm_estop_changed(TwoArmStation::Shared& sh, const std::string& why) {
  const bool engaged = sh.remote_estop.load() || sh.local_estop.load();
  if (engaged != sh.estop_reported) ++sh.estop_changes;
  sh.estop_reported = engaged;
  spdlog::warn("event=estop engaged={} local={} remote={} reason=\"{}\"", engaged, sh.local_estop.load(),
               sh.remote_estop.load(), why);
  wire::SessionFrame rep;
  rep.mutable_estop()->set_engaged(engaged);
  rep.mutable_estop()->set_reason(why);
  sh.server->send_session_frame(rep);
}

// Network thread: the newest snapshot, if new, and its ArmsState sent.
void twoarm_pump_states(TwoArmStation::Shared& sh) {
  const TwoArmSnapshot* s = sh.states.take();
  if (s == nullptr) return;
  sh.latest = *s;
  sh.have_latest = true;
  {
    std::lock_guard<std::mutex> lk(sh.passivity_mu);
    sh.peer_old = sh.peer_refused = 0;
    for (std::size_t i = 0; i < kArms; ++i) {
      sh.passivity[i] = haptics::tdpa::summarize(sh.latest.port[i]);
      sh.peer_old += sh.latest.port[i].peer_old;
      sh.peer_refused += sh.latest.port[i].peer_refused;
    }
    sh.direct_commands = sh.latest.direct_commands;
    sh.direct_stale_ticks = sh.latest.direct_stale_ticks;
  }
  if (!sh.server->link_up()) return;
  wire::ArmsState* st = sh.msg.mutable_arms_state();
  to_wire(sh.model, sh.latest, st);
  st->set_mode(static_cast<wire::Mode>(sh.exec_mode.load(std::memory_order_relaxed)));
  st->set_frame_epoch(sh.frame_epoch);
  // The refusals are the network thread's: it validates.
  st->set_refusals(sh.commands_refused.load(std::memory_order_relaxed));
  st->set_last_refusal(static_cast<wire::ArmsRefusalReason>(sh.last_refusal.load(std::memory_order_relaxed)));
  st->set_last_refused_seq(sh.last_refused_seq.load(std::memory_order_relaxed));
  st->set_last_refused_index(sh.last_refused_index.load(std::memory_order_relaxed));
  if (sh.server->streams().send(sh.msg)) {
    ++sh.states_sent;
  } else {
    ++sh.send_failures;
  }
}

void twoarm_arm_poll(const SharedPtr& sh) {
  if (sh->stop.load(std::memory_order_acquire)) return;
  sh->next_poll_ns += kStatePollNs;
  const int64_t now = steady_now_ns();
  if (sh->next_poll_ns < now) sh->next_poll_ns = now;  // behind: no burst
  sh->poll->expires_after(std::chrono::nanoseconds(sh->next_poll_ns - now));
  sh->poll->async_wait([sh](const asio::error_code& ec) {
    if (ec) return;
    twoarm_pump_states(*sh);
    twoarm_arm_poll(sh);
  });
}

// Network thread: an ArmsCommand datagram of the authenticated session.
void twoarm_on_command(TwoArmStation::Shared& sh, const net::DatagramHeader& h, int64_t recv_ns,
                       const wire::StreamMessage& m) {
  ++sh.commands_received;
  if (!sh.server->operator_in_control() || !sh.server->link_up()) {
    const uint64_t n = ++sh.commands_without_control;
    if (twoarm_log_count(n)) spdlog::warn("event=arms_command_dropped why=no_control count={}", n);
    return;
  }
  const wire::ArmsCommand& cmd = m.arms_command();
  const net::MessageAge age = sh.server->message_age(cmd.stamp_ns(), recv_ns);
  if (age.stale) {
    const uint64_t n = ++sh.commands_stale;
    if (twoarm_log_count(n))
      spdlog::warn("event=arms_command_dropped why=stale age_ms={} known={} count={}", age.age_ns / 1'000'000,
                   age.known, n);
    return;
  }
  twoarm_pump_states(sh);  // validate against the newest readings
  if (!sh.have_latest) {
    // The control thread has not stepped yet: nothing to check the jump against.
    ++sh.commands_without_control;
    return;
  }
  TwoArmStation::Shared::TimedArmsCommand& tc = sh.commands.back();
  const int64_t t0 = steady_now_ns();
  std::optional<ArmsRefusal> r = validate_arms_command(sh.model, sh.limits, cmd, sh.latest.readings, &tc.command);
  sh.validate_ns.record(steady_now_ns() - t0);
  // The energies: a new controlling session starts from zero; a newer
  // command with less energy than the last taken is refused (an older one,
  // reordered, carries less by nature: the control thread ignores it).
  if (const uint32_t e = sh.control_epoch.load(std::memory_order_acquire); e != sh.energy_epoch) {
    sh.energy_epoch = e;
    sh.energy_record = PeerEnergyRecord{};
    sh.energy_seq = 0;
  }
  const bool newest = h.seq > sh.energy_seq;
  if (!r && newest) r = check_energy_not_decreasing(tc.command, sh.energy_record);
  if (r) {
    const uint64_t n = ++sh.commands_refused;
    const int reason = static_cast<int>(r->reason);
    if (reason >= 0 && reason < kArmsRefusalReasons) ++sh.refused_by_reason[static_cast<std::size_t>(reason)];
    sh.last_refusal.store(reason);
    sh.last_refused_seq.store(h.seq);
    sh.last_refused_index.store(r->index);
    if (twoarm_log_count(n))
      spdlog::warn("event=arms_command_refused reason={} index={} count={} detail=\"{}\"",
                   wire::ArmsRefusalReason_Name(r->reason), r->index, n, r->detail);
    std::lock_guard<std::mutex> lk(sh.detail_mu);
    sh.last_refusal_detail = std::move(r->detail);
    return;
  }
  if (const ValidatedArmsCommand& v = tc.command; v.at_reach_edge[0] || v.at_reach_edge[1]) {
    std::lock_guard<std::mutex> lk(sh.detail_mu);
    for (std::size_t i = 0; i < kArms; ++i) {
      if (!v.at_reach_edge[i]) continue;
      ++sh.targets_at_reach_edge;
      sh.max_reach_error_m = std::max(sh.max_reach_error_m, v.reach_error_m[i]);
      sh.max_reach_error_rad = std::max(sh.max_reach_error_rad, v.reach_error_rad[i]);
    }
  }
  if (newest) {
    note_energy(tc.command, &sh.energy_record);
    sh.energy_seq = h.seq;
  }
  tc.seq = h.seq;
  tc.excess_age_ns = age.excess_ns;
  sh.commands.publish();
}

}  // namespace

report::TwoArmStation to_report(const TwoArmStationStatistics& s) {
  report::TwoArmStation r;
  r.set_sim_steps(s.sim_steps);
  r.set_late_steps(s.late_steps);
  r.set_resyncs(s.resyncs);
  r.set_max_lateness_ns(s.max_lateness_ns);
  r.set_mean_lateness_ns(s.mean_lateness_ns);
  r.set_commands_received(s.commands_received);
  r.set_commands_without_control(s.commands_without_control);
  r.set_commands_stale(s.commands_stale);
  r.set_commands_mode_mismatch(s.commands_mode_mismatch);
  r.set_commands_refused(s.commands_refused);
  r.set_commands_accepted(s.commands_accepted);
  r.set_commands_applied(s.commands_applied);
  r.set_refused_nonfinite(s.refused_by_reason[wire::ARMS_REFUSAL_NONFINITE]);
  r.set_refused_unknown_arm(s.refused_by_reason[wire::ARMS_REFUSAL_UNKNOWN_ARM]);
  r.set_refused_unknown_gripper(s.refused_by_reason[wire::ARMS_REFUSAL_UNKNOWN_GRIPPER]);
  r.set_refused_bad_pose(s.refused_by_reason[wire::ARMS_REFUSAL_BAD_POSE]);
  r.set_refused_out_of_reach(s.refused_by_reason[wire::ARMS_REFUSAL_OUT_OF_REACH]);
  r.set_refused_gripper_range(s.refused_by_reason[wire::ARMS_REFUSAL_GRIPPER_RANGE]);
  r.set_last_refusal(wire::ArmsRefusalReason_Name(static_cast<wire::ArmsRefusalReason>(s.last_refusal)));
  r.set_last_refused_seq(s.last_refused_seq);
  r.set_last_refused_index(s.last_refused_index);
  r.set_last_refusal_detail(s.last_refusal_detail);
  r.set_targets_at_reach_edge(s.targets_at_reach_edge);
  r.set_max_reach_error_m(s.max_reach_error_m);
  r.set_max_reach_error_rad(s.max_reach_error_rad);
  rt::fill(r.mutable_validate(), s.validate);
  rt::fill(r.mutable_control_compute(), s.control_compute);
  rt::fill(r.mutable_control_timing(), s.control_timing);
  r.set_states_sent(s.states_sent);
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
  r.set_armed(s.armed);
  r.set_following(s.following);
  for (std::size_t i = 0; i < kArms; ++i) {
    const haptics::tdpa::ArmPortSummary& p = s.passivity[i];
    report::TwoArmPassivityPort* o = r.add_passivity();
    o->set_index(static_cast<uint32_t>(i));
    o->set_energy_in_j(p.in_J);
    o->set_energy_out_j(p.out_J);
    o->set_peer_energy_in_j(p.peer_in_J);
    o->set_dissipated_j(p.dissipated_J);
    o->set_min_margin_j(p.min_margin_J);
    o->set_pc_active_ticks(p.pc_active_ticks);
    o->set_pc_on(s.passivity_controller);
  }
  r.set_refused_passivity(s.refused_by_reason[wire::ARMS_REFUSAL_PASSIVITY]);
  r.set_direct_commands(s.direct_commands);
  r.set_direct_stale_ticks(s.direct_stale_ticks);
  r.set_passivity_peer_old(s.passivity_peer_old);
  r.set_passivity_peer_refused(s.passivity_peer_refused);
  if (s.task_judged) {
    const TaskVerdict& v = s.task_verdict;
    report::TwoArmTaskVerdict* t = r.mutable_task();
    t->set_task(to_string(s.task));
    t->set_success(v.success);
    t->set_why(v.why);
    t->set_goal(v.goal);
    t->set_dropped(v.dropped);
    t->set_forces_ok(v.forces_ok);
    t->set_completion_s(v.completion_s);
    for (std::size_t a = 0; a < kArms; ++a) {
      t->add_wrist_peak_n(v.wrist_peak_N[a]);
      t->add_wrist_peak_t_s(v.wrist_peak_t_s[a]);
      t->add_wrist_rms_n(v.wrist_rms_N[a]);
      t->add_hand_squeeze_peak_n(v.hand_squeeze_peak_N[a]);
      t->add_carried(v.carried[a]);
    }
    t->set_object_env_peak_n(v.object_env_peak_N);
    t->set_object_env_peak_t_s(v.object_env_peak_t_s);
    t->set_squeeze_peak_n(v.squeeze_peak_N);
    t->set_goal_xy_err_m(v.end.goal_xy_err_m);
    t->set_goal_z_err_m(v.end.goal_z_err_m);
    t->set_depth_m(v.end.depth_m);
    t->set_axis_offset_m(v.end.axis_offset_m);
    t->set_tilt_rad(v.end.tilt_rad);
    t->set_ticks(s.task_ticks);
    t->set_lift_time_s(s.task_lift_time_s);
  }
  return r;
}

std::string to_log_fields(const TwoArmStationStatistics& s) {
  std::ostringstream os;
  os << "sim_steps=" << s.sim_steps << " late_steps=" << s.late_steps << " resyncs=" << s.resyncs
     << " max_lateness_us=" << s.max_lateness_ns / 1000 << " commands_received=" << s.commands_received
     << " commands_accepted=" << s.commands_accepted << " commands_applied=" << s.commands_applied
     << " commands_refused=" << s.commands_refused << " commands_stale=" << s.commands_stale
     << " commands_without_control=" << s.commands_without_control
     << " commands_mode_mismatch=" << s.commands_mode_mismatch << " states_sent=" << s.states_sent
     << " depth_frames_sent=" << s.depth_frames_sent << " depth_frames_skipped=" << s.depth_frames_skipped
     << " send_failures=" << s.send_failures << " control_compute_median_us=" << s.control_compute.median_us
     << " control_compute_p99_us=" << s.control_compute.p99_us << " estop=" << s.estop << " mode=" << s.mode
     << " safety=" << s.safety;
  return os.str();
}

std::string to_summary(const TwoArmStationStatistics& s) {
  std::ostringstream os;
  os << "two-arm robot (SIMULATED): " << s.sim_steps << " steps, " << s.late_steps << " late (>1 period), "
     << s.resyncs << " resyncs, lateness mean " << s.mean_lateness_ns / 1000.0 << " us max "
     << s.max_lateness_ns / 1000 << " us\n"
     << "  control loop: " << rt::to_string(s.control_timing) << "\n"
     << "  both arms' controllers per tick: median " << s.control_compute.median_us << " us, p99 "
     << s.control_compute.p99_us << " us, max " << s.control_compute.max_us << " us\n"
     << "  commands: " << s.commands_received << " received, " << s.commands_accepted << " accepted, "
     << s.commands_applied << " applied, " << s.commands_refused << " refused, " << s.commands_without_control
     << " without control, " << s.commands_stale << " stale, " << s.commands_mode_mismatch << " wrong mode\n"
     << "  refused by reason: nonfinite " << s.refused_by_reason[wire::ARMS_REFUSAL_NONFINITE] << ", unknown arm "
     << s.refused_by_reason[wire::ARMS_REFUSAL_UNKNOWN_ARM] << ", unknown gripper "
     << s.refused_by_reason[wire::ARMS_REFUSAL_UNKNOWN_GRIPPER] << ", bad pose "
     << s.refused_by_reason[wire::ARMS_REFUSAL_BAD_POSE] << ", out of reach "
     << s.refused_by_reason[wire::ARMS_REFUSAL_OUT_OF_REACH] << ", gripper range "
     << s.refused_by_reason[wire::ARMS_REFUSAL_GRIPPER_RANGE] << ", passivity "
     << s.refused_by_reason[wire::ARMS_REFUSAL_PASSIVITY] << "; validation median " << s.validate.median_us
     << " us, p99 " << s.validate.p99_us << " us\n"
     << "  sent: " << s.states_sent << " states, " << s.depth_frames_sent << " depth frames (" << s.depth_chunks_sent
     << " chunks, " << s.depth_frames_skipped << " skipped), " << s.send_failures << " send failures\n"
     << "  session: " << s.mode_changes << " mode changes, " << s.estop_changes << " e-stop changes, "
     << s.requests_refused << " requests refused; e-stop " << (s.estop ? "engaged" : "released")
     << (s.estop_local ? " (at the robot)" : "") << "\n"
     << "  direct mode: " << s.direct_commands << " twist commands, " << s.direct_stale_ticks
     << " stale-twist ticks; passivity controller " << (s.passivity_controller ? "on" : "off (observer only)") << "\n";
  for (std::size_t i = 0; i < kArms; ++i) {
    const haptics::tdpa::ArmPortSummary& p = s.passivity[i];
    os << "    arm " << i << " robot end: in " << p.in_J << " J, out " << p.out_J << " J, operator's in "
       << p.peer_in_J << " J, dissipated " << p.dissipated_J << " J, min margin " << p.min_margin_J << " J\n";
  }
  if (s.task_judged) {
    const TaskVerdict& v = s.task_verdict;
    os << "  task " << to_string(s.task) << " (SIMULATION ONLY, MuJoCo truth): " << (v.success ? "success" : "FAILED")
       << (v.success ? "" : " - " + v.why) << "; completion " << v.completion_s << " s, wrist peak right / left "
       << v.wrist_peak_N[0] << " / " << v.wrist_peak_N[1] << " N (at " << v.wrist_peak_t_s[0] << " / "
       << v.wrist_peak_t_s[1] << " s; in A " << v.wrist_peak_force_A[0].transpose() << " / "
       << v.wrist_peak_force_A[1].transpose() << " N), RMS " << v.wrist_rms_N[0] << " / " << v.wrist_rms_N[1] << " N, squeeze peak "
       << v.squeeze_peak_N << " N, object contact peak " << v.object_env_peak_N << " N (at " << v.object_env_peak_t_s
       << " s)\n";
  }
  return os.str();
}

TwoArmStation::TwoArmStation(asio::io_context& io, robot::RobotServer& server, TwoArmStationOptions o)
    : io_(io), server_(server), o_(o), shared_(std::make_shared<Shared>()) {
  std::random_device rd;
  while (frame_epoch_ == 0) frame_epoch_ = (static_cast<uint64_t>(rd()) << 32) ^ rd();
  shared_->server = &server_;
  shared_->io = &io_;
  shared_->frame_epoch = frame_epoch_;
}

TwoArmStation::~TwoArmStation() { stop(); }

int64_t TwoArmStation::timestep_ns() const { return robot_ ? robot_->timestep_ns() : 0; }

const TwoArmModel& TwoArmStation::model() const { return robot_->sim().model(); }

std::optional<std::string> TwoArmStation::load(const config::RobotConfig& config, const std::string& scene_path) {
  if (running() || attached_) return "the station is running";
  if (o_.state_rate_hz == 0 || o_.state_rate_hz > 10000) return "state rate must be in 1..10000 Hz";
  std::unique_ptr<TwoArmRobot> robot;
  try {
    robot = std::make_unique<TwoArmRobot>(scene_path, two_arm_robot_options(config));
  } catch (const std::exception& e) {
    return std::string(e.what());
  }
  std::unique_ptr<DepthWorker> depth;
  int period = 0;
  if (config.depth_camera().enabled()) {
    const config::DepthCameraConfig& dc = config.depth_camera();
    if (dc.has_mount() || dc.has_mast_x_m() || dc.has_mast_z_m() || dc.has_mast_pitch_deg())
      return "depth_camera: the two-arm robot's camera is the scene's head_depth camera; leave mount and mast_* unset";
    robot::SimDepthCameraParams p = robot::depth_camera_params_from_config(config);
    p.name = "head_depth";
    p.pan_tilt = false;
    p.mount_on_base = true;
    if (auto e = robot::check_params(p)) return "depth camera: " + *e;
    const mjModel* m = robot->sim().m();
    const int cam = mj_name2id(m, mjOBJ_CAMERA, "head_depth");
    if (cam < 0) return "scene '" + scene_path + "' has no camera head_depth";
    if (m->ngeom > kTwoArmMaxGeoms) return "scene has more than " + std::to_string(kTwoArmMaxGeoms) + " geoms";
    const double steps = 1e9 / p.rate_hz / static_cast<double>(robot->timestep_ns());
    period = std::max(1, static_cast<int>(std::lround(steps)));
    depth = std::make_unique<DepthWorker>(m, p, cam, config.sim().seed());
  }
  std::unique_ptr<const TaskTruthModel> judge;
  if (const std::string& task = config.twoarm().task(); !task.empty()) {
    const std::optional<Task> t = task_from_string(task);
    if (!t) return "twoarm.task '" + task + "': box, peg, bar or empty";
    TaskTruthParams tp;
    tp.wrist_force_limit_N = config.twoarm().force_limit_n();
    try {
      judge = std::make_unique<const TaskTruthModel>(make_task_truth_model(robot->sim(), *t, tp));
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
  }
  robot_ = std::move(robot);
  task_model_ = std::move(judge);
  depth_ = std::move(depth);
  depth_on_ = depth_ != nullptr;
  depth_period_steps_ = period;
  shared_->model = robot_->sim().model();
  shared_->limits = two_arm_robot_options(config).limits;
  return std::nullopt;
}

bool TwoArmStation::start(std::string* error) {
  if (!robot_) {
    *error = "two-arm station: no scene loaded";
    return false;
  }
  if (running() || attached_) {
    *error = "two-arm station: already started";
    return false;
  }
  if (auto why = rt::check_cpu(o_.control_thread.cpu)) {
    *error = "two-arm station: control thread cpu: " + *why;
    return false;
  }
  attached_ = true;
  const SharedPtr sh = shared_;

  server_.streams().on(wire::StreamMessage::kArmsCommand,
                       [sh](const net::DatagramHeader& h, int64_t recv_ns, const wire::StreamMessage& m) {
                         twoarm_on_command(*sh, h, recv_ns, m);
                       });
  server_.on_session_frame(wire::SessionFrame::kModeChange, [sh](const wire::SessionFrame& f) {
    const wire::ModeChange& mc = f.mode_change();
    if (!sh->server->operator_in_control()) return twoarm_refuse_request(*sh, mc.request_id(), "not the controlling operator");
    if (mc.mode() < wire::MODE_IDLE || mc.mode() > wire::MODE_EXPLORATION)
      return twoarm_refuse_request(*sh, mc.request_id(), "unknown mode " + std::to_string(static_cast<int>(mc.mode())));
    if (sh->session_mode.load() != mc.mode()) ++sh->mode_changes;
    sh->session_mode.store(mc.mode());
    sh->mode_epoch.fetch_add(1);
    spdlog::info("event=mode_change mode={} request_id={}", wire::Mode_Name(mc.mode()), mc.request_id());
    sh->server->send_session_frame(twoarm_ack(mc.request_id(), true, "mode " + wire::Mode_Name(mc.mode())));
  });
  server_.on_session_frame(wire::SessionFrame::kEstop, [sh](const wire::SessionFrame& f) {
    const wire::EStop& e = f.estop();
    // Anyone authenticated may stop the robot; only the controller may
    // release it, and not the robot's own e-stop.
    if (!e.engaged() && !sh->server->operator_in_control())
      return twoarm_refuse_request(*sh, e.request_id(), "only the controlling operator may release the e-stop");
    if (!e.engaged() && sh->local_estop.load())
      return twoarm_refuse_request(*sh, e.request_id(),
                                   "the e-stop is engaged at the robot: only the robot can release it");
    sh->server->send_session_frame(twoarm_ack(e.request_id(), true, e.engaged() ? "e-stop engaged" : "e-stop released"));
    if (sh->remote_estop.exchange(e.engaged()) != e.engaged())
      twoarm_estop_changed(*sh, (e.engaged() ? "engaged by operator: " : "released by operator: ") +
                                    net::printable_text(e.reason()));
  });

  if (depth_) {
    depth_->deliver = [sh](mapping::DepthImage&& img) {
      std::vector<wire::DepthChunk> chunks;
      if (auto err = mapping::encode_depth_chunks(img, "head_depth", mapping::DepthStreamParams{}, &chunks)) {
        spdlog::warn("event=depth_encode_failed error=\"{}\"", *err);
        return;
      }
      asio::post(*sh->io, [sh, chunks = std::move(chunks)]() mutable {
        Shared& s = *sh;
        if (!s.server->link_up()) return;
        bool all = true;
        wire::StreamMessage m;
        for (wire::DepthChunk& c : chunks) {
          c.set_frame_epoch(s.frame_epoch);
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
    };
    depth_->start();
  }

  shared_->poll = std::make_unique<asio::steady_timer>(io_);
  shared_->next_poll_ns = steady_now_ns();
  asio::post(io_, [sh] { twoarm_arm_poll(sh); });

  // The truth trace's rows, allocated here so the control thread never does.
  trace_rows_ = 0;
  trace_.clear();
  if (task_model_ && o_.truth_trace_s > 0.0) trace_.resize(static_cast<std::size_t>(o_.truth_trace_s * 100.0) + 1);
  trace_period_steps_ = static_cast<uint64_t>(std::max<int64_t>(1, std::llround(1e7 / static_cast<double>(timestep_ns()))));

  shared_->stop.store(false, std::memory_order_release);
  robot::start_control_thread(thread_, [this] { run(); }, o_.control_thread, &shared_->rt_status, &wake_latency_fd_,
                       "twoarm");
  return true;
}

void TwoArmStation::local_estop(bool engaged, const std::string& reason) {
  // Takes effect at the next control tick, whatever the network thread does.
  const bool was = shared_->local_estop.exchange(engaged);
  if (was == engaged) return;
  const SharedPtr sh = shared_;
  const std::string why = (engaged ? "engaged at the robot: " : "released at the robot: ") + net::printable_text(reason);
  asio::post(io_, [sh, why] { twoarm_estop_changed(*sh, why); });
}

void TwoArmStation::stop() {
  shared_->stop.store(true, std::memory_order_release);
  if (thread_.joinable()) {
    thread_.join();
    trace_.resize(trace_rows_);  // shrinking: the rows written
  }
  if (depth_) depth_->halt();
  rt::release_cpu_wake_latency(wake_latency_fd_);
  wake_latency_fd_ = -1;
}

bool TwoArmStation::truth_sim(TwoArmTruthSim* out) const {
  const Shared& sh = *shared_;
  std::lock_guard<std::mutex> lk(sh.truth_mu);
  if (const TwoArmTruthSim* t = sh.truth.take()) {
    sh.truth_latest = *t;
    sh.have_truth = true;
  }
  if (!sh.have_truth) return false;
  *out = sh.truth_latest;
  return true;
}

const std::vector<TruthTraceRow>& TwoArmStation::truth_trace() const {
  static const std::vector<TruthTraceRow> kNone;
  return running() ? kNone : trace_;
}

std::string truth_trace_csv(const std::vector<TruthTraceRow>& rows) {
  std::ostringstream os;
  os << "t_s,clock_s";
  for (const char* arm : {"right", "left"})
    for (const char* what : {"G", "target", "force", "G_rot", "target_rot"})
      for (const char* axis : {"x", "y", "z"}) os << ',' << arm << '_' << what << '_' << axis;
  os << ",right_squeeze_N,left_squeeze_N,right_pads,left_pads,object_env_N,on_start,on_goal,on_other,goal_xy_err_m,"
        "goal_z_err_m,tilt_rad\n";
  os.precision(6);
  for (const TruthTraceRow& r : rows) {
    os << r.t_s << ',' << std::fixed << std::setprecision(6) << r.clock_s << std::defaultfloat << std::setprecision(6);
    for (std::size_t a = 0; a < kArms; ++a)
      for (const Eigen::Vector3d* v : {&r.G_A[a], &r.target_A[a], &r.force_A[a], &r.G_rot_A[a], &r.target_rot_A[a]})
        os << ',' << v->x() << ',' << v->y() << ',' << v->z();
    os << ',' << r.squeeze_N[0] << ',' << r.squeeze_N[1] << ',' << r.pads_on_object[0] << ',' << r.pads_on_object[1]
       << ',' << r.object_env_N << ',' << r.on_start << ',' << r.on_goal << ',' << r.on_other << ',' << r.goal_xy_err_m
       << ',' << r.goal_z_err_m << ',' << r.tilt_rad << '\n';
  }
  return os.str();
}

TwoArmStationStatistics TwoArmStation::statistics() const {
  const Shared& sh = *shared_;
  TwoArmStationStatistics s;
  s.sim_steps = sh.sim_steps.load();
  s.late_steps = sh.pacing.late_steps.load();
  s.resyncs = sh.pacing.resyncs.load();
  s.max_lateness_ns = sh.pacing.max_lateness_ns.load();
  s.mean_lateness_ns = sh.pacing.mean_lateness_ns();
  s.commands_received = sh.commands_received.load();
  s.commands_without_control = sh.commands_without_control.load();
  s.commands_stale = sh.commands_stale.load();
  s.commands_mode_mismatch = sh.commands_mode_mismatch.load();
  s.commands_refused = sh.commands_refused.load();
  for (std::size_t i = 0; i < s.refused_by_reason.size(); ++i) s.refused_by_reason[i] = sh.refused_by_reason[i].load();
  s.commands_accepted = sh.commands_accepted.load();
  s.commands_applied = sh.commands_applied.load();
  {
    std::lock_guard<std::mutex> lk(sh.detail_mu);
    s.targets_at_reach_edge = sh.targets_at_reach_edge;
    s.max_reach_error_m = sh.max_reach_error_m;
    s.max_reach_error_rad = sh.max_reach_error_rad;
  }
  s.last_refusal = sh.last_refusal.load();
  s.last_refused_seq = sh.last_refused_seq.load();
  s.last_refused_index = sh.last_refused_index.load();
  {
    std::lock_guard<std::mutex> lk(sh.detail_mu);
    s.last_refusal_detail = sh.last_refusal_detail;
  }
  s.validate = rt::summarize(sh.validate_ns);
  if (robot_) s.control_compute = rt::summarize(robot_->control_compute());
  s.states_sent = sh.states_sent.load();
  s.send_failures = sh.send_failures.load();
  s.depth_frames_sent = sh.depth_frames_sent.load();
  s.depth_chunks_sent = sh.depth_chunks_sent.load();
  s.depth_frames_skipped = depth_ ? depth_->skipped.load() : 0;
  s.depth_bytes_sent = sh.depth_bytes_sent.load();
  s.mode_changes = sh.mode_changes.load();
  s.estop_changes = sh.estop_changes.load();
  s.requests_refused = sh.requests_refused.load();
  s.estop_local = sh.local_estop.load();
  s.estop = sh.remote_estop.load() || s.estop_local;
  s.mode = sh.session_mode.load();
  s.safety = sh.safety.load();
  s.armed = sh.armed.load();
  s.following = sh.following.load();
  s.control_timing = robot::pacing_summary(sh.pacing, timestep_ns(), o_.late_wake_threshold_ns, sh.rt_status);
  {
    std::lock_guard<std::mutex> lk(sh.passivity_mu);
    s.passivity = sh.passivity;
    s.direct_commands = sh.direct_commands;
    s.direct_stale_ticks = sh.direct_stale_ticks;
    s.passivity_peer_old = sh.peer_old;
    s.passivity_peer_refused = sh.peer_refused;
  }
  s.passivity_controller = !robot_ || robot_->pc_mode() == haptics::tdpa::PcMode::kControl;
  if (task_model_) {
    std::lock_guard<std::mutex> lk(sh.task_mu);
    if (const TaskTruthData* d = sh.task_data.take()) {
      sh.task_latest = *d;
      sh.have_task = true;
    }
    if (sh.have_task) {
      s.task_judged = true;
      s.task = task_model_->task;
      s.task_verdict = task_truth_verdict(*task_model_, sh.task_latest);
      s.task_ticks = sh.task_latest.ticks;
      s.task_lift_time_s = sh.task_latest.lift_time_s;
    }
  }
  return s;
}

std::optional<std::string> TwoArmStation::attach_view(std::shared_ptr<robot::TwoArmViewFeed> feed) {
  if (!robot_) return std::string("attach_view: load() first");
  if (thread_.joinable()) return std::string("attach_view: before start()");
  if (robot_->sim().m()->nq > robot::TwoArmViewFrame::kMaxQpos)
    return "the scene's " + std::to_string(robot_->sim().m()->nq) + " qpos do not fit the view's frame (" +
           std::to_string(robot::TwoArmViewFrame::kMaxQpos) + ")";
  view_ = std::move(feed);
  return std::nullopt;
}

// The control thread. Nothing here allocates, locks, logs or touches a
// socket: the network thread does all of that with what is published here.
void TwoArmStation::run() {
  Shared& sh = *shared_;
  TwoArmRobot& robot = *robot_;
  robot::RobotServer& server = server_;
  const int64_t dt = robot.timestep_ns();
  const int64_t state_period = std::max<int64_t>(1, 1'000'000'000 / static_cast<int64_t>(o_.state_rate_hz));

  robot::ControlPacer pacer(dt, o_.max_catch_up_ns, o_.late_wake_threshold_ns, steady_now_ns());
  robot.set_time_origin_ns(pacer.anchor_ns());
  int64_t next_state_ns = robot.time_ns();
  uint64_t steps = 0;
  uint32_t depth_id = 0;
  uint32_t mode_epoch = sh.mode_epoch.load();
  int session_mode = sh.session_mode.load();
  int exec_mode = wire::MODE_IDLE;
  bool was_in_control = false;
  bool was_controlling = false;
  const TaskTruthModel* judge = task_model_.get();
  TaskTruthData judged;  // SIMULATION ONLY: accumulated here, copied out at each state publication

  if (o_.control_thread_hook) o_.control_thread_hook(true);
  while (!sh.stop.load(std::memory_order_acquire)) {
    pacer.set_what("step");
    if (o_.realtime && pacer.wait(sh.pacing) > 0) robot.set_time_origin_ns(pacer.anchor_ns());

    // Link and control first: a command must see the current state.
    const bool link_up = server.link_up();
    const bool in_control = link_up && server.operator_in_control();
    robot.set_link(in_control, link_up);
    // A new controlling session (not a link outage within one): both ends'
    // energies start from zero.
    if (const bool controlling = server.operator_in_control(); controlling != was_controlling) {
      was_controlling = controlling;
      if (controlling) {
        robot.reset_passivity();
        sh.control_epoch.fetch_add(1, std::memory_order_release);
      }
    }
    if (!in_control && was_in_control) {
      sh.session_mode.store(wire::MODE_UNSPECIFIED);  // losing control forgets the session mode
      session_mode = wire::MODE_UNSPECIFIED;
    }
    was_in_control = in_control;
    robot.set_estop(sh.remote_estop.load(std::memory_order_acquire) || sh.local_estop.load(std::memory_order_acquire));
    if (const uint32_t e = sh.mode_epoch.load(std::memory_order_acquire); e != mode_epoch) {
      mode_epoch = e;
      session_mode = sh.session_mode.load();
      if (session_mode != exec_mode) {
        // Stop what the old mode was doing until a command of the new one.
        robot.stop_commanded_motion();
        exec_mode = wire::MODE_IDLE;
        sh.exec_mode.store(exec_mode, std::memory_order_relaxed);
      }
    }

    // The newest validated command (older ones were superseded in the mailbox).
    if (const Shared::TimedArmsCommand* tc = sh.commands.take()) {
      if (!in_control) {
        sh.commands_without_control.fetch_add(1, std::memory_order_relaxed);  // control or link lost since
      } else if (session_mode != wire::MODE_UNSPECIFIED && tc->command.mode != session_mode) {
        sh.commands_mode_mismatch.fetch_add(1, std::memory_order_relaxed);
      } else {
        const uint64_t applied = robot.counters().applied;
        robot.apply(tc->command, tc->seq, robot.time_ns() - tc->excess_age_ns);
        sh.commands_accepted.fetch_add(1, std::memory_order_relaxed);
        if (robot.counters().applied != applied) sh.commands_applied.fetch_add(1, std::memory_order_relaxed);
        exec_mode = tc->command.mode;
        sh.exec_mode.store(exec_mode, std::memory_order_relaxed);
      }
    }

    robot.step();
    if (judge != nullptr) {
      task_truth_tick(*judge, robot.sim(), judged);
      if (trace_rows_ < trace_.size() && steps % trace_period_steps_ == 0) fill_truth_row(judged.last, robot, trace_[trace_rows_++]);
    }
    pacer.stepped();
    ++steps;
    sh.sim_steps.fetch_add(1, std::memory_order_relaxed);

    const int64_t now = robot.time_ns();
    if (now >= next_state_ns) {
      next_state_ns += state_period;
      if (next_state_ns <= now) next_state_ns = now + state_period;  // after a resync
      TwoArmSnapshot& snap = sh.states.back();
      robot.snapshot(&snap);
      if (view_ && view_->due(now)) {
        fill_view_frame(robot.sim(), snap, judge != nullptr ? &judged : nullptr, link_up, in_control, now,
                        view_->back());
        view_->publish();
      }
      sh.states.publish();
      TwoArmTruthSim& truth = sh.truth.back();
      truth.stamp_ns = now;
      truth.T_A_G = {robot.sim().grasp_site_A(Side::kRight), robot.sim().grasp_site_A(Side::kLeft)};
      sh.truth.publish();
      if (judge != nullptr) {
        sh.task_data.back() = judged;
        sh.task_data.publish();
      }
      sh.safety.store(robot.safety(), std::memory_order_relaxed);
      sh.armed.store(robot.armed(), std::memory_order_relaxed);
      sh.following.store(robot.following(), std::memory_order_relaxed);
      pacer.set_what("state");
    }
    if (depth_ && steps % static_cast<uint64_t>(depth_period_steps_) == 0) {
      depth_->submit(robot.sim().d(), now, depth_id++);
      pacer.set_what("depth");
    }
    if (o_.realtime) pacer.record(sh.pacing);
  }
  if (judge != nullptr) {  // the verdict covers every tick
    sh.task_data.back() = judged;
    sh.task_data.publish();
  }
  if (o_.control_thread_hook) o_.control_thread_hook(false);
}

}  // namespace hemm::twoarm
