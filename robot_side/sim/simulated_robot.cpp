#include "robot_side/sim/simulated_robot.h"

#include "robot_side/sim/sim_contact.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <numbers>
#include <mutex>
#include <random>
#include <thread>

#include "common/clock/steady_clock.h"

#include <mujoco/mujoco.h>

#include "common/config/config.h"
#include "common/sim/mujoco_owner.h"
#include "common/sim/mujoco_pose.h"
#include "config_robot.pb.h"
#include "robot_side/control/arm_control.h"
#include "robot_side/control/arm_keep_out.h"
#include "robot_side/control/collision_guard.h"
#include "robot_side/control/motion_gate.h"
#include "robot_side/control/seen_voxels.h"
#include "robot_side/control/watchdog.h"
#include "robot_side/sim/mujoco_ray_caster.h"

namespace hemm::robot {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr size_t kMaxQueuedScans = 64;
// SIMULATION ONLY: how far the tool's clearance to the world is measured.
constexpr double kArmClearanceRange = 0.10;
// The RobotState's refusal reason is the ArmRefusal's value.
static_assert(static_cast<int>(GazeRefusal::kNotFinite) == wire::GAZE_REFUSAL_NOT_FINITE &&
              static_cast<int>(GazeRefusal::kTooNear) == wire::GAZE_REFUSAL_TOO_NEAR &&
              static_cast<int>(GazeRefusal::kTooFar) == wire::GAZE_REFUSAL_TOO_FAR &&
              static_cast<int>(GazeRefusal::kPanLimit) == wire::GAZE_REFUSAL_PAN_LIMIT &&
              static_cast<int>(GazeRefusal::kTiltLimit) == wire::GAZE_REFUSAL_TILT_LIMIT);
static_assert(static_cast<int>(ArmRefusal::kFloor) == wire::ARM_REFUSAL_FLOOR &&
              static_cast<int>(ArmRefusal::kBase) == wire::ARM_REFUSAL_BASE &&
              static_cast<int>(ArmRefusal::kScene) == wire::ARM_REFUSAL_SCENE);

Eigen::Isometry3d pose_from(const mjtNum* pos, const mjtNum* quat) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << pos[0], pos[1], pos[2];
  T.linear() = Eigen::Quaterniond(quat[0], quat[1], quat[2], quat[3]).normalized().toRotationMatrix();
  return T;
}

Pose2 planar(const Eigen::Isometry3d& T) {
  return {T.translation().x(), T.translation().y(), std::atan2(T.linear()(1, 0), T.linear()(0, 0))};
}

bool finite_command(const BaseArmCommand& c) {
  return std::isfinite(c.v) && std::isfinite(c.omega) && c.arm_target_R.allFinite() && std::isfinite(c.wrist_pitch) &&
         std::isfinite(c.wrist_roll);
}

}  // namespace

SimLaserParams laser_params_from_config(const config::RobotConfig& c) {
  const auto& l = c.laser();
  SimLaserParams p;
  p.beams = static_cast<int>(l.beams());
  p.fov = l.fov_deg() * kDeg;
  p.range_min = l.range_min_m();
  p.range_max = l.range_max_m();
  p.sigma = l.sigma_m();
  p.rate_hz = l.rate_hz();
  p.dropout_probability = l.dropout_probability();
  p.T_R_S = Eigen::Isometry3d::Identity();
  p.T_R_S.translation() << l.mount_x_m(), 0.0, l.mount_z_m();
  return p;
}

SimSonarParams sonar_params_from_config(const config::RobotConfig& c) {
  const auto& s = c.sonar();
  SimSonarParams p;
  p.count = static_cast<int>(s.count());
  p.cone = s.cone_deg() * kDeg;
  p.rays_per_cone = static_cast<int>(s.rays_per_cone());
  p.range_min = s.range_min_m();
  p.range_max = s.range_max_m();
  p.sigma = s.sigma_m();
  p.rate_hz = s.rate_hz();
  p.dropout_probability = s.dropout_probability();
  p.T_R_S = Eigen::Isometry3d::Identity();
  p.T_R_S.translation() << 0.0, 0.0, 0.20;  // ring centre at bumper height
  return p;
}

// A depth frame into the robot's seen voxels (placed with its odometry
// pose), timed; returns the new points snapshot.
std::shared_ptr<const std::vector<Eigen::Vector3f>> integrate_seen(SeenVoxels& seen, const mapping::DepthImage& img,
                                                                    SeenVoxelsStats* st) {
  const int64_t t0 = steady_now_ns();
  seen.add_frame(img, img.T_W_S);
  auto pts = std::make_shared<std::vector<Eigen::Vector3f>>();
  seen.points(pts.get());
  const double us = static_cast<double>(steady_now_ns() - t0) * 1e-3;
  st->frames += 1;
  st->voxels = seen.size();
  st->memory_bytes = seen.memory_bytes();
  st->last_integrate_us = us;
  st->max_integrate_us = std::max(st->max_integrate_us, us);
  return pts;
}

// Casts depth frames on its own thread (DepthCasting::kWorker): one frame
// is 4800 mj_ray calls against every geom, several milliseconds, which would
// make the 1 kHz simulation thread late. The simulation thread hands over
// the geoms' poses of the step (a copy into the worker's own mjData: mj_ray
// reads only geom_xpos / geom_xmat there, and the const mjModel) and goes
// on; a frame due while the last is still being cast is skipped (counted),
// never waited for.
struct DepthWorker {
  const mjModel* m = nullptr;
  sim::MjDataPtr d;
  SimDepthCameraParams params;
  std::mt19937_64 rng;
  std::mutex mu;
  std::condition_variable cv;
  bool busy = false, have_job = false, stop = false;  // guarded by mu
  mapping::DepthImage job;                            // poses and stamp; guarded by mu
  std::deque<mapping::DepthImage> done;               // guarded by mu
  std::uint64_t skipped = 0;                          // simulation thread only
  // The robot's own seen voxels, integrated here (off the simulation
  // thread); each frame publishes a new points snapshot.
  SeenVoxels seen;                                    // worker thread only
  std::shared_ptr<const std::vector<Eigen::Vector3f>> seen_points;  // guarded by mu; null: taken
  SeenVoxelsStats seen_stats;                         // guarded by mu
  std::thread thread;

