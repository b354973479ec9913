// The operator's model thread (DESIGN.md "Threads of the operator station"):
// scans and robot states from the network thread -> local map in W -> an
// immutable OperatorModelSnapshot published to the servo thread through the
// ModelChannel (lock-free; retired snapshots are freed here, never on the
// servo thread).
//
// Inputs cross threads without locks: the network thread pushes wire
// RangeScans (shared, immutable) into an SPSC ring, the newest RobotState into
// a newest-wins mailbox, and every command it sends into another SPSC ring
// (the history the pose prediction integrates). A full ring drops the input
// and counts it. Each step() (model thread, model_rate_hz) drains them,
// converts and validates scans (a bad scan is counted and changes nothing),
// predicts the robot's present pose, slides the map window around it, and
// publishes a snapshot.
//
// Staleness. The model's age is how old its newest robot data is: now minus
// the newest RobotState or scan stamp (mapped into our clock). Normal data
// arrives a one-way delay (RTT / 2) after it was taken, so the model counts
// as fresh while its age is at most stale_after = RTT / 2 + fresh_s; beyond
// that it is going stale and the servo task fades its force to zero over
// fade_s (OperatorServoTask). stale_after is capped at the map's window age
// minus fade_s, so the force is gone before the map's segments age out.
//
// Live voxmap (params.live_voxmap): the robot's depth chunks (DepthChunk
// stream, newest cloud wins) are integrated into a LiveVoxmap in W, kept to
// a region of interest: with voxmap_roi kProbe a cube around the operator's
// 3D probe (mapping::follow_probe, with hysteresis; the servo publishes the
// probe's proxy through probe_positions(), a lock-free newest-wins mailbox),
// and ahead of the robot (voxmap_roi_R, moved with the predicted pose) while
// no probe is active (before the first tick, outside exploration) or with
// kRobot; at voxmap_rate_hz, when chunks came in, its signed
// vps::Voxmap is rebuilt on a voxmap thread of its own (never on the servo
// thread, and not holding up the 2D map) and every snapshot carries the
// newest one as a shared_ptr (freed off the servo thread when retired). A
// chunk of a new frame epoch (a restarted robot, its W anew) clears the
// voxmap and the stream's newest-cloud filter; chunks of an epoch replaced so
// (late or reordered) are dropped and counted.
//
// Robot restarts. The robot stamps its states and scans with its frame
// epoch (random per start of its odometry frame W). An epoch the model has
// not seen means the robot restarted and W with it: the model resynchronises.
// For fade_s it keeps publishing the old map with the pose frozen and
// `resyncing` set (the servo fades the force out and holds the robot) while
// the new epoch's data builds a fresh map; then it swaps in the fresh map and
// the new robot's state, drops the command history, and counts a resync
// (the task and the operator's hand restart from the robot's state).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "common/mapping/depth_registration.h"
#include "common/mapping/depth_stream.h"
#include "common/mapping/live_voxmap.h"
#include "common/mapping/local_map.h"
#include "common/mapping/voxmap_roi.h"
#include "common/mapping/shape_completion.h"
#include "operator/model/pose_prediction.h"
#include "operator/model/scan_convert.h"
#include "operator/model/scan_registration.h"
#include "common/concurrency/newest_mailbox.h"
#include "operator/servo/servo_loop.h"
#include "operator/servo/spsc_ring.h"

