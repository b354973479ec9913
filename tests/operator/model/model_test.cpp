// Wire -> RangeScan2D conversion (validation, chunks, clock offset) and the
// model thread's step (map, rejects, prediction, snapshots).
#include <gtest/gtest.h>
#include <numbers>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "common/haptics/vps/voxmap.h"
#include "operator/model/model_thread.h"

namespace ho = hemm::op;
namespace hw = hemm::wire;
namespace hm = hemm::math;

namespace {

// A laser at the robot origin facing +x sees a wall x = wall_x (robot frame),
// beams over [-60, 60] deg; chunk = beams [first, first + n).
hw::RangeScan wall_scan(double wall_x, hm::Pose2 T_W_R, std::int64_t stamp, std::uint32_t first = 0,
                        std::uint32_t n = 121) {
  hw::RangeScan m;
  m.set_stamp_ns(stamp);
  m.set_scan_id(1);
  m.set_sensor(hw::RANGE_SENSOR_LASER);
  m.mutable_t_w_r()->set_x(T_W_R.x);
  m.mutable_t_w_r()->set_y(T_W_R.y);
  m.mutable_t_w_r()->set_theta(T_W_R.theta);
  m.mutable_t_r_s()->mutable_orientation()->set_w(1.0);
  const double a0 = -std::numbers::pi / 3, step = std::numbers::pi / 180;
  m.set_angle_min(a0);
  m.set_angle_step(step);
  m.set_beam_count(121);
  m.set_first_beam(first);
  m.set_range_min(0.05);
  m.set_range_max(10.0);
  for (std::uint32_t i = first; i < first + n; ++i) {
    m.add_ranges(static_cast<float>(wall_x / std::cos(a0 + i * step)));
    m.add_valid(true);
  }
  return m;
}

TEST(ScanFromWire, ConvertsChunksAndMapsTheClock) {
  hw::RangeScan m = wall_scan(1.0, {0.5, -0.2, 0.1}, 5'000'000'000, 30, 40);
  const double yaw = 0.25;
  m.mutable_t_r_s()->mutable_position()->set_x(0.2);
  m.mutable_t_r_s()->mutable_orientation()->set_w(std::cos(yaw / 2));
  m.mutable_t_r_s()->mutable_orientation()->set_z(std::sin(yaw / 2));
  hemm::mapping::RangeScan2D s;
  ASSERT_FALSE(ho::scan_from_wire(m, 1'000'000'000, &s));
  EXPECT_EQ(s.stamp_ns, 4'000'000'000);  // robot clock minus (robot - local)
  EXPECT_NEAR(s.angle_min, -std::numbers::pi / 3 + 30 * std::numbers::pi / 180, 1e-12);
  EXPECT_EQ(s.ranges.size(), 40u);
  EXPECT_NEAR(s.T_R_S.theta, yaw, 1e-12);
  EXPECT_NEAR(s.T_R_S.x, 0.2, 1e-12);
  EXPECT_NEAR(s.T_W_R.x, 0.5, 1e-12);
  EXPECT_NEAR(s.T_W_R.theta, 0.1, 1e-12);
  EXPECT_EQ(s.kind, hemm::mapping::SensorKind::kLaser);
}

TEST(ScanFromWire, NoReturnBecomesFreeSpaceAndDropoutsStayUnknown) {
  hw::RangeScan m = wall_scan(1.0, {}, 1000, 0, 3);
  m.set_valid(1, false);
  m.set_valid(2, false);
  m.add_no_return(false);
  m.add_no_return(true);   // nothing up to range_max
  m.add_no_return(false);  // a dropout
  hemm::mapping::RangeScan2D s;
  ASSERT_FALSE(ho::scan_from_wire(m, 0, &s));
  EXPECT_EQ(s.valid[1], 1);  // says "free up to range_max" ...
  EXPECT_FLOAT_EQ(s.ranges[1], 10.0f);
  EXPECT_FALSE(hemm::mapping::beam_is_return(s, 1));  // ... and is never an obstacle
  EXPECT_EQ(s.valid[2], 0);  // a dropout says nothing
  EXPECT_TRUE(hemm::mapping::beam_is_return(s, 0));
  m.add_no_return(true);  // one flag too many
  EXPECT_TRUE(ho::scan_from_wire(m, 0, &s).has_value());
}

TEST(ScanFromWire, HostileInputIsRejectedWithoutChange) {
  const hw::RangeScan good = wall_scan(1.0, {}, 1000);
  hemm::mapping::RangeScan2D s;
  s.stamp_ns = 77;
  auto expect_bad = [&](const hw::RangeScan& m, const char* what) {
    const auto e = ho::scan_from_wire(m, 0, &s);
    EXPECT_TRUE(e.has_value()) << what;
    EXPECT_EQ(s.stamp_ns, 77) << what;
    EXPECT_TRUE(s.ranges.empty()) << what;
  };
  hw::RangeScan m = good;
  m.add_ranges(1.0f);
  expect_bad(m, "valid size");
  m = good;
  m.mutable_t_w_r()->set_x(std::nan(""));
  expect_bad(m, "nan pose");
  m = good;
  m.set_first_beam(10);
  expect_bad(m, "beyond beam_count");
  m = good;
  m.mutable_t_r_s()->mutable_orientation()->set_x(0.5);
  m.mutable_t_r_s()->mutable_orientation()->set_w(std::sqrt(0.75));
  expect_bad(m, "tilted sensor");
  m = good;
  m.set_sensor(hw::RANGE_SENSOR_UNSPECIFIED);
  expect_bad(m, "sensor type");
  m = good;
  m.set_angle_step(-0.1);
  expect_bad(m, "negative step");
  m = good;
  m.clear_t_w_r();
  expect_bad(m, "no pose");
  m = good;
  m.set_stamp_ns(0);
  expect_bad(m, "no stamp");
}

TEST(StateFromWire, MapsClockAndRejectsNonFinite) {
  hw::RobotState st;
  st.set_stamp_ns(3'000'000'000);
  st.mutable_t_w_r_odom()->set_x(1.0);
  st.set_v(0.2);
  ho::RobotStateSample s;
  ASSERT_FALSE(ho::state_from_wire(st, -500, &s));
  EXPECT_EQ(s.stamp_local_ns, 3'000'000'500);
  EXPECT_FALSE(s.has_truth);
  st.set_v(INFINITY);
  s.v = 9;
  EXPECT_TRUE(ho::state_from_wire(st, 0, &s).has_value());
  EXPECT_EQ(s.v, 9);
}

// A robot standing at the origin of W, stamped t.
void submit_state_at(ho::ModelThread& mt, std::int64_t t) {
  hw::RobotState st;
  st.set_stamp_ns(t);
  st.mutable_t_w_r_odom()->set_x(0.0);
  mt.submit_state(st);
}

const ho::OperatorModelSnapshot* newest(hemm::servo::ModelChannel& ch) {
  return static_cast<const ho::OperatorModelSnapshot*>(ch.acquire());
}

TEST(ModelThread, StepBuildsTheWallAndCountsBadScans) {
  hemm::servo::ModelChannel ch;
  ho::ModelThread mt(ch, {});
  const std::int64_t t0 = 10'000'000'000;
  // The robot at (1, 0) heading +x sees a wall 1 m ahead: x = 2 in W.
  hw::RobotState st;
  st.set_stamp_ns(t0);
  st.mutable_t_w_r_odom()->set_x(1.0);
  mt.submit_state(st);
  mt.submit_scan(std::make_shared<const hw::RangeScan>(wall_scan(1.0, {1.0, 0.0, 0.0}, t0, 0, 60)));
  mt.submit_scan(std::make_shared<const hw::RangeScan>(wall_scan(1.0, {1.0, 0.0, 0.0}, t0, 60, 61)));
  hw::RangeScan bad = wall_scan(1.0, {1.0, 0.0, 0.0}, t0);
  bad.mutable_valid()->RemoveLast();
  mt.submit_scan(std::make_shared<const hw::RangeScan>(bad));
  mt.step(t0 + 1'000'000);
  const ho::ModelStats s = mt.stats();
  EXPECT_EQ(s.scans_in, 2u);
  EXPECT_EQ(s.scans_rejected, 1u);
  EXPECT_EQ(s.states_in, 1u);
  EXPECT_FALSE(mt.last_error().empty());
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  EXPECT_EQ(snap->version, 1u);
  EXPECT_TRUE(snap->have_state);
  EXPECT_NEAR(snap->T_W_R.x, 1.0, 1e-12);
  ASSERT_GT(snap->map.segments.size(), 5u);
  for (const auto& seg : snap->map.segments) {
    EXPECT_NEAR(seg.a.x(), 2.0, 0.02);
    EXPECT_NEAR(seg.b.x(), 2.0, 0.02);
    EXPECT_LT(seg.normal.x(), -0.95);  // free side toward the robot
  }
  // The wall spans y = tan(+-60 deg) around y = 0.
  double ymin = 1e9, ymax = -1e9;
  for (const auto& seg : snap->map.segments) {
    ymin = std::min({ymin, seg.a.y(), seg.b.y()});
    ymax = std::max({ymax, seg.a.y(), seg.b.y()});
  }
  EXPECT_NEAR(ymin, -std::sqrt(3.0), 0.05);
  EXPECT_NEAR(ymax, std::sqrt(3.0), 0.05);
  const std::size_t before = mt.map().segments.size();
  // A bad scan alone changes nothing.
  mt.submit_scan(std::make_shared<const hw::RangeScan>(bad));
  mt.step(t0 + 2'000'000);
  EXPECT_EQ(mt.map().segments.size(), before);
  EXPECT_EQ(mt.stats().scans_rejected, 2u);
}

TEST(ModelThread, OneCorrectionPlacesTheScansAndThePublishedPoseInBoundedSteps) {
  // The robot drives at 0.2 m/s toward a wall (x = 3 in W) for 1.2 s, then
  // stands; its odometry slips, reporting 8 % more travel than the truth.
  // Registration keeps the published pose (which the device's mapping and so
  // the force follow) on the truth. It is made with the same correction the
  // scans are placed by, so the wall in the map stays where it truly is; the
  // correction changes by at most correction_per_metre of the odometry's
  // travel per scan, and not at all while the robot stands.
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p;
  ASSERT_TRUE(p.registration.enabled);  // on by default
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 10'000'000'000, dt = 20'000'000;  // a scan and a snapshot every 20 ms
  double pose_err = 0.0, odom_err = 0.0, max_change = 0.0, wall_err = 0.0, rest_change = 0.0;
  double prev_corr = 0.0, corr_at_rest = 0.0;
  for (int k = 0; k < 90; ++k) {
    const std::int64_t t = t0 + k * dt;
    const double truth_x = 0.2 * 0.02 * std::min(k, 60), odom_x = 1.08 * truth_x;
    hw::RobotState st;
    st.set_stamp_ns(t);
    st.mutable_t_w_r_odom()->set_x(odom_x);
    mt.submit_state(st);
    // In two chunks, as the robot sends a scan: they share one stamp and so
    // one allowance of correction. Cast from the true pose, stamped with
    // odometry.
    mt.submit_scan(std::make_shared<const hw::RangeScan>(wall_scan(3.0 - truth_x, {odom_x, 0.0, 0.0}, t, 0, 60)));
    mt.submit_scan(std::make_shared<const hw::RangeScan>(wall_scan(3.0 - truth_x, {odom_x, 0.0, 0.0}, t, 60, 61)));
    mt.step(t + 1'000'000);
    const auto* snap = newest(ch);
    ASSERT_NE(snap, nullptr);
    const ho::ModelStats s = mt.stats();
    const double corr = s.registration.correction.x;
    if (k > 0) max_change = std::max(max_change, std::abs(corr - prev_corr));
    prev_corr = corr;
    if (k == 62) corr_at_rest = corr;
    if (k > 62) rest_change = std::max(rest_change, std::abs(corr - corr_at_rest));
    // The pose stands where the correction puts odometry (no other blend) ...
    EXPECT_NEAR(snap->T_W_R.x, corr + odom_x * std::cos(s.registration.correction.theta), 1e-6);
    // ... which is near the truth.
    pose_err = std::max(pose_err, std::abs(snap->T_W_R.x - truth_x));
    odom_err = std::max(odom_err, std::abs(odom_x - truth_x));
    for (const auto& seg : mt.map().segments)
      if (!seg.shadow) wall_err = std::max({wall_err, std::abs(seg.a.x() - 3.0), std::abs(seg.b.x() - 3.0)});
  }
  const ho::ModelStats s = mt.stats();
  std::printf("pose error: odometry %.4f m, published %.4f m; largest correction change per scan %.5f m; at rest "
              "%.5f m; wall in the map within %.4f m of the truth; accepted %llu, held out %llu\n",
              odom_err, pose_err, max_change, rest_change, wall_err,
              static_cast<unsigned long long>(s.registration.accepted),
              static_cast<unsigned long long>(s.registration.limited));
  EXPECT_GT(s.registration.accepted, 80u);
  EXPECT_GT(odom_err, 0.018);       // the slip is there (the test can fail) ...
  EXPECT_LT(pose_err, 0.004);       // ... and the published pose does not show it
  EXPECT_LT(wall_err, 0.005);       // the map is not drawn after the slip
  // Per scan at most 10 % of the odometry's 4.3 mm travel.
  EXPECT_LE(max_change, p.registration.correction_per_metre * 1.08 * 0.004 + 1e-6);
  EXPECT_GT(max_change, 0.0);
  EXPECT_EQ(rest_change, 0.0);      // standing: the estimate does not move
}

TEST(ModelThread, PredictsWithRecordedCommandsAndFreesRetiredSnapshots) {
  hemm::servo::ModelChannel ch;
  ho::ModelThread mt(ch, {});
  const std::int64_t t0 = 1'000'000'000;
  hw::RobotState st;
  st.set_stamp_ns(t0);
  st.mutable_t_w_r_odom()->set_theta(0.0);
  mt.submit_state(st);
  mt.set_command_delay(50'000'000);
  mt.record_command({t0, 0.5, 0.0});  // acts from t0 + 50 ms
  mt.step(t0 + 450'000'000);
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  EXPECT_NEAR(snap->T_W_R.x, 0.5 * 0.4, 1e-9);
  EXPECT_NEAR(snap->v, 0.5, 1e-12);
  // Reader takes each new snapshot; the publisher frees the retired ones.
  for (int i = 0; i < 20; ++i) {
    mt.step(t0 + 500'000'000 + i * 1'000'000);
    ASSERT_NE(newest(ch), nullptr);
  }
  mt.step(t0 + 600'000'000);
  EXPECT_GE(ch.freed_by_collect(), 19u);
  EXPECT_EQ(mt.stats().snapshots, 22u);
}

// Issue 9 item 8: the model's age and the thresholds the servo fades by.
TEST(ModelThread, StaleAfterIsTheOneWayDelayPlusFreshCappedByTheMapWindow) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p;  // fresh 0.25 s, fade 1 s, window 3 s
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 1'000'000'000;
  submit_state_at(mt, t0);
  mt.set_command_delay(300'000'000);
  mt.step(t0 + 10'000'000);
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  EXPECT_TRUE(snap->have_data);
  EXPECT_EQ(snap->data_stamp_ns, t0);
  EXPECT_EQ(snap->stale_after_ns, 550'000'000);  // 0.3 + 0.25 s
  EXPECT_EQ(snap->fade_ns, 1'000'000'000);
  // A newer scan is newer data.
  mt.submit_scan(std::make_shared<const hw::RangeScan>(wall_scan(1.0, {0, 0, 0}, t0 + 40'000'000)));
  mt.step(t0 + 50'000'000);
  EXPECT_EQ(newest(ch)->data_stamp_ns, t0 + 40'000'000);
  // A 5 s one-way delay: capped so the force is gone before the map's
  // segments age out (3 s window - 1 s fade).
  mt.set_command_delay(5'000'000'000);
  mt.step(t0 + 60'000'000);
  EXPECT_EQ(newest(ch)->stale_after_ns, 2'000'000'000);
}

// Issue 9 item 8: the robot restarted (a new frame epoch). The old robot's map
// stays, the pose frozen, while the force fades (resyncing); then the new
// robot's map and state take over and the command history is gone.
TEST(ModelThread, ARestartedRobotIsTakenInAfterTheFade) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p;
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 10'000'000'000;
  const std::uint64_t old_epoch = 0x1111, new_epoch = 0x2222;
  hw::RobotState st;
  st.set_stamp_ns(t0);
  st.mutable_t_w_r_odom()->set_x(1.5);
  st.set_frame_epoch(old_epoch);
  mt.submit_state(st);
  hw::RangeScan old_scan = wall_scan(1.0, {1.5, 0.0, 0.0}, t0);  // wall x = 2.5
  old_scan.set_frame_epoch(old_epoch);
  mt.submit_scan(std::make_shared<const hw::RangeScan>(old_scan));
  mt.record_command({t0, 0.3, 0.0});
  mt.step(t0 + 10'000'000);
  ASSERT_FALSE(newest(ch)->resyncing);
  const double x_old = newest(ch)->T_W_R.x;
  EXPECT_GT(x_old, 1.5);  // predicted on with the command
  // The restarted robot: at the origin, a wall x = 1 (1 m ahead).
  const std::int64_t t1 = t0 + 3'000'000'000;
  st.set_stamp_ns(t1);
  st.mutable_t_w_r_odom()->set_x(0.0);
  st.set_frame_epoch(new_epoch);
  mt.submit_state(st);
  hw::RangeScan new_scan = wall_scan(1.0, {0.0, 0.0, 0.0}, t1);
  new_scan.set_frame_epoch(new_epoch);
  mt.submit_scan(std::make_shared<const hw::RangeScan>(new_scan));
  mt.step(t1 + 10'000'000);
  const auto* during = newest(ch);
  EXPECT_TRUE(during->resyncing);
  EXPECT_EQ(during->resyncs, 0u);
  EXPECT_NEAR(during->T_W_R.x, x_old, 1e-3);  // frozen where the old robot was last seen
  EXPECT_EQ(during->v, 0.0);
  // A late scan of the old robot is dropped, not mixed in.
  mt.submit_scan(std::make_shared<const hw::RangeScan>(old_scan));
  mt.step(t1 + 500'000'000);
  EXPECT_TRUE(newest(ch)->resyncing);
  EXPECT_EQ(mt.stats().old_epoch_dropped, 1u);
  // After the fade: the new robot's map and pose.
  mt.step(t1 + 1'020'000'000);
  const auto* after = newest(ch);
  EXPECT_FALSE(after->resyncing);
  EXPECT_EQ(after->resyncs, 1u);
  EXPECT_EQ(mt.stats().resyncs, 1u);
  EXPECT_NEAR(after->T_W_R.x, 0.0, 1e-9);  // the old command (0.3 m/s) is not integrated on
  ASSERT_GT(after->map.segments.size(), 5u);
  for (const auto& seg : after->map.segments) EXPECT_NEAR(seg.a.x(), 1.0, 0.02);  // only the new wall
  // The old robot's data, resent, never comes back.
  mt.submit_state([&] { hw::RobotState o = st; o.set_frame_epoch(old_epoch); return o; }());
  mt.step(t1 + 1'100'000'000);
  EXPECT_FALSE(newest(ch)->resyncing);
  EXPECT_EQ(mt.stats().old_epoch_dropped, 2u);
}

TEST(ModelThread, ThreadPublishes) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p;
  p.rate_hz = 200;
  ho::ModelThread mt(ch, p);
  mt.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  mt.stop();
  EXPECT_GE(mt.stats().snapshots, 2u);
  ho::ModelThreadParams bad;
  bad.rate_hz = 0.0;
  EXPECT_THROW(ho::ModelThread(ch, bad), std::invalid_argument);
}

}  // namespace

namespace {

// A SIMULATED (closed-form) depth frame: the camera 1 m above the floor at
// W (1, 0), looking straight down at a plane 0.5 m below it.
hemm::mapping::DepthImage plane_below_camera(std::uint32_t id, std::int64_t t) {
  hemm::mapping::DepthImage img;
  img.stamp_ns = t;
  img.cloud_id = id;
  img.K = hemm::mapping::intrinsics_from_hfov(80, 60, std::numbers::pi / 3, 0.2, 3.0);
  img.T_W_S.linear() << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // looking straight down
  img.T_W_S.translation() << 1.0, 0.0, 1.0;
  img.T_W_S_truth = img.T_W_S;
  img.depth.assign(80 * 60, 0.5f);
  img.status.assign(80 * 60, hemm::mapping::DepthStatus::kValid);
  return img;
}

// The live voxmap on, its normals over two rows of the frame above.
ho::ModelThreadParams live_voxmap_params() {
  ho::ModelThreadParams p;
  p.live_voxmap = true;
  p.voxmap.normal_radius = 0.05;
  return p;
}

}  // namespace

// The live voxmap path, stepped by hand: a SIMULATED (closed-form) camera
// 0.5 m above a table plane at z = 0.5, its chunks through the wire encoding
// into the model; the snapshot's voxmap has the plane at its true height, and
// a malformed chunk is counted and changes nothing.
TEST(ModelThread, DepthChunksBuildTheLiveVoxmapOfASeenPlane) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p = live_voxmap_params();
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 10'000'000'000;
  submit_state_at(mt, t0);
  mt.step(t0);  // the pose places the region of interest
  std::vector<hw::DepthChunk> chunks;
  ASSERT_FALSE(hemm::mapping::encode_depth_chunks(plane_below_camera(1, t0), "depth", {}, &chunks));
  hw::DepthChunk bad = chunks[0];
  bad.set_depth("x");  // payload length does not match its rows
  mt.submit_depth_chunk(std::make_shared<const hw::DepthChunk>(bad));
  for (const auto& c : chunks) mt.submit_depth_chunk(std::make_shared<const hw::DepthChunk>(c));
  mt.step(t0 + 300'000'000);  // after the rebuild interval (5 Hz) the first step started
  const ho::ModelStats s = mt.stats();
  EXPECT_EQ(s.voxmap.stream.malformed, 1u);
  EXPECT_EQ(s.voxmap.chunks_integrated, chunks.size());
  EXPECT_EQ(s.voxmap.builds, 1u);
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  ASSERT_NE(snap->voxmap, nullptr);
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(1.0, 0.0), Eigen::Vector2d(0.9, 0.1), Eigen::Vector2d(1.1, -0.1)}) {
    EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {xy.x(), xy.y(), 0.52}), 0.02, 0.002);
    EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {xy.x(), xy.y(), 0.49}), -0.01, 0.002);
  }
}

// The region of interest around the probe (voxmap_roi kProbe), stepped by
// hand: the same plane seen from above, the servo's probe published at
// (0.9, 0, 0.55): only the plane inside the 0.2 m cube around it is kept;
// with the probe inactive the ROI is back ahead of the robot and the next
// frame fills the rest of the plane.
TEST(ModelThread, LiveVoxmapRegionOfInterestFollowsTheProbe) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p = live_voxmap_params();
  p.voxmap_roi = ho::VoxmapRoi::kProbe;
  p.voxmap_probe_roi = {0.2, 0.05};
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 10'000'000'000;
  submit_state_at(mt, t0);
  mt.probe_positions().publish(ho::ProbePosition{Eigen::Vector3d(0.9, 0.0, 0.55), true});
  mt.step(t0);
  EXPECT_TRUE(mt.stats().voxmap.roi_on_probe);
  auto frame = [&](std::uint32_t id, std::int64_t t) {
    std::vector<hw::DepthChunk> chunks;
    EXPECT_FALSE(hemm::mapping::encode_depth_chunks(plane_below_camera(id, t), "depth", {}, &chunks));
    for (const auto& c : chunks) mt.submit_depth_chunk(std::make_shared<const hw::DepthChunk>(c));
  };
  frame(1, t0);
  mt.step(t0 + 300'000'000);
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  ASSERT_NE(snap->voxmap, nullptr);
  // Inside the cube (x 0.8..1.0, |y| <= 0.1): the plane at z = 0.5.
  EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {0.9, 0.0, 0.52}), 0.02, 0.002);
  // 0.25 m beyond its face: nothing stored there, far outside.
  EXPECT_GT(hemm::vps::sdf_hermite(*snap->voxmap, {1.25, 0.0, 0.49}), 0.03);
  const std::size_t cells_probe = mt.stats().voxmap.cells;
  EXPECT_LT(cells_probe, 20u * 20u * 2u);  // about the cube's 20 x 20 cm of plane at 1 cm
  // The probe put away (another mode): back ahead of the robot, the whole plane.
  mt.probe_positions().publish(ho::ProbePosition{Eigen::Vector3d(0.9, 0.0, 0.55), false});
  mt.step(t0 + 400'000'000);
  EXPECT_FALSE(mt.stats().voxmap.roi_on_probe);
  frame(2, t0 + 400'000'000);
  mt.step(t0 + 700'000'000);
  snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  ASSERT_NE(snap->voxmap, nullptr);
  EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {1.2, 0.0, 0.52}), 0.02, 0.002);
  EXPECT_GT(mt.stats().voxmap.cells, 4 * cells_probe);
  EXPECT_EQ(mt.stats().voxmap.roi_moves, 2u);
}