  DepthWorker(const mjModel* model, const SimDepthCameraParams& p, std::uint64_t seed, const SeenVoxelParams& sp)
      : m(model), d(mj_makeData(model)), params(p), rng(seed), seen(sp) {
    thread = std::thread([this] { run(); });
  }
  ~DepthWorker() {
    {
      std::lock_guard<std::mutex> lk(mu);
      stop = true;
    }
    cv.notify_one();
    thread.join();
  }
  // Simulation thread: never blocks on the worker.
  void submit(const mjData* src, mapping::DepthImage&& meta) {
    std::unique_lock<std::mutex> lk(mu, std::try_to_lock);
    if (!lk.owns_lock() || busy) {
      ++skipped;
      return;
    }
    mju_copy(d->geom_xpos, src->geom_xpos, 3 * m->ngeom);
    mju_copy(d->geom_xmat, src->geom_xmat, 9 * m->ngeom);
    job = std::move(meta);
    busy = have_job = true;
    lk.unlock();
    cv.notify_one();
  }
  void take(std::vector<mapping::DepthImage>* out) {
    std::unique_lock<std::mutex> lk(mu, std::try_to_lock);
    if (!lk.owns_lock()) return;  // next step
    for (auto& img : done) out->push_back(std::move(img));
    done.clear();
  }
  // Simulation thread: the newest seen points, if new (never blocks).
  void take_seen(std::shared_ptr<const std::vector<Eigen::Vector3f>>* out, SeenVoxelsStats* stats) {
    std::unique_lock<std::mutex> lk(mu, std::try_to_lock);
    if (!lk.owns_lock() || !seen_points) return;
    *out = std::move(seen_points);
    seen_points.reset();
    // The voxel figures; the checks' are the simulation thread's own.
    stats->frames = seen_stats.frames;
    stats->voxels = seen_stats.voxels;
    stats->memory_bytes = seen_stats.memory_bytes;
    stats->last_integrate_us = seen_stats.last_integrate_us;
    stats->max_integrate_us = seen_stats.max_integrate_us;
  }
  void run() {
    std::unique_lock<std::mutex> lk(mu);
    for (;;) {
      cv.wait(lk, [this] { return stop || have_job; });
      if (stop) return;
      have_job = false;
      mapping::DepthImage meta = std::move(job);
      lk.unlock();  // the simulation thread does not touch d while busy
      MujocoRayCaster caster(m, d.get());
      mapping::DepthImage img = simulate_depth_image(params, caster, meta.T_W_S_truth, rng);
      img.stamp_ns = meta.stamp_ns;
      img.cloud_id = meta.cloud_id;
      img.T_W_S = meta.T_W_S;
      img.T_W_S_truth = meta.T_W_S_truth;
      SeenVoxelsStats st = seen_stats;  // only this thread writes it
      auto pts = integrate_seen(seen, img, &st);
      lk.lock();
      seen_points = std::move(pts);
      seen_stats = st;
      done.push_back(std::move(img));
      while (done.size() > 4) done.pop_front();
      busy = false;
    }
  }
};

struct SimulatedRobot::Impl {
  sim::MjModelPtr m;
  sim::MjDataPtr d;

  // Model indices.
  int base_body = -1, arm_base_body = -1, floor_geom = -1, ee_site = -1;
  int base_qpos = 0, base_qvel = 0;
  std::array<int, 5> arm_qpos{}, arm_qvel{}, arm_act{};
  std::array<int, 4> wheel_qvel{}, wheel_act{};  // fl, rl, fr, rr

  kinematics::Arm5Model arm;
  Eigen::Isometry3d T_R_A = Eigen::Isometry3d::Identity();
  SkidSteerGeometry geometry;
  BaseLimits base_limits;
  ArmControlParams arm_params;
  CollisionGuardParams guard;
  SimLaserParams laser;
  SimSonarParams sonar;
  bool laser_on = true, sonar_on = true;
  int laser_period = 33, sonar_period = 100;
  SimDepthCameraParams depth;
  bool depth_on = false;
  int depth_period = 67;
  uint32_t depth_id = 0;
  std::deque<mapping::DepthImage> depth_images;
  std::unique_ptr<DepthWorker> depth_worker;  // DepthCasting::kWorker; declared after m, destroyed before it
  // The SIMULATED pan-tilt head (depth.pan_tilt): controller, plant, the
  // newest encoder reading (every step), and its own noise stream so the
  // other sensors' noise does not depend on whether there is a head.
  HeadControlState head_ctl;
  SimPanTiltHead head_plant;
  Eigen::Vector2d head_enc = Eigen::Vector2d::Zero();
  std::mt19937_64 head_rng{2};

  // Clock.
  int64_t origin_ns = 0, dt_ns = 1'000'000;
  int64_t steps = 0;

  // Command and safety state.
  Watchdog watchdog;
  BaseArmCommand command;
  bool have_arm_goal = false;
  kinematics::Arm5Vector arm_goal = kinematics::Arm5Vector::Zero();
  bool arm_goal_flagged = false;
  bool arm_holding = true;
  bool operator_in_control = false, estop = false, link_lost = false;
  // Re-arm (simulated_robot.h): armed once a neutral command and then a
  // pressed one came after the last stop.
  MotionGate gate;
  uint64_t rejected = 0;
  uint32_t safety = 0;

  // Controllers.
  BaseSetpoint setpoint;
  ArmControlState arm_state;
  Odometry odom;
  WheelSpeeds wheels_measured;

  // Sensors.
  std::mt19937_64 rng{1};
  uint32_t scan_id = 0;
  std::deque<RangeScanData> scans;
  // The newest laser and sonar scans as the guard keeps them (odometry W).
  struct GuardScan {
    std::vector<Eigen::Vector2d> ends_W;  // each beam's end at its known range
    std::vector<uint8_t> known, obstacle;
    std::vector<float> known_range;       // scratch
    double cone_half_angle = 0.0;
    bool ring = false;
    void clear() {
      ends_W.clear();
      known.clear();
      obstacle.clear();
    }
  };
  GuardScan laser_guard, sonar_guard;
  std::vector<Eigen::Vector2d> guard_points_R, guard_ends_R;  // scratch, refreshed every step
  KnownFree known_free{};
  ArmKeepOut arm_keep_out;
  SimulatedRobot::ArmRefusals arm_refusals;
  // The 3D keep-out: the seen voxels' points (frame: odometry W), from the
  // worker (kWorker) or integrated inline (kInline, tests).
  SeenVoxelParams seen_params;
  std::unique_ptr<SeenVoxels> seen_inline;
  std::shared_ptr<const std::vector<Eigen::Vector3f>> seen_points;
  SeenVoxelsStats seen_stats;
  std::vector<uint8_t> column_capped;  // scratch
  // SIMULATION ONLY: contacts of the arm with the world, and the tool's clearance.
  int arm_geom_first = -1, arm_geom_last = -1, tool_body = -1;
  SimulatedRobot::ArmContactStats arm_contacts;

  int64_t now() const { return origin_ns + steps * dt_ns; }

  Eigen::Isometry3d base_pose() const {
    return pose_from(d->qpos + base_qpos, d->qpos + base_qpos + 3);
  }

  kinematics::Arm5Vector q() const {
    kinematics::Arm5Vector v;
    for (int i = 0; i < 5; ++i) v(i) = d->qpos[arm_qpos[static_cast<size_t>(i)]];
    return v;
  }
  kinematics::Arm5Vector qd() const {
    kinematics::Arm5Vector v;
    for (int i = 0; i < 5; ++i) v(i) = d->qvel[arm_qvel[static_cast<size_t>(i)]];
    return v;
  }

  WheelSpeeds measure_wheels() const {
    const double r = geometry.wheel_radius;
    return {0.5 * r * (d->qvel[wheel_qvel[0]] + d->qvel[wheel_qvel[1]]),
            0.5 * r * (d->qvel[wheel_qvel[2]] + d->qvel[wheel_qvel[3]])};
  }

  bool is_robot_geom(int g) const { return g >= 0 && m->body_rootid[m->geom_bodyid[g]] == base_body; }

  void reset_dynamics_state() {
    setpoint = {};
    odom = {};
    const Pose2 p = planar(base_pose());
    odom.x = p.x;
    odom.y = p.y;
    odom.theta = p.theta;
    laser_guard.clear();
    sonar_guard.clear();
    guard_points_R.clear();
    reset_arm(arm_state, q());
    arm_holding = true;
    have_arm_goal = false;
  }

