#include "operator/model/model_thread.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace hemm::op {
namespace {
std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

ModelThread::ModelThread(servo::ModelChannel& channel, const ModelThreadParams& p)
    : channel_(channel),
      p_(p),
      scans_(p.scan_queue),
      commands_(p.command_queue),
      localizer_(p.registration),
      history_(p.history) {
  if (std::string e = mapping::validate(p.map); !e.empty()) throw std::invalid_argument("ModelThread: " + e);
  if (std::string e = validate(p.registration); !e.empty()) throw std::invalid_argument("ModelThread: " + e);
  if (!(p.correction_blend_speed > 0.0) || !(p.correction_blend_turn_rate > 0.0) ||
      !std::isfinite(p.correction_blend_speed) || !std::isfinite(p.correction_blend_turn_rate))
    throw std::invalid_argument("ModelThread: correction blend rates must be finite and > 0");
  if (!(p.rate_hz > 0.0 && p.rate_hz <= 1000.0)) throw std::invalid_argument("ModelThread: rate_hz outside (0, 1000]");
}

ModelThread::~ModelThread() { stop(); }

void ModelThread::submit_scan(std::shared_ptr<const wire::RangeScan> scan) {
  if (!scan) return;
  if (!scans_.try_push(std::move(scan))) scans_dropped_.fetch_add(1, std::memory_order_relaxed);
}

void ModelThread::submit_state(const wire::RobotState& state) { state_box_.put(state); }

void ModelThread::record_command(const SentCommand& c) {
  if (!commands_.try_push(c)) commands_dropped_.fetch_add(1, std::memory_order_relaxed);
}

ModelStats ModelThread::stats() const {
  ModelStats s;
  s.scans_in = scans_in_.load();
  s.scans_rejected = scans_rejected_.load();
  s.scans_dropped = scans_dropped_.load();
  s.states_in = states_in_.load();
  s.states_rejected = states_rejected_.load();
  s.commands_dropped = commands_dropped_.load();
  s.snapshots = snapshots_.load();
  s.freed = freed_.load();
  std::lock_guard<std::mutex> lock(stats_mutex_);  // never taken by the servo thread
  s.registration = reg_stats_;
  s.correction_shown = shown_stats_;
  return s;
}

void ModelThread::step(std::int64_t now_ns) {
  const std::int64_t offset = offset_ns_.load();
  const std::int64_t delay = delay_ns_.load();  // one value for the whole step
  if (step_tap_) {
    tapped_.now_ns = now_ns;
    tapped_.offset_ns = offset;
    tapped_.delay_ns = delay;
    tapped_.commands.clear();
    tapped_.state.reset();
    tapped_.scans.clear();
  }
  SentCommand c;
  while (commands_.try_pop(c)) {
    history_.push(c);
    if (step_tap_) tapped_.commands.push_back(c);
  }
  wire::RobotState ws;
  if (state_box_.take(ws)) {
    if (step_tap_) tapped_.state = ws;
    RobotStateSample s;
    if (auto e = state_from_wire(ws, offset, &s)) {
      states_rejected_.fetch_add(1);
      last_error_ = *e;
    } else if (!have_state_ || s.stamp_local_ns >= state_.stamp_local_ns) {
      state_ = s;
      have_state_ = true;
      states_in_.fetch_add(1);
    }
  }
  std::shared_ptr<const wire::RangeScan> m;
  mapping::RangeScan2D scan;
  localizer_.begin_step();
  while (scans_.try_pop(m)) {
    if (step_tap_) tapped_.scans.push_back(m);
    std::optional<std::string> e = scan_from_wire(*m, offset, &scan);
    m.reset();  // the ring slot keeps a copy of the pointer until overwritten; drop ours now
    if (!e) {
      // Placed by the corrected odometry, registered against the map.
      localizer_.place(scan, map_);
      std::string err = mapping::add_scan(p_.map, map_, scan);
      if (!err.empty()) e = std::move(err);
    }
    if (e) {
      scans_rejected_.fetch_add(1);
      last_error_ = *e;
    } else {
      scans_in_.fetch_add(1);
    }
  }

  blend_correction(now_ns);
  auto snap = std::make_unique<OperatorModelSnapshot>();
  snap->stamp_ns = now_ns;
  snap->version = ++version_;
  snap->have_state = have_state_;
  if (have_state_) {
    PredictionInput in{math::compose(shown_, state_.T_W_R_odom), state_.stamp_local_ns, state_.v, state_.omega};
    snap->T_W_R = predict_pose(in, history_, delay, now_ns, p_.max_prediction_s);
    snap->state = state_;
    // The motion acting now: the newest command that reached the robot.
    snap->v = state_.v;
    snap->omega = state_.omega;
    for (std::size_t i = history_.size(); i-- > 0;) {
      if (history_[i].t_ns + delay <= now_ns) {
        if (history_[i].t_ns + delay > state_.stamp_local_ns) {
          snap->v = history_[i].v;
          snap->omega = history_[i].omega;
        }
        break;
      }
    }
  }
  mapping::slide_window(p_.map, map_, now_ns, math::translation(snap->T_W_R));
  snap->map = mapping::build_snapshot(p_.map, map_);
  snap->segments = map_.segments.size();
  if (observer_) observer_(*snap);
  if (step_tap_) {
    step_tap_(tapped_, *snap);
    tapped_.scans.clear();  // the scans' memory is not kept here
  }
  channel_.publish(std::move(snap));  // also frees what the servo retired
  snapshots_.fetch_add(1);
  freed_.store(channel_.freed_by_collect());
}

void ModelThread::blend_correction(std::int64_t now_ns) {
  const math::Pose2& target = localizer_.stats().correction;
  const double dt = last_step_ns_ == 0 ? 0.0 : std::clamp(static_cast<double>(now_ns - last_step_ns_) * 1e-9, 0.0, 0.1);
  last_step_ns_ = now_ns;
  // Moves the shown correction toward the estimate at bounded speed. The
  // correction's translation depends on its rotation about W's origin, so
  // the blend is on the pose of the robot it maps: from shown * odom toward
  // target * odom, then expressed back as a correction.
  const math::Pose2 odom = have_state_ ? state_.T_W_R_odom : math::Pose2{};
  const math::Pose2 from = math::compose(shown_, odom), to = math::compose(target, odom);
  const Eigen::Vector2d d(to.x - from.x, to.y - from.y);
  const double dth = math::wrap_angle(to.theta - from.theta);
  const double max_d = p_.correction_blend_speed * dt, max_th = p_.correction_blend_turn_rate * dt;
  const double dn = d.norm();
  const Eigen::Vector2d step = dn > max_d ? Eigen::Vector2d(d * (max_d / dn)) : d;
  const double th = std::clamp(dth, -max_th, max_th);
  const math::Pose2 next{from.x + step.x(), from.y + step.y(), math::wrap_angle(from.theta + th)};
  shown_ = math::compose(next, math::inverse(odom));
  std::lock_guard<std::mutex> lock(stats_mutex_);
  reg_stats_ = localizer_.stats();
  shown_stats_ = shown_;
}

void ModelThread::start() {
  if (thread_.joinable()) throw std::logic_error("ModelThread already running");
  stop_.store(false);
  thread_ = std::thread([this] { run(); });
}

void ModelThread::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

void ModelThread::run() {
  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / p_.rate_hz));
  auto next = std::chrono::steady_clock::now();
  while (!stop_.load()) {
    step(steady_now_ns());
    next += period;
    const auto now = std::chrono::steady_clock::now();
    if (next < now) next = now;  // behind: do not run back to back
    std::this_thread::sleep_until(next);
  }
}

}  // namespace hemm::op
