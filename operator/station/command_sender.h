// The command sender (network thread): at rate_hz takes the newest
// StationSetpoint from the servo task's mailbox and sends a wire Command.
// Its dead-man is the hand's (the setpoint's deadman: the device's dead-man
// input) AND the setpoint is fresh (a stalled servo thread stops the robot);
// a manipulation setpoint without an arm target (the motion hold) goes
// without it (nothing to follow). Motion (v, omega, the arm target) goes only
// with the dead-man and when the task commands motion; otherwise the command
// is neutral. Device samples with a non-finite pose (the setpoint's count
// grew) are logged here, off the servo thread. A mode change also goes as a
// ModeChange session frame, after the first command of that mode was sent
// successfully (and again after the link was lost and is back). Each command sent is recorded for the pose
// prediction (model thread). An e-stop pressed on the device (the setpoint's
// estop_presses grew) goes as an EStop session frame as soon as the link is
// up (at once, or when it is back). Runs on one asio io_context; the send
// functions are called there.
#pragma once

#include <asio.hpp>
#include <cstdint>
#include <functional>

#include "operator/model/gaze.h"
#include "operator/model/model_thread.h"
#include "operator/station/operator_task.h"
#include "wire.pb.h"

namespace hemm::op {

struct CommandSenderParams {
  double rate_hz = 200.0;                // >= 100 (wire.proto)
  std::int64_t stale_after_ns = 100'000'000;  // setpoint older than this: no deadman
  // The depth camera's gaze (issue 24): every command carries a Gaze chosen
  // from the setpoint's tool position (operator/model/gaze.h; inactive while
  // there is no tool or the setpoint is stale). Off: no Gaze field at all.
  bool gaze = false;
  GazeParams gaze_params;
};

struct CommandSenderStats {
  std::uint64_t commands_sent = 0;
  std::uint64_t send_failures = 0;   // the link was up and the send failed
  std::uint64_t link_down = 0;       // periods with no link (connecting, reconnecting, lost): nothing sent
  std::uint64_t mode_changes_sent = 0;
  std::uint64_t stale = 0;  // commands sent with the deadman released because the setpoint was stale
  std::uint64_t estops_sent = 0;  // EStop frames (engage or release) sent
  std::uint64_t deadman_pressed = 0;  // commands sent with the hand's dead-man pressed
  std::uint64_t nonfinite_poses = 0;  // device samples with a non-finite pose (the task's count)
  std::uint64_t gaze_active = 0;      // commands sent with an active gaze
  std::uint64_t gaze_moves = 0;       // times the gaze point moved (beyond the hysteresis)
};

class CommandSender {
 public:
  using SendStream = std::function<bool(const wire::StreamMessage&)>;
  using SendSession = std::function<void(const wire::SessionFrame&)>;
  using Clock = std::function<std::int64_t()>;
  using LinkUp = std::function<bool()>;

  // Throws std::invalid_argument if rate_hz is outside [100, 1000]. model may
  // be null (no prediction history). link_up may be null (always up); while
  // it says down nothing is sent (counted as link_down, not as failures).
  CommandSender(asio::io_context& io, NewestMailbox<StationSetpoint>& setpoints, SendStream send,
                SendSession send_session, ModelThread* model, const CommandSenderParams& p, Clock clock,
                LinkUp link_up = nullptr);
  void start();
  void stop();
  // One period's work (the timer calls it; tests may too, on the io thread).
  void send_once();
  // Sends an EStop frame now (engaged or released) and returns its request
  // id (its Ack names it); 0 if the link is down (nothing sent).
  std::uint64_t send_estop(bool engaged, const std::string& reason);
  // Where the unseen candidates near the tool come from (e.g. the live
  // voxmap's free-space record): called on the network thread before each
  // gaze choice to fill the vector it is given (cleared first). Null: none.
  using UnseenSource = std::function<void(std::vector<GazeCandidate>*)>;
  void set_unseen_source(UnseenSource f) { unseen_source_ = std::move(f); }
  // Network thread only (or after stop).
  const CommandSenderStats& stats() const { return stats_; }
  const GazeChoice& last_gaze() const { return gaze_choice_; }
  math::Mode mode() const { return latest_.mode; }  // of the newest setpoint taken

 private:
  void arm();

  asio::steady_timer timer_;
  NewestMailbox<StationSetpoint>& setpoints_;
  SendStream send_;
  SendSession send_session_;
  ModelThread* model_;
  CommandSenderParams p_;
  Clock clock_;
  LinkUp link_up_;
  StationSetpoint latest_;
  bool have_ = false;
  wire::Mode sent_mode_ = wire::MODE_UNSPECIFIED;
  std::uint64_t request_id_ = 0;  // of mode changes and e-stops alike
  std::uint64_t estop_presses_seen_ = 0;
  bool estop_pending_ = false;
  std::chrono::steady_clock::time_point next_;
  bool running_ = false;
  CommandSenderStats stats_;
  wire::StreamMessage msg_;
  UnseenSource unseen_source_;
  std::vector<GazeCandidate> unseen_;
  GazeChooserState gaze_state_;
  GazeChoice gaze_choice_;
};

}  // namespace hemm::op