  // Dropouts are not free space: a short run of them is bounded by its
  // neighbours (2 laser beams, 1 sonar), a longer one is unknown.
  void store_guard_scan(const RangeScanData& s, GuardScan& g) const {
    const bool sonar = s.kind == RangeSensorKind::kSonar;
    g.ring = sonar;
    g.cone_half_angle = sonar ? 0.5 * s.beam_width : 0.0;
    g.known_range.resize(s.size());
    known_beam_ranges(s.ranges, s.valid, sonar ? 1 : 2, g.ring, g.known_range);
    g.ends_W.resize(s.size());
    g.known.resize(s.size());
    g.obstacle.resize(s.size());
    const double c = std::cos(odom.theta), sn = std::sin(odom.theta);
    for (size_t i = 0; i < s.size(); ++i) {
      const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
      const double r = std::max(0.0f, g.known_range[i]);
      const Eigen::Vector3d p_R = s.T_R_S * Eigen::Vector3d(r * std::cos(a), r * std::sin(a), 0);
      g.ends_W[i] = {odom.x + c * p_R.x() - sn * p_R.y(), odom.y + sn * p_R.x() + c * p_R.y()};
      g.known[i] = g.known_range[i] >= 0.0f;
      g.obstacle[i] = s.valid[i];
    }
  }

  void take_scan(bool is_laser) {
    MujocoRayCaster caster(m.get(), d.get());
    const Eigen::Isometry3d T_W_R = base_pose();
    RangeScanData s = is_laser ? simulate_laser_scan(laser, caster, T_W_R * laser.T_R_S, rng)
                               : simulate_sonar_scan(sonar, caster, T_W_R * sonar.T_R_S, rng);
    s.stamp_ns = now();
    s.scan_id = scan_id++;
    s.T_W_R_odom = {odom.x, odom.y, odom.theta};
    s.T_W_R_truth = planar(T_W_R);
    store_guard_scan(s, is_laser ? laser_guard : sonar_guard);
    scans.push_back(std::move(s));
    while (scans.size() > kMaxQueuedScans) scans.pop_front();
  }

  // The odometry pose in 3D (planar: the base height is the truth's).
  Eigen::Isometry3d T_W_R_odom3() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() << odom.x, odom.y, base_pose().translation().z();
    T.linear() = Eigen::AngleAxisd(odom.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
  }

  // The camera in R as the robot believes it (the head's encoders) and truly.
  Eigen::Isometry3d camera_T_R_S(bool truth) const {
    if (depth.pan_tilt) {
      return truth ? head_T_R_S(depth.head.head_R, head_plant.pan, head_plant.tilt)
                   : head_T_R_S(depth.head.head_R, head_enc.x(), head_enc.y());
    }
    return depth.mount_on_base ? depth.T_mount_S : T_R_A * kinematics::forward_kinematics(arm, q()) * depth.T_mount_S;
  }

  // A camera frame: cast from the true pose, reported with the pose the
  // robot believes (odometry, and the head's encoders of this step).
  void take_depth_image() {
    const Eigen::Isometry3d T_W_R = base_pose();
    mapping::DepthImage meta;
    meta.stamp_ns = now();
    meta.cloud_id = depth_id++;
    meta.T_W_S = T_W_R_odom3() * camera_T_R_S(false);
    meta.T_W_S_truth = T_W_R * camera_T_R_S(true);
    if (depth_worker) {
      depth_worker->submit(d.get(), std::move(meta));
      return;
    }
    MujocoRayCaster caster(m.get(), d.get());
    mapping::DepthImage img = simulate_depth_image(depth, caster, meta.T_W_S_truth, rng);
    img.stamp_ns = meta.stamp_ns;
    img.cloud_id = meta.cloud_id;
    img.T_W_S = meta.T_W_S;
    img.T_W_S_truth = meta.T_W_S_truth;
    if (seen_inline) seen_points = integrate_seen(*seen_inline, img, &seen_stats);
    depth_images.push_back(std::move(img));
    while (depth_images.size() > 4) depth_images.pop_front();
  }

  // The guard's footprint grows with the arm when it reaches out. The
  // stored scans are brought into R at the present odometry pose: the
  // returns (obstacles) and what they show free.
  GuardLimit guard_limit() {
    CollisionGuardParams g = guard;
    for (const Eigen::Vector3d& p_A : kinematics::arm_points(arm, q())) {
      const Eigen::Vector3d p = T_R_A * p_A;
      g.front_x = std::max(g.front_x, p.x() + 0.04);
      g.rear_x = std::min(g.rear_x, p.x() - 0.04);
      g.half_width = std::max(g.half_width, std::abs(p.y()) + 0.04);
    }
    guard_points_R.clear();
    known_free.fill(0.0);
    const double c = std::cos(odom.theta), sn = std::sin(odom.theta);
    for (const GuardScan* gs : {&laser_guard, &sonar_guard}) {
      guard_ends_R.resize(gs->ends_W.size());
      for (size_t i = 0; i < gs->ends_W.size(); ++i) {
        const Eigen::Vector2d dlt = gs->ends_W[i] - Eigen::Vector2d(odom.x, odom.y);
        guard_ends_R[i] = {c * dlt.x() + sn * dlt.y(), -sn * dlt.x() + c * dlt.y()};
        if (gs->obstacle[i]) guard_points_R.push_back(guard_ends_R[i]);
      }
      add_known_free(guard_ends_R, gs->known, gs->cone_half_angle, gs->ring, known_free);
    }
    return collision_guard(g, guard_points_R, &known_free);
  }

  // What the arm check sees now: the guard's columns (refreshed every step),
  // capped where the mast camera sees above them, and the newest seen points.
  SeenScene seen_scene() {
    SeenScene sc;
    sc.columns_R = guard_points_R;
    if (!depth_on) return sc;
    if (depth_worker) depth_worker->take_seen(&seen_points, &seen_stats);
    if (seen_points) sc.points_P = *seen_points;
    sc.T_P_R = T_W_R_odom3();
    if (depth.mount_on_base) {
      // A wrist camera moves with the arm: its columns stay infinite. (The
      // head's present view stands for the one the seen points came from.)
      const mapping::DepthIntrinsics K = depth.intrinsics();
      const Eigen::Isometry3d T_S_R = camera_T_R_S(false).inverse();
      const double top = laser.T_R_S.translation().z() + arm_keep_out.column_cap_margin;
      const double arm_top = T_R_A.translation().z() + arm.A2 + arm.A4 + arm.A5 + arm_keep_out.link_radius;
      column_capped.resize(guard_points_R.size());
      for (size_t i = 0; i < guard_points_R.size(); ++i)
        column_capped[i] = column_seen_from_above(K, T_S_R, guard_points_R[i], top, arm_top) ? 1 : 0;
      sc.column_capped = column_capped;
      sc.column_top_z = top;
    }
    return sc;
  }

  void disarm() { gate_disarm(gate); }

  // A command of the operator's, towards the re-arm: counted only once no
  // stop is in force. A pressed command after a neutral one arms.
  void rearm_with(const BaseArmCommand& c) {
    const bool neutral = !c.deadman || (c.mode != wire::MODE_NAVIGATION && c.mode != wire::MODE_MANIPULATION) ||
                         (c.mode == wire::MODE_NAVIGATION && c.v == 0.0 && c.omega == 0.0);
    gate_offer(gate, !operator_in_control || estop || link_lost, neutral, c.deadman);
  }

