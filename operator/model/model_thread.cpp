#include "operator/model/model_thread.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/voxmap.h"

namespace hemm::op {
namespace {
}  // namespace

ModelThread::ModelThread(servo::ModelChannel& channel, const ModelThreadParams& p)
    : channel_(channel),
      p_(p),
      scans_(p.scan_queue),
      depth_(p.depth_queue),
      commands_(p.command_queue),
      localizer_(p.registration),
      history_(p.history) {
  if (std::string e = mapping::validate(p.map); !e.empty()) throw std::invalid_argument("ModelThread: " + e);
  if (std::string e = validate(p.registration); !e.empty()) throw std::invalid_argument("ModelThread: " + e);
  if (std::string e = mapping::validate(p.shapes); !e.empty()) throw std::invalid_argument("ModelThread: " + e);
  if (!(p.rate_hz > 0.0 && p.rate_hz <= 1000.0)) throw std::invalid_argument("ModelThread: rate_hz outside (0, 1000]");
  if (!(p.fresh_s >= 0.0 && p.fade_s > 0.0 && p.fade_s < 60.0 && p.fresh_s < 60.0))
    throw std::invalid_argument("ModelThread: need fresh_s >= 0 and fade_s > 0 (both under a minute)");
  if (p.live_voxmap) {
    mapping::LiveVoxmapParams vp = p.voxmap;
    vp.roi = p.voxmap_roi_R;  // placed at the robot once a pose is known
    if (auto e = mapping::LiveVoxmap::check(vp)) throw std::invalid_argument("ModelThread: live voxmap: " + *e);
    if (p.voxmap_roi == VoxmapRoi::kProbe) {
      if (auto e = mapping::check(p.voxmap_probe_roi)) throw std::invalid_argument("ModelThread: live voxmap: " + *e);
    }
    if (!(p.voxmap_rate_hz > 0.0 && p.voxmap_rate_hz <= 100.0))
      throw std::invalid_argument("ModelThread: voxmap_rate_hz outside (0, 100]");
    voxmap_ = std::make_unique<mapping::LiveVoxmap>(vp);
    if (p.depth_registration) {
      if (auto e = mapping::check(p.depth_registration_params)) throw std::invalid_argument("ModelThread: " + *e);
      depth_reg_ = std::make_unique<mapping::DepthFrameRegistration>(p.depth_registration_params);
    }
  }
}

ModelThread::~ModelThread() { stop(); }

void ModelThread::submit_scan(std::shared_ptr<const wire::RangeScan> scan) {
  if (!scan) return;
  if (!scans_.try_push(std::move(scan))) scans_dropped_.fetch_add(1, std::memory_order_relaxed);
}

void ModelThread::submit_depth_chunk(std::shared_ptr<const wire::DepthChunk> chunk) {
  if (!chunk) return;
  if (!depth_.try_push(std::move(chunk))) depth_dropped_.fetch_add(1, std::memory_order_relaxed);
}

void ModelThread::submit_state(const wire::RobotState& state) { state_box_.publish(state); }

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
  s.shapes = shape_stats_;
  s.resyncs = resyncs_.load();
  s.old_epoch_dropped = old_epoch_dropped_.load();
  s.voxmap = voxmap_stats_out_;
  s.voxmap.chunks_dropped = depth_dropped_.load();
  return s;
}

void ModelThread::retire(std::uint64_t epoch) {
  std::rotate(retired_epochs_.rbegin(), retired_epochs_.rbegin() + 1, retired_epochs_.rend());
  retired_epochs_[0] = epoch;
}

ModelThread::Route ModelThread::route(std::uint64_t epoch, std::int64_t now_ns) {
  if (epoch == 0 || (epoch == epoch_ && !resyncing_)) return Route::kCurrent;  // 0: a robot without epochs
  if (epoch_ == 0) {
    epoch_ = epoch;
    return Route::kCurrent;
  }
  if (std::find(retired_epochs_.begin(), retired_epochs_.end(), epoch) != retired_epochs_.end() ||
      (resyncing_ && epoch == epoch_)) {
    old_epoch_dropped_.fetch_add(1, std::memory_order_relaxed);
    return Route::kDrop;  // a robot that has restarted since
  }
  if (resyncing_ && epoch == next_epoch_) return Route::kNext;
  // A robot we have not seen: it restarted (again, if a resync was under way).
  if (resyncing_) retire(next_epoch_);
  resyncing_ = true;
  next_epoch_ = epoch;
  resync_end_ns_ = now_ns + static_cast<std::int64_t>(p_.fade_s * 1e9);
  next_map_ = mapping::LocalMap{};
  next_have_state_ = next_have_data_ = false;
  frozen_pose_ = last_pose_;
  history_.clear();  // the commands the old robot was given
  return Route::kNext;
}

