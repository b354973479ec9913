#include "operator/telemanip/task_human.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "common/config/config.h"
#include "config_operator.pb.h"
#include "operator/device/bimanual/handles.h"
#include "operator/device/bimanual/simulation.h"
#include "report.pb.h"

namespace hemm::op::telemanip {

double lever_for_gripper(const ArmMappingParams& p, const twoarm::GripperTarget& g) noexcept {
  const double span = p.opening_open_m - p.opening_closed_m;
  if (!(std::abs(span) > 1e-9) || !std::isfinite(g.opening_m)) return 0.0;
  return std::clamp((p.opening_open_m - g.opening_m) / span, 0.0, 1.0);
}

std::string validate(const DriftCorrectionParams& p) {
  const auto ok = [](double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; };
  if (!ok(p.gain_per_s, 0.0, 5.0)) return "drift correction: gain must be in [0, 5] per second";
  if (!ok(p.wait_s, 0.0, 60.0)) return "drift correction: wait must be in [0, 60] s";
  if (!ok(p.max_m, 0.0, 1.0) || !ok(p.max_rad, 0.0, 3.0))
    return "drift correction: bounds must be in [0, 1] m and [0, 3] rad";
  if (!ok(p.contact_N, 0.0, 1000.0) || !ok(p.contact_Nm, 0.0, 100.0))
    return "drift correction: contact thresholds must be >= 0 (and finite)";
  return {};
}

void integrate_drift(const DriftCorrectionParams& p, const Eigen::Isometry3d& target,
                     const twoarm_tasks::BelievedArm& b, double dt, DriftOffset* o) noexcept {
  if (!(p.gain_per_s > 0.0 && dt > 0.0)) return;
  const Eigen::Vector3d lack_p = target.translation() - b.T_A_G.translation();
  const Eigen::AngleAxisd lack_R(target.linear() * b.T_A_G.linear().transpose());
  const Eigen::Vector3d lack_r = lack_R.angle() * lack_R.axis();
  for (int i = 0; i < 3; ++i) {
    // The environment's force on the gripper against the lack: a contact.
    if (!(b.force_A[i] * (lack_p[i] > 0.0 ? 1.0 : -1.0) < -p.contact_N)) o->p_A[i] += p.gain_per_s * dt * lack_p[i];
    if (!(b.torque_A[i] * (lack_r[i] > 0.0 ? 1.0 : -1.0) < -p.contact_Nm)) o->r_A[i] += p.gain_per_s * dt * lack_r[i];
  }
  if (const double n = o->p_A.norm(); n > p.max_m) o->p_A *= p.max_m / n;
  if (const double n = o->r_A.norm(); n > p.max_rad) o->r_A *= p.max_rad / n;
  if (!o->p_A.allFinite() || !o->r_A.allFinite()) *o = DriftOffset{};
}

Eigen::Isometry3d offset_target(const Eigen::Isometry3d& target, const DriftOffset& o) noexcept {
  Eigen::Isometry3d T = target;
  T.translation() += o.p_A;
  if (const double a = o.r_A.norm(); a > 0.0) T.linear() = Eigen::AngleAxisd(a, o.r_A / a).toRotationMatrix() * target.linear();
  return T;
}

TaskHumanBrain::TaskHumanBrain(twoarm_tasks::TaskScript script, const std::array<ArmMappingParams, 2>& mapping)
    : script_(std::move(script)), mapping_(mapping) {
  for (const ArmMappingParams& m : mapping_)
    if (std::string e = validate(m); !e.empty()) throw std::invalid_argument("task human: mapping: " + e);
  if (script_.steps.empty()) throw std::invalid_argument("task human: the plan has no steps");
  progress_.task = script_.task;
  progress_.steps = script_.steps.size();
  progress_.last_step = script_.steps.front().name;
}

TaskHumanBrain::~TaskHumanBrain() { stop(); }

void TaskHumanBrain::set_drift_correction(const DriftCorrectionParams& p) {
  if (std::string e = validate(p); !e.empty()) throw std::invalid_argument("task human: " + e);
  drift_ = p;
}

void TaskHumanBrain::tick(double t_s) {
  const wire::ArmsState* b = believed_.take();
  if (b == nullptr) b = believed_.latest();
  // The plan's clock stops while the clutch is held and resume_s after.
  const bool indexing = indexing_.held[0].load(std::memory_order_relaxed) || indexing_.held[1].load(std::memory_order_relaxed);
  if (indexing) last_index_t_ = t_s;
  const bool paused = last_index_t_ >= 0.0 && t_s - last_index_t_ <= indexing_.p.resume_s;
  if (paused && last_t_ >= 0.0) paused_s_ += std::max(0.0, t_s - last_t_);
  const double prev_t = last_t_;
  last_t_ = t_s;
  const bool was_started = st_.started, was_done = st_.done;
  const twoarm_tasks::ScriptOutput out = twoarm_tasks::script_step(script_, st_, b, t_s - paused_s_);
  if (!was_started && st_.started) start_t_ = t_s;
  while (step_end_t_.size() < st_.step_end_t.size()) step_end_t_.push_back(t_s);
  if (!was_done && st_.done) done_t_ = t_s;
  ++ticks_;
  const double dt = ticks_ > 0 && prev_t >= 0.0 ? std::clamp(t_s - prev_t, 0.0, 0.1) : 0.0;
  if (out.send && drift_.gain_per_s > 0.0) {
    std::array<twoarm_tasks::BelievedArm, 2> seen;
    const bool have = b != nullptr && !twoarm_tasks::read_believed(*b, &seen);
    for (std::size_t k = 0; k < 2; ++k) {
      const Eigen::Isometry3d& T = out.targets.T_A_G[k];
      if (!T.isApprox(last_target_[k], 1e-9)) last_move_t_[k] = t_s;
      last_target_[k] = T;
      if (have && !paused && t_s - last_move_t_[k] >= drift_.wait_s) {
        integrate_drift(drift_, T, seen[k], dt, &drift_offset_[k]);
        drift_max_m_[k] = std::max(drift_max_m_[k], drift_offset_[k].p_A.norm());
      }
    }
  }
  if (out.send) {
    for (std::size_t k = 0; k < 2; ++k) {
      TaskHandWish& w = wishes_[k].back();
      w.active = true;
      w.T_A_G = offset_target(out.targets.T_A_G[k], drift_offset_[k]);
      w.lever = lever_for_gripper(mapping_[k], out.targets.gripper[k]);
      w.deadman = out.deadman;
      wishes_[k].publish();
    }
  }
  if (st_.done) done_.store(true, std::memory_order_release);
  std::lock_guard<std::mutex> lk(mu_);
  progress_.started = st_.started;
  progress_.done = st_.done;
  progress_.done_s = st_.done ? done_t_ - start_t_ : -1.0;
  progress_.steps_done = st_.step;
  progress_.last_step = st_.step < script_.steps.size() ? script_.steps[st_.step].name : "done";
  progress_.searches = st_.searches;
  progress_.error = st_.error;
  progress_.ticks = ticks_;
  progress_.wait_pos_m = st_.wait_pos_m;
  progress_.wait_rot_rad = st_.wait_rot_rad;
  progress_.wait_speed_mps = st_.wait_speed_mps;
  progress_.step_done_s.resize(step_end_t_.size());
  for (std::size_t i = 0; i < step_end_t_.size(); ++i) progress_.step_done_s[i] = step_end_t_[i] - start_t_;
  progress_.indexing_pause_s = paused_s_;
  progress_.drift_offset_max_m = drift_max_m_;
  progress_.clutch_presses = indexing_.presses[0].load(std::memory_order_relaxed) + indexing_.presses[1].load(std::memory_order_relaxed);
}

void TaskHumanBrain::start(double rate_hz) {
  if (thread_.joinable()) return;
  if (!(rate_hz >= 1.0 && rate_hz <= 1000.0)) throw std::invalid_argument("task human: rate must be in [1, 1000] Hz");
  stop_.store(false);
  thread_ = std::thread([this, rate_hz] {
    using clock = std::chrono::steady_clock;
    const auto period = std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(1.0 / rate_hz));
    const auto t0 = clock::now();
    auto next = t0;
    while (!stop_.load(std::memory_order_acquire)) {
      tick(std::chrono::duration<double>(clock::now() - t0).count());
      next += period;
      const auto now = clock::now();
      if (next < now) next = now;  // behind: no burst
      std::this_thread::sleep_until(next);
    }
  });
}