  void control_step() {
    const double dt = m->opt.timestep;
    const int64_t t = now();
    wheels_measured = measure_wheels();
    integrate_odometry(geometry, wheels_measured, dt, odom);

    uint32_t flags = 0;
    if (!operator_in_control) flags |= wire::SAFETY_NO_OPERATOR;
    const bool expired = watchdog_expired(watchdog, t);
    if (expired && operator_in_control) flags |= wire::SAFETY_WATCHDOG;
    if (estop) flags |= wire::SAFETY_ESTOP;
    if (link_lost) flags |= wire::SAFETY_LINK_LOST;
    if (!operator_in_control || expired || estop || link_lost) disarm();
    if (!gate.armed) flags |= wire::SAFETY_REARM;
    const bool may_move = gate.armed && command.deadman;

    // Base.
    double v_cmd = 0.0, w_cmd = 0.0;
    if (may_move && command.mode == wire::MODE_NAVIGATION) {
      v_cmd = command.v;
      w_cmd = command.omega;
    }
    const GuardLimit gl = guard_limit();
    const double v_guarded = std::clamp(v_cmd, -gl.max_backward, gl.max_forward);
    const double w_guarded = std::clamp(w_cmd, -gl.max_yaw_cw, gl.max_yaw_ccw);
    if (v_guarded != v_cmd || setpoint.v > gl.max_forward || -setpoint.v > gl.max_backward ||
        w_guarded != w_cmd || setpoint.omega > gl.max_yaw_ccw || -setpoint.omega > gl.max_yaw_cw)
      flags |= wire::SAFETY_COLLISION_GUARD;
    if (estop) {
      setpoint = {};
    } else {
      setpoint = slew_setpoint(base_limits, setpoint, v_guarded, w_guarded, dt);
      // Braking for the guard may exceed the comfort slew: never run faster
      // than the guard allows.
      setpoint.v = std::clamp(setpoint.v, -gl.max_backward, gl.max_forward);
      setpoint.omega = std::clamp(setpoint.omega, -gl.max_yaw_cw, gl.max_yaw_ccw);
    }
    const WheelSpeeds ws = wheel_speeds(geometry, setpoint);
    const double r = geometry.wheel_radius;
    d->ctrl[wheel_act[0]] = d->ctrl[wheel_act[1]] = ws.left / r;
    d->ctrl[wheel_act[2]] = d->ctrl[wheel_act[3]] = ws.right / r;

    // Arm.
    const bool arm_moves = may_move && command.mode == wire::MODE_MANIPULATION && have_arm_goal;
    if (arm_moves) {
      arm_state.q_goal = arm_goal;
      arm_holding = false;
    } else if (!arm_holding) {
      hold_arm(arm_state);
      arm_holding = true;
    }
    if (arm_goal_flagged) flags |= wire::SAFETY_JOINT_LIMIT;
    kinematics::Arm5Vector bias;
    for (int i = 0; i < 5; ++i) bias(i) = d->qfrc_bias[arm_qvel[static_cast<size_t>(i)]];
    const kinematics::Arm5Vector tau = arm_control_step(arm_params, arm_state, q(), qd(), bias, dt);
    for (int i = 0; i < 5; ++i) d->ctrl[arm_act[static_cast<size_t>(i)]] = tau(i);

    // The pan-tilt head follows the operator's gaze while in control and
    // the link and the command watchdog are good, holds at the e-stop, and
    // goes home otherwise (head_control.h).
    if (depth_on && depth.pan_tilt) {
      const bool may_follow = operator_in_control && !link_lost && !expired;
      head_control_step(depth.head, head_ctl, T_W_R_odom3(), may_follow, estop, t, dt);
      head_plant.step(depth.head, head_ctl.pan_sp, head_ctl.tilt_sp, dt);
      head_enc = head_plant.read_encoders(head_rng);
    }
    safety = flags;
  }

  bool is_arm_geom(int g) const { return g >= arm_geom_first && g <= arm_geom_last; }

  // SIMULATION ONLY. The arm's geoms carry a margin with an equal gap
  // (load()): MuJoCo reports every world geom within that margin as an
  // inactive contact (exclude = 1, no force) with its distance, so the
  // tool's true clearance is read off the contacts; a contact with
  // exclude = 0 is a real one.
  void count_arm_contacts() {
    bool touching = false;
    double clearance = kArmClearanceRange;
    for (int i = 0; i < d->ncon; ++i) {
      const mjContact& c = d->contact[i];
      const bool a1 = is_arm_geom(c.geom1), a2 = is_arm_geom(c.geom2);
      if (a1 == a2) continue;
      const int other = a1 ? c.geom2 : c.geom1;
      if (is_robot_geom(other)) continue;
      if (c.exclude == 0) {
        touching = true;
        ++arm_contacts.contacts;
      }
      const int mine = a1 ? c.geom1 : c.geom2;
      if (m->geom_bodyid[mine] == tool_body) clearance = std::min(clearance, static_cast<double>(c.dist));
    }
    if (touching) ++arm_contacts.contact_steps;
    arm_contacts.tool_min_clearance = std::min(arm_contacts.tool_min_clearance, clearance);
    arm_contacts.tool_clearance = clearance;
  }

  void step_once() {
    // qfrc_bias must match the current state: mj_step1 computes it (and the
    // rest of the position/velocity stages) before the controller reads it.
    mj_step1(m.get(), d.get());
    control_step();
    mj_step2(m.get(), d.get());
    ++steps;
    count_arm_contacts();
    if (laser_on && steps % laser_period == 0) take_scan(true);
    if (sonar_on && steps % sonar_period == 0) take_scan(false);
    if (depth_on && steps % depth_period == 0) take_depth_image();
  }
};

SimulatedRobot::SimulatedRobot() = default;
SimulatedRobot::~SimulatedRobot() = default;
SimulatedRobot::SimulatedRobot(SimulatedRobot&&) noexcept = default;
SimulatedRobot& SimulatedRobot::operator=(SimulatedRobot&&) noexcept = default;

