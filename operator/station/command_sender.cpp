#include "operator/station/command_sender.h"

#include <spdlog/spdlog.h>

#include <bit>
#include <stdexcept>

namespace hemm::op {

CommandSender::CommandSender(asio::io_context& io, NewestMailbox<StationSetpoint>& setpoints, SendStream send,
                             SendSession send_session, ModelThread* model, const CommandSenderParams& p, Clock clock,
                             LinkUp link_up)
    : timer_(io),
      setpoints_(setpoints),
      send_(std::move(send)),
      send_session_(std::move(send_session)),
      model_(model),
      p_(p),
      clock_(std::move(clock)),
      link_up_(std::move(link_up)) {
  if (!(p.rate_hz >= 100.0 && p.rate_hz <= 1000.0))
    throw std::invalid_argument("CommandSender: rate_hz must be in [100, 1000]");
  if (!send_ || !clock_) throw std::invalid_argument("CommandSender: send and clock are required");
  if (auto e = check(p.gaze_params)) throw std::invalid_argument("CommandSender: " + *e);
}

void CommandSender::start() {
  running_ = true;
  next_ = std::chrono::steady_clock::now();
  arm();
}

void CommandSender::stop() {
  running_ = false;
  timer_.cancel();
}

void CommandSender::arm() {
  if (!running_) return;
  next_ += std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / p_.rate_hz));
  const auto now = std::chrono::steady_clock::now();
  if (next_ < now) next_ = now;  // behind: keep the rate, do not burst
  timer_.expires_at(next_);
  timer_.async_wait([this](const asio::error_code& ec) {
    if (ec || !running_) return;
    send_once();
    arm();
  });
}

std::uint64_t CommandSender::send_estop(bool engaged, const std::string& reason) {
  if (!send_session_ || (link_up_ && !link_up_())) return 0;
  wire::SessionFrame f;
  f.mutable_estop()->set_engaged(engaged);
  f.mutable_estop()->set_reason(reason);
  f.mutable_estop()->set_request_id(++request_id_);
  send_session_(f);
  ++stats_.estops_sent;
  return request_id_;
}

void CommandSender::send_once() {
  StationSetpoint sp;
  if (setpoints_.take(sp)) {
    latest_ = sp;
    have_ = true;
  }
  const std::int64_t now = clock_();
  if (!have_) return;  // the servo has not run yet: nothing to say
  if (latest_.estop_presses > estop_presses_seen_) {
    estop_presses_seen_ = latest_.estop_presses;
    estop_pending_ = true;
  }
  if (latest_.nonfinite_poses > stats_.nonfinite_poses) {
    // The first time, then at every doubling: a broken sensor does not flood the log.
    const std::uint64_t before = stats_.nonfinite_poses;
    stats_.nonfinite_poses = latest_.nonfinite_poses;
    if (before == 0 || std::bit_width(before) != std::bit_width(stats_.nonfinite_poses))
      spdlog::warn("event=device_pose_nonfinite count={} action=\"all motion held\"", stats_.nonfinite_poses);
  }
  if (link_up_ && !link_up_()) {
    // Nothing to send on; a re-opened link hears the mode (and a pending e-stop) again.
    ++stats_.link_down;
    sent_mode_ = wire::MODE_UNSPECIFIED;
    return;
  }
  if (estop_pending_ && send_estop(true, "device buttons") != 0) estop_pending_ = false;
  const wire::Mode mode = to_wire_mode(latest_.mode);
  const bool fresh = now - latest_.t_ns <= p_.stale_after_ns;
  if (!fresh && latest_.moves_robot) ++stats_.stale;
  const bool deadman = latest_.deadman && fresh && (mode != wire::MODE_MANIPULATION || latest_.arm_valid);
  const bool moves = deadman && latest_.moves_robot;
  wire::Command& c = *msg_.mutable_command();
  c.set_stamp_ns(now);
  c.set_mode(mode);
  c.set_deadman(deadman);
  c.set_v(moves ? latest_.v : 0.0);
  c.set_omega(moves ? latest_.omega : 0.0);
  if (moves && latest_.arm_valid) {
    c.mutable_arm_target()->set_x(latest_.arm_target_R.x());
    c.mutable_arm_target()->set_y(latest_.arm_target_R.y());
    c.mutable_arm_target()->set_z(latest_.arm_target_R.z());
  } else {
    c.clear_arm_target();
  }
  if (p_.gaze) {
    unseen_.clear();
    if (unseen_source_) unseen_source_(&unseen_);
    const std::uint64_t moves_before = gaze_state_.moves;
    const std::optional<Eigen::Vector3d> tool =
        latest_.tool_valid && fresh ? std::optional<Eigen::Vector3d>(latest_.tool_W) : std::nullopt;
    gaze_choice_ = choose_gaze(p_.gaze_params, gaze_state_, tool, now, unseen_);
    stats_.gaze_moves += gaze_state_.moves - moves_before;
    wire::Gaze& g = *c.mutable_gaze();
    g.set_active(gaze_choice_.active);
    g.mutable_point_w()->set_x(gaze_choice_.point_W.x());
    g.mutable_point_w()->set_y(gaze_choice_.point_W.y());
    g.mutable_point_w()->set_z(gaze_choice_.point_W.z());
  }
  if (send_(msg_)) {
    ++stats_.commands_sent;
    if (deadman) ++stats_.deadman_pressed;
    if (p_.gaze && gaze_choice_.active) ++stats_.gaze_active;
    if (model_ != nullptr) model_->record_command(SentCommand{now, c.v(), c.omega()});
    // The mode goes on the session only once the link carries commands; a
    // failed send (no session: connecting, reconnecting) forgets it, so a
    // re-opened session hears the mode again.
    if (mode != sent_mode_ && send_session_) {
      wire::SessionFrame f;
      f.mutable_mode_change()->set_mode(mode);
      f.mutable_mode_change()->set_request_id(++request_id_);
      send_session_(f);
      ++stats_.mode_changes_sent;
    }
    sent_mode_ = mode;
  } else {
    ++stats_.send_failures;
    sent_mode_ = wire::MODE_UNSPECIFIED;
  }
}

}  // namespace hemm::op