void TaskHumanBrain::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

TaskProgress TaskHumanBrain::progress() const {
  std::lock_guard<std::mutex> lk(mu_);
  return progress_;
}

TaskHumanHand::TaskHumanHand(const device::bimanual::HumanTarget& rest, const ArmMappingParams& mapping,
                             NewestMailbox<TaskHandWish>* wishes, NewestMailbox<MappingAnchor>* anchors,
                             double lever_travel_m, const std::atomic<std::uint32_t>* robot_safety,
                             TaskIndexing* indexing, int hand, std::uint32_t clutch_buttons)
    : rest_(rest),
      mapping_(mapping),
      wishes_(wishes),
      anchors_(anchors),
      lever_travel_m_(lever_travel_m),
      robot_safety_(robot_safety),
      indexing_(indexing),
      hand_(hand),
      clutch_buttons_(clutch_buttons),
      last_p_D_(rest.position_D),
      last_q_D_(rest.orientation_D) {
  if (std::string e = validate(mapping); !e.empty()) throw std::invalid_argument("task human: mapping: " + e);
  if (wishes_ == nullptr || anchors_ == nullptr) throw std::invalid_argument("task human: no mailbox");
  if (!(std::isfinite(lever_travel_m) && lever_travel_m >= 0.0))
    throw std::invalid_argument("task human: lever travel must be >= 0");
  if (hand < 0 || hand > 1) throw std::invalid_argument("task human: hand must be 0 (right) or 1 (left)");
  if (indexing != nullptr) {
    const TaskIndexingParams& q = indexing->p;
    if (!(q.reach_m > 0.0 && q.reach_m < 1.0 && q.hold_s > 0.0 && q.hold_s < 10.0 && q.cooldown_s >= 0.0 &&
          q.cooldown_s < 10.0 && q.resume_s >= 0.0 && q.resume_s < 10.0))
      throw std::invalid_argument(
          "task human: indexing reach in (0, 1) m, hold in (0, 10) s, cooldown and resume in [0, 10) s");
  }
}