std::optional<std::string> SimulatedRobot::load(const config::RobotConfig& cfg, const std::string& scene_path) {
  if (scene_path.empty() || !std::filesystem::is_regular_file(scene_path))
    return "scene file not found: " + scene_path;
  if (const auto issues = config::validate_robot_config(cfg); !issues.empty())
    return "config: " + issues.front().field + ": " + issues.front().message;
  auto impl = std::make_unique<Impl>();
  try {
    impl->m = sim::load_model_file(scene_path);
  } catch (const std::runtime_error& e) {
    return std::string("MuJoCo could not load ") + e.what();  // "PATH: MuJoCo's message"
  }
  mjModel* m = impl->m.get();
  m->opt.timestep = cfg.sim().timestep_s();
  impl->d.reset(mj_makeData(m));
  if (!impl->d) return "MuJoCo could not allocate data";

  auto id = [&](int type, const char* name) { return mj_name2id(m, type, name); };
  impl->base_body = id(mjOBJ_BODY, "base_link");
  impl->arm_base_body = id(mjOBJ_BODY, "arm_base");
  impl->ee_site = id(mjOBJ_SITE, "ee");
  impl->floor_geom = id(mjOBJ_GEOM, "floor");
  if (impl->base_body < 0 || impl->arm_base_body < 0 || impl->ee_site < 0)
    return "scene lacks the robot (base_link, arm_base, ee): does it include robot.xml?";
  const int free_jnt = m->body_jntadr[impl->base_body];
  if (free_jnt < 0 || m->jnt_type[free_jnt] != mjJNT_FREE) return "base_link needs a free joint";
  impl->base_qpos = m->jnt_qposadr[free_jnt];
  impl->base_qvel = m->jnt_dofadr[free_jnt];
  if (m->body_parentid[impl->arm_base_body] != impl->base_body) return "arm_base must be a child of base_link";

  // The arm: joints, actuators, and the link lengths of Eq. 3 read from the
  // MJCF; the chain must have the structure the kinematics assumes.
  const char* link_names[5] = {"arm_link1", "arm_link2", "arm_link3", "arm_link4", "arm_link5"};
  const Eigen::Vector3d axes[5] = {{0, 0, 1}, {0, -1, 0}, {0, -1, 0}, {-1, 0, 0}, {0, 1, 0}};
  double offsets[5] = {};
  for (int i = 0; i < 5; ++i) {
    const auto k = static_cast<size_t>(i);
    const std::string jn = "arm_q" + std::to_string(i + 1);
    const std::string an = "arm_tau" + std::to_string(i + 1);
    const int j = id(mjOBJ_JOINT, jn.c_str());
    const int a = id(mjOBJ_ACTUATOR, an.c_str());
    const int b = id(mjOBJ_BODY, link_names[i]);
    if (j < 0 || a < 0 || b < 0) return "robot.xml lacks " + jn + ", " + an + " or " + link_names[i];
    if (m->jnt_type[j] != mjJNT_HINGE || !m->jnt_limited[j] || m->jnt_bodyid[j] != b)
      return jn + " must be a limited hinge of " + link_names[i];
    const Eigen::Vector3d ax(m->jnt_axis[3 * j], m->jnt_axis[3 * j + 1], m->jnt_axis[3 * j + 2]);
    const mjtNum* bp = m->body_pos + 3 * b;
    const mjtNum* bq = m->body_quat + 4 * b;
    if ((ax - axes[i]).norm() > 1e-9 || std::abs(bp[1]) > 1e-12 || std::abs(bp[2]) > 1e-12 ||
        std::abs(bq[0] - 1) > 1e-12)
      return std::string("robot.xml: ") + link_names[i] + " does not follow the chain of Eq. 2-4";
    offsets[i] = bp[0];
    impl->arm_qpos[k] = m->jnt_qposadr[j];
    impl->arm_qvel[k] = m->jnt_dofadr[j];
    impl->arm_act[k] = a;
    impl->arm.q_min(i) = m->jnt_range[2 * j];
    impl->arm.q_max(i) = m->jnt_range[2 * j + 1];
  }
  if (std::abs(offsets[0]) > 1e-12 || std::abs(offsets[4]) > 1e-12) return "robot.xml: arm_link1/5 must sit at 0";
  const mjtNum* sp = m->site_pos + 3 * impl->ee_site;
  if (m->site_bodyid[impl->ee_site] != id(mjOBJ_BODY, "arm_link5") || std::abs(sp[1]) > 1e-12 ||
      std::abs(sp[2]) > 1e-12)
    return "robot.xml: site ee must lie on the x axis of arm_link5";
  impl->arm.A1 = offsets[1];
  impl->arm.A2 = offsets[2];
  impl->arm.A4 = offsets[3];
  impl->arm.A5 = sp[0];
  if (auto e = kinematics::validate(impl->arm)) return "robot.xml arm: " + *e;
  impl->T_R_A = pose_from(m->body_pos + 3 * impl->arm_base_body, m->body_quat + 4 * impl->arm_base_body);
  // SIMULATION ONLY: the arm's geoms (arm_base's subtree: MuJoCo numbers a
  // body's descendants after it, geoms in body order) get a margin and an
  // equal gap, so world geoms within kArmClearanceRange show up as inactive
  // contacts carrying their distance (count_arm_contacts); no force changes.
  impl->tool_body = id(mjOBJ_BODY, "arm_link5");
  for (int g = 0; g < m->ngeom; ++g) {
    int b = m->geom_bodyid[g];
    while (b > 0 && b != impl->arm_base_body) b = m->body_parentid[b];
    if (b != impl->arm_base_body) continue;
    if (impl->arm_geom_first < 0) impl->arm_geom_first = g;
    if (impl->arm_geom_last >= 0 && impl->arm_geom_last != g - 1) return "robot.xml: the arm's geoms must be consecutive";
    impl->arm_geom_last = g;
    m->geom_margin[g] = kArmClearanceRange;
    m->geom_gap[g] = kArmClearanceRange;
  }

  const char* wheels[4] = {"wheel_fl", "wheel_rl", "wheel_fr", "wheel_rr"};
  for (int i = 0; i < 4; ++i) {
    const int j = id(mjOBJ_JOINT, wheels[i]);
    const int a = id(mjOBJ_ACTUATOR, (std::string(wheels[i]) + "_vel").c_str());
    const int g = id(mjOBJ_GEOM, wheels[i]);
    if (j < 0 || a < 0 || g < 0) return std::string("robot.xml lacks wheel ") + wheels[i];
    impl->wheel_qvel[static_cast<size_t>(i)] = m->jnt_dofadr[j];
    impl->wheel_act[static_cast<size_t>(i)] = a;
    if (i == 0) impl->geometry.wheel_radius = m->geom_size[3 * g];
  }
  {
    const int fl = id(mjOBJ_BODY, "wheel_fl"), fr = id(mjOBJ_BODY, "wheel_fr");
    impl->geometry.track_width = m->body_pos[3 * fl + 1] - m->body_pos[3 * fr + 1];
  }

  // Config.
  impl->base_limits = {cfg.base().max_speed_mps(), cfg.base().max_yaw_rate_rps(), cfg.base().max_accel_mps2(),
                       cfg.base().max_yaw_accel_rps2()};
  impl->arm_params = {cfg.arm().kp(), cfg.arm().kd(), cfg.arm().max_joint_speed_rps(),
                      cfg.arm().max_joint_torque_nm()};
  impl->guard.margin = cfg.safety().collision_margin_m();
  impl->guard.reaction_time = cfg.safety().guard_reaction_time_s();
  impl->geometry.slip_factor = cfg.base().skid_slip_factor();
  impl->guard.max_decel = cfg.base().max_accel_mps2();
  impl->guard.max_yaw_decel = cfg.base().max_yaw_accel_rps2();
  impl->watchdog.timeout_ns = static_cast<int64_t>(cfg.safety().watchdog_ms()) * 1'000'000;
  impl->laser = laser_params_from_config(cfg);
  impl->sonar = sonar_params_from_config(cfg);
  impl->laser_on = cfg.laser().enabled();
  impl->sonar_on = cfg.sonar().enabled();
  impl->dt_ns = std::llround(m->opt.timestep * 1e9);
  impl->laser_period = std::max(1, static_cast<int>(std::lround(1.0 / (impl->laser.rate_hz * m->opt.timestep))));
  impl->sonar_period = std::max(1, static_cast<int>(std::lround(1.0 / (impl->sonar.rate_hz * m->opt.timestep))));
  impl->rng.seed(cfg.sim().seed());
  impl->head_rng.seed(cfg.sim().seed() ^ 0x9e3779b97f4a7c15ull);

  // Start pose: the scene's site "robot_start", else the origin.
  mj_resetData(m, impl->d.get());
  Pose2 start;
  const int start_site = id(mjOBJ_SITE, "robot_start");
  if (start_site >= 0) start = planar(pose_from(m->site_pos + 3 * start_site, m->site_quat + 4 * start_site));
  if (cfg.sim().has_start_x_m() || cfg.sim().has_start_y_m() || cfg.sim().has_start_theta_rad())
    start = {cfg.sim().start_x_m(), cfg.sim().start_y_m(), cfg.sim().start_theta_rad()};
  impl_ = std::move(impl);
  set_base_pose_sim(start);
  // The arm starts folded over the base (inside the footprint), or where the
  // config says (SIMULATION ONLY).
  kinematics::Arm5Vector q0 = (kinematics::Arm5Vector() << 0, 1.2, -2.2, 0, 0).finished();
  if (cfg.sim().start_arm_q_size() == 5)
    for (int i = 0; i < 5; ++i) q0(i) = cfg.sim().start_arm_q(i);
  set_arm_q_sim(kinematics::clamp_to_limits(impl_->arm, q0));
  return std::nullopt;
}