// A restarted robot (new frame epoch) numbers its clouds afresh in a new W:
// its first chunks clear the live voxmap (the old robot's plane at z = 0.5 is
// gone, the new one's at z = 0.4 is built, its cloud 1 is not "stale" after
// the old robot's cloud 5), and a late chunk of the old robot is dropped.
TEST(ModelThread, ANewFrameEpochClearsTheLiveVoxmap) {
  hemm::servo::ModelChannel ch;
  ho::ModelThreadParams p = live_voxmap_params();
  ho::ModelThread mt(ch, p);
  const std::int64_t t0 = 10'000'000'000;
  submit_state_at(mt, t0);
  mt.step(t0);
  auto submit = [&](std::uint64_t epoch, std::uint32_t id, std::int64_t t, float depth) {
    hemm::mapping::DepthImage img = plane_below_camera(id, t);
    img.depth.assign(img.depth.size(), depth);
    std::vector<hw::DepthChunk> chunks;
    EXPECT_FALSE(hemm::mapping::encode_depth_chunks(img, "depth", {}, &chunks));
    for (auto& c : chunks) {
      c.set_frame_epoch(epoch);
      mt.submit_depth_chunk(std::make_shared<const hw::DepthChunk>(c));
    }
    return chunks.size();
  };
  const std::uint64_t kOld = 0x1111, kNew = 0x2222;
  submit(kOld, 5, t0, 0.5f);
  mt.step(t0 + 300'000'000);
  const auto* snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  ASSERT_NE(snap->voxmap, nullptr);
  EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {1.0, 0.0, 0.52}), 0.02, 0.002);
  // The restarted robot: cloud 1 of a new epoch, the plane 0.1 m lower.
  const std::size_t n = submit(kNew, 1, t0 + 400'000'000, 0.6f);
  mt.step(t0 + 600'000'000);
  snap = newest(ch);
  ASSERT_NE(snap, nullptr);
  ASSERT_NE(snap->voxmap, nullptr);
  EXPECT_NEAR(hemm::vps::sdf_hermite(*snap->voxmap, {1.0, 0.0, 0.42}), 0.02, 0.002);
  // The old plane is gone: 5 cm above the new one is free (outside the layers).
  EXPECT_GT(hemm::vps::sdf_hermite(*snap->voxmap, {1.0, 0.0, 0.5}), 0.04);
  ho::ModelStats s = mt.stats();
  EXPECT_EQ(s.voxmap.restarts, 1u);
  EXPECT_EQ(s.voxmap.stream.stale, 0u);
  EXPECT_EQ(s.voxmap.chunks_integrated, 2 * n);
  // A late chunk of the old robot changes nothing.
  submit(kOld, 6, t0 + 700'000'000, 0.5f);
  mt.step(t0 + 900'000'000);
  s = mt.stats();
  EXPECT_EQ(s.voxmap.old_epoch_chunks, n);
  EXPECT_EQ(s.voxmap.restarts, 1u);
  EXPECT_EQ(s.voxmap.chunks_integrated, 2 * n);
}