bool TaskHumanHand::clutch_step(double t_s) const noexcept {
  if (indexing_ == nullptr || clutch_buttons_ == 0) return false;
  if (clutch_held_) {
    if (t_s - clutch_t0_ >= indexing_->p.hold_s) {
      clutch_held_ = false;
      clutch_released_t_ = t_s;
      indexing_->held[static_cast<std::size_t>(hand_)].store(false, std::memory_order_relaxed);
    }
  } else if (t_s - clutch_released_t_ >= indexing_->p.cooldown_s &&
             (indexing_->wants[0].load(std::memory_order_relaxed) || indexing_->wants[1].load(std::memory_order_relaxed))) {
    clutch_held_ = true;
    clutch_t0_ = t_s;
    indexing_->held[static_cast<std::size_t>(hand_)].store(true, std::memory_order_relaxed);
    indexing_->presses[static_cast<std::size_t>(hand_)].fetch_add(1, std::memory_order_relaxed);
  }
  return clutch_held_;
}

device::bimanual::HumanTarget TaskHumanHand::at(double t_s) const noexcept {
  if (const MappingAnchor* a = anchors_->take()) anchor_ = *a;
  if (const TaskHandWish* w = wishes_->take()) wish_ = *w;
  device::bimanual::HumanTarget g = rest_;
  const bool habit =
      robot_safety_ == nullptr || deadman_.step(robot_safety_->load(std::memory_order_relaxed), t_s);
  g.deadman = habit && wish_.active && wish_.deadman;
  if (lever_travel_m_ > 0.0) {
    g.finger_position = wish_.lever * lever_travel_m_;
  } else {
    g.joystick = Eigen::Vector2d(0.0, wish_.lever);
  }
  const double dt = last_t_s_ >= 0.0 ? std::clamp(t_s - last_t_s_, 0.0, 0.1) : 0.0;
  last_t_s_ = t_s;
  if (g.deadman && clutch_step(t_s)) g.buttons |= clutch_buttons_;
  if (!wish_.active || !anchor_.engaged) {
    // Released or clutched: the mapping re-anchors at the next press, so
    // the hand starts over - back towards its rest, from where it was.
    turn_bias_D_.setZero();
    if (indexing_ != nullptr) indexing_->wants[static_cast<std::size_t>(hand_)].store(false, std::memory_order_relaxed);
    const Eigen::Vector3d d = rest_.position_D - last_p_D_;
    const double step = kReturnSpeed_mps * dt;
    last_p_D_ += d.norm() > step ? (step / d.norm()) * d : d;
    const double a = last_q_D_.angularDistance(rest_.orientation_D);
    const double turn = kReturnRate_radps * dt;
    last_q_D_ = a > turn ? last_q_D_.slerp(turn / a, rest_.orientation_D) : rest_.orientation_D;
    g.position_D = last_p_D_;
    g.orientation_D = last_q_D_;
    return g;
  }
  // Where the hand must be for the mapping to ask the plan's G (from the anchor).
  const Eigen::Isometry3d hand_D = hand_pose_D(mapping_, anchor_.state, wish_.T_A_G);
  g.position_D = hand_D.translation();
  if (indexing_ != nullptr) {
    const bool far = (hand_D.translation() - rest_.position_D).norm() > indexing_->p.reach_m;
    indexing_->wants[static_cast<std::size_t>(hand_)].store(far, std::memory_order_relaxed);
  }
  // The turn the commanded G still lacks, in A, seen as the hand's (in D, 1/k of it).
  const Eigen::AngleAxisd lack_A(wish_.T_A_G.linear() * anchor_.state.T_A_G_cmd.linear().transpose());
  const Eigen::Vector3d lack_D =
      mapping_.R_A_D.transpose() * (lack_A.angle() * lack_A.axis()) / mapping_.rotation_scale;
  turn_bias_D_ += kTurnGain_per_s * dt * lack_D;
  if (const double n = turn_bias_D_.norm(); n > kTurnBiasMax_rad) turn_bias_D_ *= kTurnBiasMax_rad / n;
  const double b = turn_bias_D_.norm();
  const Eigen::Matrix3d bias =
      b > 0.0 ? Eigen::AngleAxisd(b, turn_bias_D_ / b).toRotationMatrix() : Eigen::Matrix3d::Identity();
  g.orientation_D = Eigen::Quaterniond(bias * hand_D.linear());
  last_p_D_ = g.position_D;
  last_q_D_ = g.orientation_D;
  return g;
}