bool SimulatedRobot::loaded() const { return impl_ != nullptr; }

void SimulatedRobot::set_time_origin_ns(int64_t o) {
  if (impl_) impl_->origin_ns = o - impl_->steps * impl_->dt_ns;
}
int64_t SimulatedRobot::time_ns() const { return impl_ ? impl_->now() : 0; }
int64_t SimulatedRobot::timestep_ns() const { return impl_ ? impl_->dt_ns : 0; }

void SimulatedRobot::step(int n) {
  if (!impl_) return;
  for (int i = 0; i < n; ++i) impl_->step_once();
}

int SimulatedRobot::step_until(int64_t t_ns, int max_steps) {
  int n = 0;
  while (impl_ && n < max_steps && impl_->now() < t_ns) {
    impl_->step_once();
    ++n;
  }
  return n;
}

std::optional<std::string> SimulatedRobot::set_command(const BaseArmCommand& c, int64_t now_ns) {
  if (!impl_) return "robot not loaded";
  Impl& s = *impl_;
  const auto reject = [&](std::string why) -> std::optional<std::string> {
    ++s.rejected;
    return why;
  };
  if (!finite_command(c)) return reject("command has non-finite values");
  if (c.mode < wire::MODE_IDLE || c.mode > wire::MODE_EXPLORATION) return reject("command has an unknown mode");
  if (c.arm_target_R.norm() > 10.0) return reject("arm target farther than 10 m");
  if (std::abs(c.wrist_pitch) > 10.0 || std::abs(c.wrist_roll) > 10.0) return reject("wrist angles out of range");
  if (c.gaze.present && !c.gaze.point_W.allFinite()) return reject("gaze target not finite");
  // The gaze goes to the head whatever the arm's checks decide below (its
  // own checks refuse a bad target: counted in the head's state).
  if (c.gaze.present && s.depth_on && s.depth.pan_tilt)
    head_gaze_command(s.depth.head, s.head_ctl, c.gaze.point_W, c.gaze.active, s.T_W_R_odom3(), c.seq, now_ns);
  // A command after the watchdog expired comes after a stop (the step may
  // not have seen the expiry yet).
  if (watchdog_expired(s.watchdog, now_ns)) s.disarm();
  // Without the deadman the arm holds whatever the target says (a held
  // operator sends none: (0, 0, 0), which is in the base): nothing to solve.
  if (c.mode == wire::MODE_MANIPULATION && c.deadman) {
    const kinematics::Arm5Target t{s.T_R_A.inverse() * c.arm_target_R, c.wrist_pitch, c.wrist_roll};
    const kinematics::Arm5Vector seed = s.have_arm_goal ? s.arm_goal : s.arm_state.q_ref;
    kinematics::IkResult ik = kinematics::inverse_kinematics(s.arm, t, seed);
    if (ik.status == kinematics::IkStatus::kInvalidInput) return reject("arm target rejected by IK");
    // The pose the arm would go to (the IK's nearest reachable one) must stay
    // out of the floor, the base and what the sensors have seen.
    const SeenScene seen = s.seen_scene();
    const auto check = [&](const kinematics::Arm5Vector& q, const ArmKeepOut& keep_out) {
      std::array<Eigen::Vector3d, 5> chain;
      chain[0] = s.T_R_A.translation();
      const auto joints = kinematics::arm_points(s.arm, q);
      for (size_t i = 0; i < joints.size(); ++i) chain[i + 1] = s.T_R_A * joints[i];
      const int64_t t0 = steady_now_ns();
      const ArmRefusal r = check_arm_chain(keep_out, chain, seen);
      const double us = static_cast<double>(steady_now_ns() - t0) * 1e-3;
      s.seen_stats.checks += 1;
      s.seen_stats.max_check_us = std::max(s.seen_stats.max_check_us, us);
      s.seen_stats.sum_check_us += us;
      return r;
    };
    // The arm gets there along its reference's path (arm_control.h), not in
    // one jump: the goal is checked first (its refusal names what the target
    // itself is in), then the poses on the way, every kPathStep rad of the
    // fastest joint (with all five joints turning, the tool moves at most
    // ~1.9 cm between two checks). On the way the links must stay out of
    // contact (their radius, and the seen points' pad for the gaps between
    // samples); the clearance is kept where the arm will hold still (the
    // folded arm itself is 5-10 mm inside it, by the laser head). A keep-out
    // the path starts in may be left, not entered anew.
    ArmKeepOut on_the_way = s.arm_keep_out;
    on_the_way.clearance = 0.0;
    const auto check_path = [&](const kinematics::Arm5Vector& q_to) {
      constexpr double kPathStep = 0.015;
      if (const ArmRefusal end = check(q_to, s.arm_keep_out); end != ArmRefusal::kNone) return end;
      const kinematics::Arm5Vector q0 = s.arm_state.q_ref;
      const double span = (q_to - q0).cwiseAbs().maxCoeff();
      const int n = static_cast<int>(std::ceil(span / kPathStep));
      ArmRefusal leaving = n > 1 ? check(q0, on_the_way) : ArmRefusal::kNone;
      for (int k = 1; k < n; ++k) {
        const ArmRefusal r = check(arm_reference_after(q0, q_to, span * k / n), on_the_way);
        if (r == ArmRefusal::kNone) {
          leaving = ArmRefusal::kNone;
        } else if (r != leaving) {
          return r;
        }
      }
      return ArmRefusal::kNone;
    };
    ArmRefusal why = check_path(ik.q);
    if (why == ArmRefusal::kBase || why == ArmRefusal::kScene) {
      // The IK follows its seed: from the folded arm it may bring the elbow
      // down onto the base where the elbow-up solution of the same target is
      // clear. Try that one before refusing.
      kinematics::Arm5Vector up;
      up << std::atan2(t.p_A_E.y(), t.p_A_E.x()), 0.9, -1.4, c.wrist_roll, 0.0;
      const kinematics::IkResult alt = kinematics::inverse_kinematics(s.arm, t, kinematics::clamp_to_limits(s.arm, up));
      if (alt.status == ik.status && check_path(alt.q) == ArmRefusal::kNone) {
        ik = alt;
        why = ArmRefusal::kNone;
      }
    }
    if (why != ArmRefusal::kNone) {
      ++(why == ArmRefusal::kFloor ? s.arm_refusals.floor
         : why == ArmRefusal::kBase ? s.arm_refusals.base
                                    : s.arm_refusals.scene);
      s.arm_refusals.last = why;
      s.arm_refusals.last_seq = c.seq;
      return reject(to_string(why));
    }
    s.arm_goal = ik.q;
    s.have_arm_goal = true;
    s.arm_goal_flagged = ik.status != kinematics::IkStatus::kConverged;
  }
  s.command = c;
  watchdog_feed(s.watchdog, now_ns);
  s.rearm_with(c);
  return std::nullopt;
}