namespace hemm::op {

// What the servo thread sees. stamp_ns: the local time T_W_R was predicted for.
struct OperatorModelSnapshot final : servo::ModelSnapshot {
  mapping::MapSnapshot map;
  // Predicted robot pose at stamp_ns, in the map frame: odometry corrected by
  // scan registration, with the very correction the map's scans were placed
  // by (the robot and its map agree).
  math::Pose2 T_W_R;
  double v = 0.0;             // command acting at stamp_ns (for extrapolation)
  double omega = 0.0;
  bool have_state = false;    // false: no RobotState yet, T_W_R is the origin
  RobotStateSample state;     // the newest state, as received
  std::size_t segments = 0;   // map segments (before splitting into pieces)
  // Staleness (see the file comment): the newest robot data's stamp (local
  // clock; have_data false: none yet) and the thresholds for this snapshot.
  bool have_data = false;
  std::int64_t data_stamp_ns = 0;
  std::int64_t stale_after_ns = 0;
  std::int64_t fade_ns = 1;
  bool resyncing = false;       // a robot restart is being taken in: the map and pose are the old robot's
  std::uint64_t resyncs = 0;    // robot restarts taken in so far
  // The live voxmap (frame W), null until one was built (or live_voxmap off).
  std::shared_ptr<const vps::Voxmap> voxmap;
  std::uint64_t voxmap_builds = 0;  // which build it is
};

// Where the operator's 3D probe is (W), published by the servo thread every
// tick (newest wins); active false: no probe this tick (not exploring with
// probe_3d), the voxmap's ROI goes back ahead of the robot.
struct ProbePosition {
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  bool active = false;
};

// Where the live voxmap's region of interest is kept.
enum class VoxmapRoi { kRobot, kProbe };

struct ModelThreadParams {
  mapping::MapParams map;
  double rate_hz = 50.0;                 // snapshots per second (at most)
  std::size_t scan_queue = 256;          // power of two
  std::size_t command_queue = 1024;      // power of two
  std::size_t history = 4096;            // sent commands kept for prediction
  double max_prediction_s = 2.0;
  RegistrationParams registration;  // its correction-rate limit keeps the force smooth
  mapping::ShapeParams shapes;      // shape completion of the snapshot (enabled by default)
  double fresh_s = 0.25;   // model age beyond the one-way delay that still counts as fresh
  double fade_s = 1.0;     // a going-stale model's force fades to zero over this
  // The live voxmap from depth clouds (off: depth chunks are counted and dropped).
  bool live_voxmap = false;
  mapping::LiveVoxmapParams voxmap;  // its roi is replaced by the cube around the probe or by
                                     // voxmap_roi_R placed at the robot (voxmap_roi below;
                                     // apply_probe3d_config: normal_radius 5 cm for the mast's rows)
  // Region of interest in R (ahead of the robot, where the 3D probe reaches).
  Eigen::AlignedBox3d voxmap_roi_R{Eigen::Vector3d(0.25, -0.7, 0.3), Eigen::Vector3d(1.6, 0.7, 1.3)};
  // kProbe: a cube around the probe while one is active (voxmap_probe_roi),
  // voxmap_roi_R otherwise.
  VoxmapRoi voxmap_roi = VoxmapRoi::kRobot;
  mapping::ProbeRoiParams voxmap_probe_roi;
  double voxmap_rate_hz = 5.0;        // rebuilds per second at most
  std::size_t depth_queue = 256;      // power of two
  // Registration-corrected fusion (issue 24, mapping/depth_registration.h):
  // each depth frame registered against the newest snapshot's surface
  // before it is integrated (a frame is held until its last chunk).
  bool depth_registration = false;
  mapping::DepthRegistrationParams depth_registration_params;
  // The shape log (issue 24; empty: none): the voxmap thread writes every
  // rebuild's accepted 3D primitives to DIR/primitives.csv and the cells
  // they were fitted to to DIR/cells_<build>.f32 (mapping::cells_to_bytes),
  // so a rebuild can be compared with the scene and fitted again offline.
  std::string shape_log_dir;
};

// The live voxmap's figures (model thread, copied out under stats_mutex_).
struct VoxmapStats {
  mapping::DepthStreamCounters stream;
  std::uint64_t chunks_dropped = 0;     // queue full
  std::uint64_t chunks_integrated = 0;
  std::uint64_t builds = 0;
  std::size_t cells = 0, occupied_cells = 0;
  std::size_t memory_bytes = 0;         // the LiveVoxmap's cells
  std::size_t snapshot_bytes = 0;       // the newest vps::Voxmap
  double last_integrate_ms = 0.0, max_integrate_ms = 0.0;  // one step's chunks
  double last_build_ms = 0.0, max_build_ms = 0.0, sum_build_ms = 0.0;
  // The newest build's 3D shape completion and unknown space, and their CPU
  // per build (the voxmap thread's wall time inside the build: that thread
  // does nothing else meanwhile), max and summed over the builds.
  mapping::LiveVoxmapSnapshotReport newest;
  double max_completion_ms = 0.0, sum_completion_ms = 0.0;
  double max_unknown_ms = 0.0, sum_unknown_ms = 0.0;
  std::size_t free_space_bytes = 0;     // the free-space record (unknown_solid)
  std::uint64_t roi_moves = 0;          // times the region of interest was moved
  std::uint64_t restarts = 0;           // cleared for a restarted robot (new frame epoch)
  std::uint64_t old_epoch_chunks = 0;   // chunks of a robot that restarted since: dropped
  bool roi_on_probe = false;            // the ROI is around the probe (else ahead of the robot)
  mapping::DepthRegistrationStats registration;  // depth_registration on
};

// Shape completion (mapping::complete_shapes) as of the newest snapshot, and
// its cost: fits run on the model thread when the map changed.
struct ShapeStats {
  std::uint64_t fits = 0;
  std::size_t circles = 0, lines = 0, bridges = 0;
  std::size_t kept = 0;             // circles held from the previous fit (temporal coherence)
  std::size_t raw_replaced = 0;     // raw segments and shadow edges the circles stand for
  double max_circle_rms_m = 0.0;    // worst fit error among the rendered circles
  std::size_t rectangles = 0, rectangles_kept = 0;  // closed pillars and boxes, held ones among them
  double max_rectangle_rms_m = 0.0;
  double last_fit_ms = 0.0, max_fit_ms = 0.0;
  // Memory: the raw segments the circles replace against the circles'
  // parameters (centre, radius), and what the snapshot draws for them (the
  // outline pieces the proxy queries).
  std::size_t raw_replaced_bytes = 0, primitive_bytes = 0, outline_bytes = 0;
};

struct ModelStats {
  std::uint64_t scans_in = 0;        // converted and added
  std::uint64_t scans_rejected = 0;  // invalid: counted, map unchanged
  std::uint64_t scans_dropped = 0;   // queue full
  std::uint64_t states_in = 0;
  std::uint64_t states_rejected = 0;
  std::uint64_t commands_dropped = 0;
  std::uint64_t snapshots = 0;
  std::uint64_t freed = 0;
  LocalizerStats registration;   // scan registration: counts, fit, the correction (scans and pose)
  ShapeStats shapes;
  std::uint64_t resyncs = 0;          // robot restarts (new frame epochs) taken in
  std::uint64_t old_epoch_dropped = 0;  // states and scans of a robot that restarted
  VoxmapStats voxmap;
};

class ModelThread {
 public:
  // Throws std::invalid_argument on bad params.
  ModelThread(servo::ModelChannel& channel, const ModelThreadParams& p);
  ~ModelThread();
  ModelThread(const ModelThread&) = delete;
  ModelThread& operator=(const ModelThread&) = delete;