std::string check_task_config(const config::TelemanipConfig& c, const std::string& config_path,
                              std::string* scene_path) {
  scene_path->clear();
  const std::string& t = c.task();
  if (t.empty()) {
    if (!c.task_scene().empty()) return "telemanip.task_scene (--task-scene) needs telemanip.task (--task)";
    return {};
  }
  if (t != "box" && t != "peg" && t != "bar") return "telemanip.task (--task) '" + t + "': must be box, peg or bar";
  if (c.task_scene().empty())
    return "telemanip.task (--task) " + t + " needs telemanip.task_scene (--task-scene): the scene whose task: lines "
           "give the objects (deploy/scenes/workbench.xml; workbench_box.xml for the box)";
  if (!(std::isfinite(c.task_settle_s()) && c.task_settle_s() >= 0.0 && c.task_settle_s() <= 60.0))
    return "telemanip.task_settle_s: must be within [0, 60] s";
  *scene_path = config::resolve_relative_to(config_path, c.task_scene());
  return {};
}

twoarm_tasks::TaskScript task_plan(const std::string& task, const std::string& scene_path) {
  const twoarm_tasks::TaskSceneResult r = twoarm_tasks::load_task_scene(scene_path);
  if (!r.scene) throw std::invalid_argument("task scene: " + r.error);
  if (task == "box") return twoarm_tasks::box_script(*r.scene);
  if (task == "peg") return twoarm_tasks::peg_script(*r.scene);
  if (task == "bar") return twoarm_tasks::bar_script(*r.scene);
  throw std::invalid_argument("task '" + task + "': must be box, peg or bar");
}

std::array<std::shared_ptr<const device::bimanual::HumanScript>, 2> task_hands(
    const device::bimanual::SimulationConfig& sim, const std::array<ArmMappingParams, 2>& mapping,
    const std::array<NewestMailbox<MappingAnchor>*, 2>& anchors, TaskHumanBrain& brain,
    const std::atomic<std::uint32_t>* robot_safety) {
  const auto rest = device::bimanual::BimanualSimulation(sim).resting_targets();
  std::array<std::shared_ptr<const device::bimanual::HumanScript>, 2> hands;
  for (std::size_t k = 0; k < hands.size(); ++k) {
    const double travel = device::bimanual::handle_spec(sim.plant.handles[k]).grip_travel;
    // The clutch buttons on this hand's handle: those of the arms it gates.
    std::uint32_t clutch = 0;
    for (const ArmMappingParams& m : mapping)
      if (m.deadman_ee == static_cast<int>(k)) clutch |= clutch_bit(m);
    hands[k] = std::make_shared<const TaskHumanHand>(rest[k], mapping[k], &brain.wishes(static_cast<int>(k)), anchors[k],
                                                     travel, robot_safety, &brain.indexing(), static_cast<int>(k), clutch);
  }
  return hands;
}

void fill_task_report(const TaskProgress& p, report::TelemanipTaskProgress* out) {
  out->set_task(p.task);
  out->set_done(p.done);
  out->set_done_s(p.done_s);
  out->set_steps_done(static_cast<std::uint32_t>(p.steps_done));
  out->set_steps(static_cast<std::uint32_t>(p.steps));
  out->set_last_step(p.last_step);
  out->set_searches(p.searches);
  out->set_error(p.error);
  out->set_brain_ticks(p.ticks);
  for (std::size_t a = 0; a < 2; ++a) {
    out->add_wait_pos_m(p.wait_pos_m[a]);
    out->add_wait_rot_rad(p.wait_rot_rad[a]);
    out->add_wait_speed_mps(p.wait_speed_mps[a]);
  }
  for (double s : p.step_done_s) out->add_step_done_s(s);
  out->set_clutch_presses(p.clutch_presses);
  out->set_indexing_pause_s(p.indexing_pause_s);
  for (double d : p.drift_offset_max_m) out->add_drift_offset_max_m(d);
}

}  // namespace hemm::op::telemanip