void SimulatedRobot::stop_commanded_motion(uint64_t seq) {
  if (!impl_) return;
  BaseArmCommand neutral;
  neutral.mode = wire::MODE_IDLE;
  neutral.seq = seq;
  impl_->command = neutral;
}

bool SimulatedRobot::armed() const { return impl_ && impl_->gate.armed; }

uint64_t SimulatedRobot::rejected_commands() const { return impl_ ? impl_->rejected : 0; }
SimulatedRobot::ArmRefusals SimulatedRobot::arm_refusals() const { return impl_ ? impl_->arm_refusals : ArmRefusals{}; }
SeenVoxelsStats SimulatedRobot::seen_voxels_stats() const { return impl_ ? impl_->seen_stats : SeenVoxelsStats{}; }
SimulatedRobot::ArmContactStats SimulatedRobot::arm_contacts_sim() const {
  return impl_ ? impl_->arm_contacts : ArmContactStats{};
}
// Each stop disarms at once: a stop set and cleared between two steps still counts.
void SimulatedRobot::set_operator_in_control(bool b) {
  if (!impl_) return;
  impl_->operator_in_control = b;
  if (!b) impl_->disarm();
}
void SimulatedRobot::set_estop(bool b) {
  if (!impl_) return;
  impl_->estop = b;
  if (b) impl_->disarm();
}
bool SimulatedRobot::estop() const { return impl_ && impl_->estop; }
void SimulatedRobot::set_link_lost(bool b) {
  if (!impl_) return;
  impl_->link_lost = b;
  if (b) impl_->disarm();
}

RobotStateSim SimulatedRobot::state() const {
  RobotStateSim st;
  if (!impl_) return st;
  const Impl& s = *impl_;
  st.stamp_ns = s.now();
  st.T_W_R_odom = {s.odom.x, s.odom.y, s.odom.theta};
  const Eigen::Isometry3d T_W_R = s.base_pose();
  st.T_W_R_truth = planar(T_W_R);
  // Free joint: linear velocity in the world frame, angular in the body frame.
  const mjtNum* qv = s.d->qvel + s.base_qvel;
  const Eigen::Vector3d lin(qv[0], qv[1], qv[2]);
  const Eigen::Vector3d ang = T_W_R.linear() * Eigen::Vector3d(qv[3], qv[4], qv[5]);
  st.v_truth = lin.dot(T_W_R.linear().col(0));
  st.omega_truth = ang.z();
  const WheelSpeeds w = s.measure_wheels();
  const BaseSetpoint odo = body_motion(s.geometry, w);
  st.v = odo.v;
  st.omega = odo.omega;
  st.wheel_left = w.left;
  st.wheel_right = w.right;
  st.q = s.q();
  st.qd = s.qd();
  for (int i = 0; i < 5; ++i) st.tau(i) = s.d->actuator_force[s.arm_act[static_cast<size_t>(i)]];
  st.T_R_E = s.T_R_A * kinematics::forward_kinematics(s.arm, st.q);
  st.safety = s.safety;
  st.mode = s.command.mode;
  st.last_command_seq = s.command.seq;
  st.arm_refusals = s.arm_refusals.floor + s.arm_refusals.base + s.arm_refusals.scene;
  st.last_arm_refusal = static_cast<int>(s.arm_refusals.last);
  st.last_refused_seq = s.arm_refusals.last_seq;
  if (s.depth_on && s.depth.pan_tilt) {
    HeadStateSim& h = st.head;
    h.present = true;
    h.pan = s.head_enc.x();
    h.tilt = s.head_enc.y();
    h.pan_setpoint = s.head_ctl.pan_sp;
    h.tilt_setpoint = s.head_ctl.tilt_sp;
    h.gaze_active = s.head_ctl.following;
    h.gaze_refusals = s.head_ctl.refusals;
    h.last_gaze_refusal = static_cast<int>(s.head_ctl.last_refusal);
    h.last_gaze_refused_seq = s.head_ctl.last_refused_seq;
    h.pan_truth = s.head_plant.pan;
    h.tilt_truth = s.head_plant.tilt;
  }
  return st;
}

std::vector<RangeScanData> SimulatedRobot::take_scans() {
  std::vector<RangeScanData> out;
  if (!impl_) return out;
  out.reserve(impl_->scans.size());
  for (auto& s : impl_->scans) out.push_back(std::move(s));
  impl_->scans.clear();
  return out;
}

const kinematics::Arm5Model& SimulatedRobot::arm_model() const {
  static const kinematics::Arm5Model kDefault;
  return impl_ ? impl_->arm : kDefault;
}
Eigen::Isometry3d SimulatedRobot::T_R_A() const { return impl_ ? impl_->T_R_A : Eigen::Isometry3d::Identity(); }
const SimLaserParams& SimulatedRobot::laser_params() const {
  static const SimLaserParams kDefault;
  return impl_ ? impl_->laser : kDefault;
}
const SimSonarParams& SimulatedRobot::sonar_params() const {
  static const SimSonarParams kDefault;
  return impl_ ? impl_->sonar : kDefault;
}
const SkidSteerGeometry& SimulatedRobot::base_geometry() const {
  static const SkidSteerGeometry kDefault;
  return impl_ ? impl_->geometry : kDefault;
}
void SimulatedRobot::enable_sensors(bool laser, bool sonar) {
  if (!impl_) return;
  impl_->laser_on = laser;
  impl_->sonar_on = sonar;
}

std::optional<std::string> SimulatedRobot::enable_depth_camera(const SimDepthCameraParams& params,
                                                               DepthCasting casting) {
  if (!impl_) return "depth camera: no scene loaded";
  if (auto e = check_params(params)) return e;
  if (!params.T_mount_S.matrix().allFinite()) return "depth camera: mount not finite";
  if (params.pan_tilt) {
    if (auto e = check(params.head)) return "depth camera: " + *e;
    if (auto e = check(params.head_plant)) return "depth camera: " + *e;
  }
  impl_->depth_worker.reset();
  impl_->seen_inline.reset();
  impl_->seen_points.reset();
  impl_->seen_stats = {};
  if (casting == DepthCasting::kWorker)
    impl_->depth_worker = std::make_unique<DepthWorker>(impl_->m.get(), params, impl_->rng(), impl_->seen_params);
  else
    impl_->seen_inline = std::make_unique<SeenVoxels>(impl_->seen_params);
  impl_->depth = params;
  if (params.pan_tilt) {
    impl_->depth.mount_on_base = true;
    impl_->head_ctl = head_control_init(params.head);
    impl_->head_plant.params = params.head_plant;
    impl_->head_plant.pan = params.head.home_pan;
    impl_->head_plant.tilt = params.head.home_tilt;
    impl_->head_enc = impl_->head_plant.read_encoders(impl_->head_rng);
  }
  impl_->depth_period =
      std::max(1, static_cast<int>(std::lround(1.0 / (params.rate_hz * impl_->m->opt.timestep))));
  impl_->depth_on = true;
  return std::nullopt;
}

