// Robot pose prediction for model-mediated teleoperation (DESIGN.md
// principle 3). The newest RobotState gives the odometry pose at its
// acquisition time (robot clock, mapped into ours with the link's clock
// offset). The robot has been moving since then under the commands this
// operator sent, so the present pose is that pose integrated forward as a
// unicycle with the command history: the command sent at local time t_i acts
// on the robot from t_i + command_delay_ns (the forward one-way delay; RTT/2
// is the usual estimate) until the next command takes over.
// Pure computation: no clocks, no threads, no allocation after construction.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/math/frames.h"

namespace hemm::op {

// One command as sent (local steady clock). A command sent without the
// deadman is recorded with v = omega = 0 (the robot stops on it).
struct SentCommand {
  std::int64_t t_ns = 0;
  double v = 0.0;      // m/s
  double omega = 0.0;  // rad/s
};

// Exact unicycle motion for dt seconds at constant (v, omega): arcs, with the
// straight line as the omega -> 0 limit.
math::Pose2 integrate_unicycle(const math::Pose2& T_W_R, double v, double omega, double dt_s);

// Bounded history of sent commands, oldest first, in non-decreasing time.
// A fixed-capacity ring: push() overwrites the oldest when full.
class CommandHistory {
 public:
  explicit CommandHistory(std::size_t capacity = 2048);
  // Rejects (returns false, no change) a non-finite command or one older than
  // the newest recorded.
  bool push(const SentCommand& c);
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return buf_.size(); }
  // i = 0 is the oldest.
  const SentCommand& operator[](std::size_t i) const { return buf_[(head_ + i) % buf_.size()]; }
  void clear() { head_ = size_ = 0; }

 private:
  std::vector<SentCommand> buf_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

struct PredictionInput {
  math::Pose2 T_W_R;               // odometry pose at stamp_local_ns
  std::int64_t stamp_local_ns = 0; // the state's stamp, in our clock
  double v = 0.0;                  // measured speed at the stamp (used before the first command in the history)
  double omega = 0.0;
};

// The pose at now_ns. Commands effective (t_i + command_delay_ns) before
// stamp_local_ns only set the motion at the stamp; before the first command
// the state's own (v, omega) is used. max_horizon_s bounds the extrapolation
// (a stale state is not integrated for ever). now_ns <= stamp: the state pose.
math::Pose2 predict_pose(const PredictionInput& in, const CommandHistory& history, std::int64_t command_delay_ns,
                         std::int64_t now_ns, double max_horizon_s = 2.0);

}  // namespace hemm::op