  // ---- network thread (one producer) ----
  void submit_scan(std::shared_ptr<const wire::RangeScan> scan);
  void submit_depth_chunk(std::shared_ptr<const wire::DepthChunk> chunk);
  void submit_state(const wire::RobotState& state);
  void record_command(const SentCommand& c);
  // ---- servo thread (one producer): where the 3D probe is (voxmap_roi kProbe) ----
  NewestMailbox<ProbePosition>& probe_positions() noexcept { return probe_box_; }
  // ---- any thread ----
  void set_clock_offset(std::int64_t robot_minus_local_ns) { offset_ns_.store(robot_minus_local_ns); }
  void set_command_delay(std::int64_t ns) { delay_ns_.store(ns); }
  ModelStats stats() const;

  // One iteration at local time now_ns (the thread calls it; tests may call
  // it directly while the thread is not running). Publishes a snapshot.
  void step(std::int64_t now_ns);

  // Called on the model thread with every snapshot just before it is
  // published (the live view copies what it draws). Set before start().
  using SnapshotObserver = std::function<void(const OperatorModelSnapshot&)>;
  void set_snapshot_observer(SnapshotObserver f) { observer_ = std::move(f); }
  // Called on the model thread after each step with what the step took (the
  // session recorder keeps it: submitting these inputs and stepping at
  // now_ns reproduces the snapshot). Set before start().
  struct StepInputs {
    std::int64_t now_ns = 0, offset_ns = 0, delay_ns = 0;
    std::vector<SentCommand> commands;
    std::optional<wire::RobotState> state;
    std::vector<std::shared_ptr<const wire::RangeScan>> scans;
  };
  using StepTap = std::function<void(const StepInputs&, const OperatorModelSnapshot&)>;
  void set_step_tap(StepTap f) { step_tap_ = std::move(f); }

  void start();
  void stop();  // idempotent; joins
  // Model-thread side (or after stop()): the map and the last error.
  const mapping::LocalMap& map() const { return map_; }
  // The newest live voxmap built (null: none); any thread but the servo's (locks).
  std::shared_ptr<const vps::Voxmap> newest_voxmap() {
    std::lock_guard<std::mutex> lock(voxmap_mu_);
    return voxmap_published_;
  }
  const std::string& last_error() const { return last_error_; }

 private:
  void run();

  servo::ModelChannel& channel_;
  ModelThreadParams p_;
  servo::SpscRing<std::shared_ptr<const wire::RangeScan>> scans_;
  servo::SpscRing<std::shared_ptr<const wire::DepthChunk>> depth_;
  servo::SpscRing<SentCommand> commands_;
  NewestMailbox<wire::RobotState> state_box_;
  NewestMailbox<ProbePosition> probe_box_;  // taken by the voxmap work only
  std::atomic<std::int64_t> offset_ns_{0}, delay_ns_{0};