void ModelThread::take_state(const RobotStateSample& s, bool next) {
  RobotStateSample& st = next ? next_state_ : state_;
  bool& have = next ? next_have_state_ : have_state_;
  if (have && s.stamp_local_ns < st.stamp_local_ns) return;  // older than what we have
  st = s;
  have = true;
  std::int64_t& data = next ? next_data_stamp_ns_ : data_stamp_ns_;
  bool& have_data = next ? next_have_data_ : have_data_;
  data = have_data ? std::max(data, s.stamp_local_ns) : s.stamp_local_ns;
  have_data = true;
  states_in_.fetch_add(1);
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
    } else if (const Route r = route(ws.frame_epoch(), now_ns); r != Route::kDrop) {
      take_state(s, r == Route::kNext);
    }
  }
  std::shared_ptr<const wire::RangeScan> m;
  mapping::RangeScan2D scan;
  localizer_.begin_step();
  while (scans_.try_pop(m)) {
    if (step_tap_) tapped_.scans.push_back(m);
    std::optional<std::string> e = scan_from_wire(*m, offset, &scan);
    const std::uint64_t epoch = m->frame_epoch();
    m.reset();  // the ring slot keeps a copy of the pointer until overwritten; drop ours now
    const Route r = e ? Route::kCurrent : route(epoch, now_ns);
    if (r == Route::kDrop) continue;
    const bool next = r == Route::kNext;
    if (!e) {
      // Placed by the corrected odometry, registered against the map; the
      // correction it ends with is the one the published pose uses, and a
      // scan whose correction was cut to the rate limit is kept out of the
      // map. A restarted robot's scans (next) are in its new odometry frame
      // and its map starts empty: placed by its odometry alone.
      if (next || !localizer_.place(scan, map_).limited) {
        std::string err = mapping::add_scan(p_.map, next ? next_map_ : map_, scan);
        if (!err.empty()) e = std::move(err);
      }
    }
    if (e) {
      scans_rejected_.fetch_add(1);
      last_error_ = *e;
      continue;
    }
    scans_in_.fetch_add(1);
    std::int64_t& data = next ? next_data_stamp_ns_ : data_stamp_ns_;
    bool& have_data = next ? next_have_data_ : have_data_;
    data = have_data ? std::max(data, scan.stamp_ns) : scan.stamp_ns;
    have_data = true;
  }
  if (resyncing_ && now_ns >= resync_end_ns_) {
    // The old robot's force has faded: the new robot's map and state take over.
    map_ = std::move(next_map_);
    next_map_ = mapping::LocalMap{};
    state_ = next_state_;
    have_state_ = next_have_state_;
    data_stamp_ns_ = next_data_stamp_ns_;
    have_data_ = next_have_data_;
    localizer_.restart();  // a new odometry frame: no correction yet
    retire(epoch_);
    epoch_ = next_epoch_;
    resyncing_ = false;
    resyncs_.fetch_add(1);
  }

  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    reg_stats_ = localizer_.stats();
  }
  auto snap = std::make_unique<OperatorModelSnapshot>();
  snap->stamp_ns = now_ns;
  snap->version = ++version_;
  snap->have_state = have_state_;
  if (resyncing_) {
    snap->T_W_R = frozen_pose_;  // v = omega = 0: held where the old robot was last seen
    snap->state = state_;
  } else if (have_state_) {
    PredictionInput in{localizer_.correct(state_.T_W_R_odom), state_.stamp_local_ns, state_.v, state_.omega};
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
  last_pose_ = snap->T_W_R;
  if (voxmap_) {
    {
      std::lock_guard<std::mutex> lock(voxmap_mu_);
      voxmap_pose_ = snap->T_W_R;
      voxmap_have_pose_ = have_state_ && !resyncing_;
      voxmap_offset_ns_ = offset;
    }
    if (!voxmap_threaded_.load(std::memory_order_acquire)) step_voxmap(now_ns);  // stepped by hand (tests)
    std::lock_guard<std::mutex> lock(voxmap_mu_);
    snap->voxmap = voxmap_published_;
    snap->voxmap_builds = voxmap_published_builds_;
  } else {
    std::shared_ptr<const wire::DepthChunk> chunk;
    while (depth_.try_pop(chunk)) chunk.reset();  // no live voxmap: the stream is not used
  }
  snap->have_data = have_data_;
  snap->data_stamp_ns = data_stamp_ns_;
  const double stale_after_s =
      std::min(static_cast<double>(delay) * 1e-9 + p_.fresh_s, std::max(0.0, p_.map.window_age_s - p_.fade_s));
  snap->stale_after_ns = static_cast<std::int64_t>(stale_after_s * 1e9);
  snap->fade_ns = std::max<std::int64_t>(1, static_cast<std::int64_t>(p_.fade_s * 1e9));
  snap->resyncing = resyncing_;
  snap->resyncs = resyncs_.load();
  mapping::slide_window(p_.map, map_, now_ns, math::translation(snap->T_W_R));
  if (p_.shapes.enabled) {
    // Refit only when the map changed (a new scan, or the window slid).
    if (map_.newest_stamp_ns != shapes_stamp_ || map_.segments.size() != shapes_size_) {
      const std::int64_t t0 = steady_now_ns();
      mapping::complete_shapes(p_.shapes, p_.map, map_, shapes_);
      const double ms = static_cast<double>(steady_now_ns() - t0) * 1e-6;
      shapes_stamp_ = map_.newest_stamp_ns;
      shapes_size_ = map_.segments.size();
      ShapeStats st;
      st.circles = shapes_.circles.size();
      st.lines = shapes_.lines.size();
      st.bridges = shapes_.bridges;
      st.kept = shapes_.kept;
      st.raw_replaced = shapes_.raw_replaced;
      for (const mapping::FittedCircle& fc : shapes_.circles) st.max_circle_rms_m = std::max(st.max_circle_rms_m, fc.rms);
      st.rectangles = shapes_.rectangles.size();
      st.rectangles_kept = shapes_.kept_rectangles;
      for (const mapping::FittedRectangle& fr : shapes_.rectangles)
        st.max_rectangle_rms_m = std::max(st.max_rectangle_rms_m, fr.rms);
      st.raw_replaced_bytes = shapes_.raw_replaced * sizeof(mapping::Segment2);
      // A rectangle: corner, axis, two sides (6 doubles), drawn as 4 pieces.
      st.primitive_bytes = (shapes_.circles.size() * 3 + shapes_.rectangles.size() * 6) * sizeof(double);
      st.outline_bytes = (shapes_.circles.size() * static_cast<std::size_t>(p_.shapes.circle_pieces) +
                          shapes_.rectangles.size() * 4) * sizeof(mapping::Segment2);
      std::lock_guard<std::mutex> lock(stats_mutex_);
      st.fits = shape_stats_.fits + 1;
      st.last_fit_ms = ms;
      st.max_fit_ms = std::max(shape_stats_.max_fit_ms, ms);
      shape_stats_ = st;
    }
    snap->map = mapping::build_snapshot(p_.map, shapes_.segments, map_.newest_stamp_ns);
  } else {
    snap->map = mapping::build_snapshot(p_.map, map_);
  }
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

void ModelThread::step_voxmap(std::int64_t now_ns) {
  math::Pose2 T_W_R;
  bool have_pose = false;
  std::int64_t offset_ns = 0;
  {
    std::lock_guard<std::mutex> lock(voxmap_mu_);
    T_W_R = voxmap_pose_;
    have_pose = voxmap_have_pose_;
    offset_ns = voxmap_offset_ns_;
  }
  VoxmapStats st = voxmap_stats_;  // written only here
  // The region of interest: around the probe while one is active (kProbe),
  // else ahead of the robot, moved only when the robot did (moving it drops
  // what falls outside).
  std::optional<Eigen::AlignedBox3d> roi_W;
  if (p_.voxmap_roi == VoxmapRoi::kProbe) {
    const ProbePosition* probe = probe_box_.take();
    if (probe == nullptr) probe = probe_box_.latest();
    if (probe != nullptr && probe->active) {
      const std::optional<Eigen::AlignedBox3d> next = mapping::follow_probe(p_.voxmap_probe_roi, probe_roi_, probe->p_W);
      if (next && (!probe_roi_ || next->min() != probe_roi_->min() || next->max() != probe_roi_->max())) roi_W = next;
      probe_roi_ = next;
    } else if (probe_roi_) {
      probe_roi_.reset();
      voxmap_roi_set_ = false;  // back ahead of the robot
    }
  }
  const double moved = std::hypot(T_W_R.x - voxmap_roi_pose_.x, T_W_R.y - voxmap_roi_pose_.y);
  const double turned = std::abs(std::remainder(T_W_R.theta - voxmap_roi_pose_.theta, 2.0 * std::numbers::pi));
  if (!probe_roi_ && have_pose && (!voxmap_roi_set_ || moved > 0.05 || turned > 0.05)) {
    Eigen::AlignedBox3d box;
    const Eigen::Matrix2d R = Eigen::Rotation2Dd(T_W_R.theta).toRotationMatrix();
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d q = p_.voxmap_roi_R.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c));
      const Eigen::Vector2d xy = R * q.head<2>() + Eigen::Vector2d(T_W_R.x, T_W_R.y);
      box.extend(Eigen::Vector3d(xy.x(), xy.y(), q.z()));
    }
    roi_W = box;
    voxmap_roi_pose_ = T_W_R;
  }
  if (roi_W) {
    voxmap_->set_roi(*roi_W);
    voxmap_roi_set_ = true;
    voxmap_dirty_ = true;
    ++st.roi_moves;
  }
  st.roi_on_probe = probe_roi_.has_value();
  const std::int64_t t0 = steady_now_ns();
  std::uint64_t integrated = 0;
  std::shared_ptr<const wire::DepthChunk> m;
  // On its own thread, integration yields to the rebuild after half a
  // rebuild period: where chunks arrive faster than they integrate (a
  // loaded machine), draining the queue in one go held the rebuild off for
  // 11-32 s of a 60 s route (max_integrate_ms, explore3d beside builds) and
  // the tool felt a model that old. What stays queued waits for the next
  // step; a full queue drops the newest chunks (counted).
  const auto integrate_budget_ns = static_cast<std::int64_t>(0.5e9 / p_.voxmap_rate_hz);
  const bool budgeted = voxmap_threaded_.load(std::memory_order_acquire);
  while ((!budgeted || steady_now_ns() - t0 < integrate_budget_ns) && depth_.try_pop(m)) {
    const std::uint64_t epoch = m->frame_epoch();
    if (epoch != 0 && epoch != voxmap_epoch_) {
      if (std::find(voxmap_retired_epochs_.begin(), voxmap_retired_epochs_.end(), epoch) != voxmap_retired_epochs_.end()) {
        ++st.old_epoch_chunks;  // a robot that has restarted since
        m.reset();
        continue;
      }
      if (voxmap_epoch_ != 0) {
        // The robot restarted: its W is new, what the voxmap holds is in the old one.
        std::rotate(voxmap_retired_epochs_.rbegin(), voxmap_retired_epochs_.rbegin() + 1, voxmap_retired_epochs_.rend());
        voxmap_retired_epochs_[0] = voxmap_epoch_;
        *voxmap_ = mapping::LiveVoxmap(voxmap_->params());
        depth_rx_.restart();
        if (depth_reg_) {
          depth_reg_->clear();
          reg_surface_ = {};
        }
        voxmap_dirty_ = false;
        ++st.restarts;
        std::shared_ptr<const vps::Voxmap> retired;  // released after the lock
        std::lock_guard<std::mutex> lock(voxmap_mu_);
        retired = std::exchange(voxmap_published_, nullptr);
      }
      voxmap_epoch_ = epoch;
    }
    const auto verdict = depth_rx_.receive(*m, offset_ns, &depth_chunk_);
    m.reset();
    if (verdict != mapping::DepthStreamReceiver::Verdict::kAccepted) continue;
    if (!voxmap_roi_set_) continue;  // no pose yet: the ROI is not placed
    if (depth_reg_) {
      reg_ready_.clear();
      depth_reg_->add(depth_chunk_, &reg_surface_, &reg_ready_);
      for (const mapping::DepthChunkData& c : reg_ready_) voxmap_->integrate(c);
      integrated += reg_ready_.size();
      st.registration = depth_reg_->stats();
    } else {
      voxmap_->integrate(depth_chunk_);
      ++integrated;
    }
  }
  if (integrated > 0) {
    const double ms = static_cast<double>(steady_now_ns() - t0) * 1e-6;
    st.last_integrate_ms = ms;
    st.max_integrate_ms = std::max(st.max_integrate_ms, ms);
    st.chunks_integrated += integrated;
    voxmap_dirty_ = true;
  }
  st.stream = depth_rx_.counters();
  if (voxmap_dirty_ && now_ns >= voxmap_next_build_ns_) {
    voxmap_next_build_ns_ = now_ns + static_cast<std::int64_t>(1e9 / p_.voxmap_rate_hz);
    voxmap_dirty_ = false;
    const std::int64_t b0 = steady_now_ns();
    auto vm = std::make_shared<vps::Voxmap>();
    std::shared_ptr<const vps::Voxmap> retired;  // released after the lock
    if (!voxmap_->snapshot(vm.get(), &steady_now_ns)) {
      if (depth_reg_) mapping::surface_from_voxmap(*vm, &reg_surface_);
      st.snapshot_bytes = vm->memory_bytes();
      ++st.builds;
      // The shape completion and unknown space of this build, and their cost.
      st.newest = voxmap_->snapshot_report();
      const double cms = 1e-6 * static_cast<double>(st.newest.completion_ns);
      const double ums = 1e-6 * static_cast<double>(st.newest.unknown_ns);
      st.max_completion_ms = std::max(st.max_completion_ms, cms);
      st.sum_completion_ms += cms;
      st.max_unknown_ms = std::max(st.max_unknown_ms, ums);
      st.sum_unknown_ms += ums;
      st.free_space_bytes = voxmap_->free_space_bytes();
      if (!p_.shape_log_dir.empty()) log_shapes(st.builds, now_ns);
      std::lock_guard<std::mutex> lock(voxmap_mu_);
      retired = std::exchange(voxmap_published_, std::move(vm));
      voxmap_published_builds_ = st.builds;
    } else if (voxmap_->occupied_cells() == 0) {
      std::lock_guard<std::mutex> lock(voxmap_mu_);
      retired = std::exchange(voxmap_published_, nullptr);  // everything was cleared (or left the ROI)
    }
    const double ms = static_cast<double>(steady_now_ns() - b0) * 1e-6;
    st.last_build_ms = ms;
    st.max_build_ms = std::max(st.max_build_ms, ms);
    st.sum_build_ms += ms;
  }
  st.cells = voxmap_->cells();
  st.occupied_cells = voxmap_->occupied_cells();
  st.memory_bytes = voxmap_->memory_bytes();
  voxmap_stats_ = st;
  std::lock_guard<std::mutex> lock(stats_mutex_);
  voxmap_stats_out_ = st;
}