void SimulatedRobot::disable_depth_camera() {
  if (!impl_) return;
  impl_->depth_on = false;
  impl_->depth_worker.reset();
  impl_->seen_inline.reset();
  impl_->seen_points.reset();
}

std::vector<mapping::DepthImage> SimulatedRobot::take_depth_images() {
  std::vector<mapping::DepthImage> out;
  if (!impl_) return out;
  for (auto& img : impl_->depth_images) out.push_back(std::move(img));
  impl_->depth_images.clear();
  if (impl_->depth_worker) impl_->depth_worker->take(&out);
  return out;
}

std::uint64_t SimulatedRobot::depth_frames_skipped() const {
  return impl_ && impl_->depth_worker ? impl_->depth_worker->skipped : 0;
}

SimDepthCameraParams depth_camera_params_from_config(const config::RobotConfig& c) {
  const auto& dc = c.depth_camera();
  SimDepthCameraParams p;
  p.width = static_cast<int>(dc.width());
  p.height = static_cast<int>(dc.height());
  p.hfov = dc.hfov_deg() * kDeg;
  p.range_min = dc.range_min_m();
  p.range_max = dc.range_max_m();
  p.rate_hz = dc.rate_hz();
  p.mount_on_base = dc.mount() == "mast" || dc.mount() == "pan-tilt";
  if (p.mount_on_base) p.T_mount_S = SimDepthCameraParams::mast_mount(dc.mast_x_m(), dc.mast_z_m(), dc.mast_pitch_deg() * kDeg);
  if (dc.mount() == "pan-tilt") {
    p.pan_tilt = true;
    HeadParams& h = p.head;
    h.head_R = Eigen::Vector3d(dc.mast_x_m(), dc.head_y_m(), dc.mast_z_m());
    h.pan_min = dc.pan_min_deg() * kDeg;
    h.pan_max = dc.pan_max_deg() * kDeg;
    h.tilt_min = dc.tilt_min_deg() * kDeg;
    h.tilt_max = dc.tilt_max_deg() * kDeg;
    h.home_pan = 0.0;
    h.home_tilt = dc.mast_pitch_deg() * kDeg;
    h.max_rate = dc.head_rate_dps() * kDeg;
    h.min_range = dc.gaze_min_range_m();
    h.max_range = dc.gaze_max_range_m();
    h.gaze_timeout_ns = static_cast<int64_t>(dc.gaze_timeout_ms()) * 1'000'000;
    p.head_plant.time_constant = dc.head_time_constant_s();
    p.head_plant.pan_bias = dc.pan_bias_deg() * kDeg;
    p.head_plant.tilt_bias = dc.tilt_bias_deg() * kDeg;
    p.head_plant.encoder_sigma = dc.encoder_sigma_deg() * kDeg;
    p.T_mount_S = head_T_R_S(h.head_R, h.home_pan, h.home_tilt);
  }
  return p;
}

void SimulatedRobot::set_base_pose_sim(const Pose2& p) {
  if (!impl_ || !std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.theta)) return;
  Impl& s = *impl_;
  mjtNum* qp = s.d->qpos + s.base_qpos;
  qp[0] = p.x;
  qp[1] = p.y;
  qp[2] = 0.0;
  qp[3] = std::cos(0.5 * p.theta);
  qp[4] = 0.0;
  qp[5] = 0.0;
  qp[6] = std::sin(0.5 * p.theta);
  for (int i = 0; i < 6; ++i) s.d->qvel[s.base_qvel + i] = 0.0;
  for (int w : s.wheel_qvel) s.d->qvel[w] = 0.0;
  mj_forward(s.m.get(), s.d.get());
  s.reset_dynamics_state();
}

void SimulatedRobot::set_arm_q_sim(const kinematics::Arm5Vector& q) {
  if (!impl_ || !q.allFinite()) return;
  Impl& s = *impl_;
  for (int i = 0; i < 5; ++i) {
    s.d->qpos[s.arm_qpos[static_cast<size_t>(i)]] = q(i);
    s.d->qvel[s.arm_qvel[static_cast<size_t>(i)]] = 0.0;
  }
  mj_forward(s.m.get(), s.d.get());
  reset_arm(s.arm_state, q);
  s.arm_holding = true;
  s.have_arm_goal = false;
}

Eigen::Isometry3d SimulatedRobot::mujoco_T_A_E_sim() const {
  if (!impl_) return Eigen::Isometry3d::Identity();
  const Impl& s = *impl_;
  // Kinematics only: the site and body poses of the current qpos.
  mj_kinematics(s.m.get(), s.d.get());
  const Eigen::Isometry3d T_W_A = sim::mujoco_pose(s.d->xpos + 3 * s.arm_base_body, s.d->xmat + 9 * s.arm_base_body);
  const Eigen::Isometry3d T_W_E = sim::mujoco_pose(s.d->site_xpos + 3 * s.ee_site, s.d->site_xmat + 9 * s.ee_site);
  return T_W_A.inverse() * T_W_E;
}

int SimulatedRobot::robot_contacts_sim(const std::string& world_geom) const {
  if (!impl_) return 0;
  const Impl& s = *impl_;
  const int target = world_geom.empty() ? -1 : mj_name2id(s.m.get(), mjOBJ_GEOM, world_geom.c_str());
  if (!world_geom.empty() && target < 0) return 0;
  int n = 0;
  for (int i = 0; i < s.d->ncon; ++i) {
    const mjContact& c = s.d->contact[i];
    if (c.exclude != 0) continue;  // the arm's clearance probes (inactive), not contacts
    const bool r1 = s.is_robot_geom(c.geom1), r2 = s.is_robot_geom(c.geom2);
    if (r1 == r2) continue;
    const int other = r1 ? c.geom2 : c.geom1;
    if (target >= 0 ? other == target : other != s.floor_geom) ++n;
  }
  return n;
}

void SimulatedRobot::view_frame_sim(SimViewFrame* out) const {
  if (!impl_ || out == nullptr) return;
  const Impl& s = *impl_;
  out->t_ns = time_ns();
  out->qpos.assign(s.d->qpos, s.d->qpos + s.m->nq);
  out->contacts.clear();
  SimContact c;
  for (int i = 0; i < s.d->ncon; ++i)
    if (sim_contact(s.m.get(), s.d.get(), i, &c)) out->contacts.push_back(c);
}

bool sim_contact(const mjModel_* m, const mjData_* d, int i, SimContact* out) noexcept {
  const mjContact& c = d->contact[i];
  if (c.exclude != 0) return false;
  mjtNum f[6];
  mj_contactForce(m, d, i, f);
  // The contact frame's rows are its axes (normal first) in W.
  const Eigen::Map<const Eigen::Matrix<mjtNum, 3, 3, Eigen::RowMajor>> frame(c.frame);
  out->pos_W = Eigen::Vector3d(c.pos[0], c.pos[1], c.pos[2]);
  out->force_W = frame.transpose() * Eigen::Vector3d(f[0], f[1], f[2]);
  out->geom1 = c.geom1;
  out->geom2 = c.geom2;
  return true;
}

}  // namespace hemm::robot
