#pragma once
// SIMULATION ONLY. Offline evaluation of the operator's rendered force
// against the force the TRUE scene gives along the same proxy path.
//
// Input: the operator's per-tick world log (hemm-operator --log RUN.csv
// writes RUN.csv.world.csv; columns are read by name) and the exact scene
// (scene_slice.h). For each servo tick at local time t:
//   - the robot's true pose T_true(t) is interpolated from the true poses the
//     simulation sent (unique state_stamp_ns with has_truth = 1; linear in
//     x, y, shortest angle in theta); ticks before the first sample are
//     skipped, after the last the last sample is held (both counted);
//   - the interaction point is robot-relative (every workspace map of HEMM
//     Eq. 1 is anchored to the robot): p_R = T_pred^-1 goal_W with T_pred the
//     operator's predicted pose, and the true point is T_true(t) p_R;
//   - the exact-geometry god-object (haptics::reference_tick, its own
//     ProxyData, reset at the first evaluated tick to the first true point as
//     the operator resets its own) runs against the scene at the tick's scale;
//   - both forces are compared in the robot frame R (what the hand feels does
//     not depend on which world frame the pose was estimated in):
//     F_rendered_R = Rot(-theta_pred) fw, F_truth_R = Rot(-theta_true) F_truth_W.
// The difference therefore contains the local model's error (scan noise,
// interpolation, staleness) and the pose error (prediction and odometry).
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/haptics/proxy/reference_scene.h"
#include "common/haptics/proxy/virtual_proxy.h"

namespace hemm::report {
class Truth;  // report.pb.h
}

namespace hemm::robot {

// The columns of a world-log row that the evaluation uses (W frame).
struct WorldLogRow {
  std::int64_t t_ns = 0;            // operator local steady clock of the tick
  double robot_x = 0, robot_y = 0, robot_theta = 0;  // predicted T_W_R
  double goal_x = 0, goal_y = 0, goal_z = 0;          // interaction point
  double proxy_x = 0, proxy_y = 0;                    // rendered proxy
  double fw_x = 0, fw_y = 0;                          // rendered force, device N, W axes
  double scale = 0;                                   // W m per device m
  std::int64_t state_stamp_ns = -1;                   // newest RobotState's local stamp
  double truth_x = 0, truth_y = 0, truth_theta = 0;   // that state's TRUE pose
  bool has_truth = false;
};

struct WorldLog {
  std::vector<WorldLogRow> rows;
  std::size_t truncated_lines = 0;  // a last line cut mid-write (no newline): dropped
};

// The columns read_world_log needs (any order; others are ignored).
const std::vector<std::string>& world_log_required_columns();

// Reads a world log. On error returns false with a one-line message naming
// the file and, for a bad field, line:column and the column's name; *out is
// left untouched. A last line without its newline is taken as cut off by a
// killed writer: dropped and counted. t_ns must not decrease.
bool read_world_log(const std::string& path, WorldLog* out, std::string* error);

struct TruthOptions {
  double contact_threshold_n = 0.05;  // a tick is a contact tick when either |F| exceeds this
  // Window in seconds since the first row's t_ns; the proxy still runs from
  // the first evaluable tick so its state at `from` is the true one.
  std::optional<double> from_s, to_s;
  bool per_tick = false;  // fill TruthReport::per_tick
};

struct TruthTick {
  std::int64_t t_ns = 0;
  double t_s = 0;                                   // since the first row
  Eigen::Vector2d f_rendered_R = Eigen::Vector2d::Zero();
  Eigen::Vector2d f_truth_R = Eigen::Vector2d::Zero();
  double df = 0;                                    // |F_rendered_R - F_truth_R|
  Eigen::Vector2d proxy_rendered_W = Eigen::Vector2d::Zero();  // operator's proxy (predicted W)
  Eigen::Vector2d proxy_true_W = Eigen::Vector2d::Zero();      // reference proxy (true W)
  double true_x = 0, true_y = 0, true_theta = 0;   // interpolated T_true(t)
  double pose_error_m = 0;                          // |predicted - true| position
  bool held = false;                                // after the last truth sample
};

struct TruthReport {
  std::size_t rows = 0;            // rows in the log
  std::size_t truth_samples = 0;   // unique stamps with a true pose
  double truth_max_gap_s = 0;      // largest gap between truth samples
  std::size_t window_rows = 0;     // rows inside [from, to]
  std::size_t ticks = 0;           // evaluated ticks (in the window)
  std::size_t skipped_before_truth = 0;  // in the window, before the first truth sample
  std::size_t skipped_invalid = 0;       // in the window, scale <= 0 or non-finite pose/goal
  std::size_t held_after_truth = 0;      // evaluated with the last truth sample held
  double rms_n = 0, max_n = 0;           // |dF| over evaluated ticks
  double max_t_s = 0;                    // time of max_n, s since the first row
  std::size_t contact_ticks = 0;
  double contact_rms_n = 0, contact_max_n = 0;
  double mean_force_rendered_n = 0, mean_force_truth_n = 0;  // over contact ticks
  double pose_error_mean_m = 0, pose_error_max_m = 0;         // predicted vs true position
  double heading_error_max_rad = 0;
  std::vector<TruthTick> per_tick;       // when options.per_tick
};

TruthReport evaluate_against_truth(const std::vector<WorldLogRow>& rows, const haptics::ExactScene& scene,
                                   const haptics::ProxyModel& proxy_model, const TruthOptions& options = {});

// The report's numbers as proto/report.proto's Truth (force and pose numbers
// left out when no tick was evaluated; contact numbers are 0 without
// contact). The run's own fields (height_m, from_s, ...) are the caller's to
// set; config::to_json prints it.
report::Truth to_report(const TruthReport& r);

}  // namespace hemm::robot