void ModelThread::log_shapes(std::uint64_t build, std::int64_t now_ns) {
  // Off the servo thread (the voxmap thread); a file that cannot be written
  // leaves the log off (said once), the model unchanged.
  if (!shape_log_) {
    if (shape_log_failed_) return;
    shape_log_.reset(std::fopen((p_.shape_log_dir + "/primitives.csv").c_str(), "w"));
    if (!shape_log_) {
      shape_log_failed_ = true;
      std::fprintf(stderr, "shape log: cannot write %s/primitives.csv: off\n", p_.shape_log_dir.c_str());
      return;
    }
    std::fprintf(shape_log_.get(), "build,t_ns,cells,objects,refused_free,refused_inside,support_nx,support_ny,support_nz,support_d,%s\n",
                 mapping::primitive_csv_header().c_str());
  }
  const mapping::Shape3dModel& sm = voxmap_->shapes();
  const auto& cells = voxmap_->shape_samples();
  char head[256];
  std::snprintf(head, sizeof head, "%llu,%lld,%zu,%zu,%zu,%zu,%.4f,%.4f,%.4f,%.5f", static_cast<unsigned long long>(build),
                static_cast<long long>(now_ns), cells.size(), sm.objects, sm.refused_free, sm.refused_inside, sm.support[0], sm.support[1],
                sm.support[2], sm.support[3]);
  for (const mapping::Primitive3& q : sm.primitives)
    std::fprintf(shape_log_.get(), "%s,%s\n", head, mapping::primitive_csv_row(q).c_str());
  if (sm.primitives.empty()) std::fprintf(shape_log_.get(), "%s,none%s\n", head, std::string(18, ',').c_str());
  std::fflush(shape_log_.get());
  char name[64];
  std::snprintf(name, sizeof name, "/cells_%05llu.f32", static_cast<unsigned long long>(build));
  std::ofstream(p_.shape_log_dir + name, std::ios::binary) << mapping::cells_to_bytes(cells);
}

void ModelThread::run_voxmap() {
  // Depth chunks arrive at ~180 per second; a 10 ms poll keeps the voxmap
  // within a frame of them without spinning.
  while (!stop_.load()) {
    step_voxmap(steady_now_ns());
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

void ModelThread::start() {
  if (thread_.joinable()) throw std::logic_error("ModelThread already running");
  stop_.store(false);
  // The voxmap thread first, and the flag before either: step() must never
  // do the voxmap work while that thread does.
  if (voxmap_) {
    voxmap_threaded_.store(true, std::memory_order_release);
    voxmap_thread_ = std::thread([this] { run_voxmap(); });
  }
  thread_ = std::thread([this] { run(); });
}

void ModelThread::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  if (voxmap_thread_.joinable()) voxmap_thread_.join();
  voxmap_threaded_.store(false, std::memory_order_release);
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