  // Which robot (frame epoch) an input belongs to; routes it (resync).
  enum class Route { kCurrent, kNext, kDrop };
  Route route(std::uint64_t epoch, std::int64_t now_ns);
  void take_state(const RobotStateSample& s, bool next);
  void retire(std::uint64_t epoch);

  // model-thread state
  mapping::LocalMap map_;
  Localizer localizer_;
  CommandHistory history_;
  RobotStateSample state_;
  bool have_state_ = false;
  std::int64_t data_stamp_ns_ = 0;
  bool have_data_ = false;
  std::uint64_t epoch_ = 0;  // 0: none seen yet
  // During a resync: the new robot's data, swapped in at resync_end_ns_.
  bool resyncing_ = false;
  std::uint64_t next_epoch_ = 0;
  std::int64_t resync_end_ns_ = 0;
  mapping::LocalMap next_map_;
  RobotStateSample next_state_;
  bool next_have_state_ = false;
  std::int64_t next_data_stamp_ns_ = 0;
  bool next_have_data_ = false;
  math::Pose2 frozen_pose_;          // the pose published while resyncing
  math::Pose2 last_pose_;            // the last pose published
  std::array<std::uint64_t, 4> retired_epochs_{};  // robots that restarted: their data is dropped
  std::uint64_t version_ = 0;
  std::string last_error_;
  SnapshotObserver observer_;
  StepTap step_tap_;
  StepInputs tapped_;  // reused

  std::atomic<std::uint64_t> scans_in_{0}, scans_rejected_{0}, scans_dropped_{0}, states_in_{0},
      states_rejected_{0}, commands_dropped_{0}, snapshots_{0}, freed_{0}, resyncs_{0}, old_epoch_dropped_{0};
  // Registration figures for stats() (read from other threads).
  mutable std::mutex stats_mutex_;
  LocalizerStats reg_stats_;
  ShapeStats shape_stats_;            // under stats_mutex_
  mapping::ShapeModel shapes_;        // model thread: the newest completion
  std::int64_t shapes_stamp_ = std::numeric_limits<std::int64_t>::min();  // map state it was fitted on
  std::size_t shapes_size_ = 0;
  // Live voxmap: its own thread (voxmap_thread_, started with the model
  // thread) integrates and rebuilds, so a 100 ms rebuild never delays the 2D
  // map or makes the model stale; step() hands it the pose and takes the
  // newest build (both under voxmap_mu_, never the servo thread). Stepped by
  // hand (tests), step() does the voxmap work itself.
  void step_voxmap(std::int64_t now_ns);
  void run_voxmap();
  std::unique_ptr<mapping::LiveVoxmap> voxmap_;
  mapping::DepthStreamReceiver depth_rx_;
  mapping::DepthChunkData depth_chunk_;  // reused
  std::unique_ptr<mapping::DepthFrameRegistration> depth_reg_;  // depth_registration on
  mapping::RegistrationSurface reg_surface_;   // of the newest build
  std::vector<mapping::DepthChunkData> reg_ready_;  // reused
  bool voxmap_dirty_ = false, voxmap_roi_set_ = false;
  math::Pose2 voxmap_roi_pose_;
  std::optional<Eigen::AlignedBox3d> probe_roi_;  // the ROI around the probe, while it is followed
  std::uint64_t voxmap_epoch_ = 0;                // the frame epoch of the chunks in the voxmap (0: none yet)
  std::array<std::uint64_t, 4> voxmap_retired_epochs_{};
  std::int64_t voxmap_next_build_ns_ = 0;
  void log_shapes(std::uint64_t build, std::int64_t now_ns);  // shape_log_dir set
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> shape_log_{nullptr, &std::fclose};
  bool shape_log_failed_ = false;  // could not be opened: off, said once on stderr
  VoxmapStats voxmap_stats_;          // voxmap work only
  VoxmapStats voxmap_stats_out_;      // under stats_mutex_
  std::mutex voxmap_mu_;              // guards the four below
  math::Pose2 voxmap_pose_;
  bool voxmap_have_pose_ = false;
  std::int64_t voxmap_offset_ns_ = 0;
  std::shared_ptr<const vps::Voxmap> voxmap_published_;
  std::uint64_t voxmap_published_builds_ = 0;
  std::atomic<std::uint64_t> depth_dropped_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
  std::thread voxmap_thread_;
  std::atomic<bool> voxmap_threaded_{false};  // set before voxmap_thread_ starts, cleared after it joined
};

}  // namespace hemm::op
