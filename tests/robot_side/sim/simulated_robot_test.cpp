// The SIMULATED robot in the home scene: the arm's kinematics against
// MuJoCo's own site pose, the laser and sonar against known geometry (a wall
// at a known distance, the bin of known radius), dropouts, loading errors.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "config_robot.pb.h"
#include "robot_side/sim/realtime.h"
#include "robot_side/control/arm_control.h"
#include "robot_side/sim/simulated_robot.h"
#include "tests/temp_dir.h"

namespace hr = hemm::robot;
namespace hk = hemm::kinematics;

namespace {

const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

// Beam i of a scan as a point in the world, placed with the truth pose.
Eigen::Vector2d beam_point_W(const hr::RangeScanData& s, size_t i) {
  const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
  const Eigen::Vector3d p_R = s.T_R_S * Eigen::Vector3d(s.ranges[i] * std::cos(a), s.ranges[i] * std::sin(a), 0.0);
  const double c = std::cos(s.T_W_R_truth.theta), sn = std::sin(s.T_W_R_truth.theta);
  return {s.T_W_R_truth.x + c * p_R.x() - sn * p_R.y(), s.T_W_R_truth.y + sn * p_R.x() + c * p_R.y()};
}

std::vector<hr::RangeScanData> collect(hr::SimulatedRobot& r, hr::RangeSensorKind kind, int steps) {
  r.take_scans();
  r.step(steps);
  std::vector<hr::RangeScanData> out;
  for (auto& s : r.take_scans()) {
    if (s.kind == kind) out.push_back(std::move(s));
  }
  return out;
}

// Geometric (orthogonal distance) circle fit by Gauss-Newton from the
// algebraic (Kasa) fit.
Eigen::Vector3d fit_circle(const std::vector<Eigen::Vector2d>& pts) {
  Eigen::MatrixXd A(pts.size(), 3);
  Eigen::VectorXd b(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    A(k, 0) = 2 * pts[i].x();
    A(k, 1) = 2 * pts[i].y();
    A(k, 2) = 1.0;
    b(k) = pts[i].squaredNorm();
  }
  const Eigen::Vector3d s = A.colPivHouseholderQr().solve(b);
  Eigen::Vector3d c(s(0), s(1), std::sqrt(s(2) + s(0) * s(0) + s(1) * s(1)));
  for (int it = 0; it < 20; ++it) {
    Eigen::MatrixXd J(pts.size(), 3);
    Eigen::VectorXd e(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      const Eigen::Vector2d d = pts[i] - c.head<2>();
      const double n = d.norm();
      e(k) = n - c(2);
      J(k, 0) = -d.x() / n;
      J(k, 1) = -d.y() / n;
      J(k, 2) = -1.0;
    }
    c -= J.colPivHouseholderQr().solve(e);
  }
  return c;
}

}  // namespace

TEST(SimulatedRobot, ForwardKinematicsMatchesMujocoSitePose) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  const hk::Arm5Model& m = r.arm_model();
  EXPECT_NEAR(m.reach(), 0.50, 1e-12);
  std::mt19937_64 rng(3);
  double worst_p = 0.0, worst_r = 0.0;
  for (int k = 0; k < 1000; ++k) {
    hk::Arm5Vector q;
    for (int i = 0; i < 5; ++i) q(i) = std::uniform_real_distribution<double>(m.q_min(i), m.q_max(i))(rng);
    r.set_arm_q_sim(q);
    const Eigen::Isometry3d Tm = r.mujoco_T_A_E_sim();
    const Eigen::Isometry3d Tk = hk::forward_kinematics(m, q);
    worst_p = std::max(worst_p, (Tm.translation() - Tk.translation()).norm());
    worst_r = std::max(worst_r, (Tm.linear() - Tk.linear()).cwiseAbs().maxCoeff());
    ASSERT_NEAR(Tk.linear().determinant(), 1.0, 1e-12);
  }
  std::printf("FK vs MuJoCo over 1000 configurations: position %.2e m, rotation %.2e\n", worst_p, worst_r);
  EXPECT_LT(worst_p, 1e-9);
  EXPECT_LT(worst_r, 1e-9);
}

TEST(SimulatedRobot, LoadErrorsLeaveTheRobotUnloaded) {
  hr::SimulatedRobot r;
  EXPECT_TRUE(r.load(hemm::config::RobotConfig(), "/nonexistent/scene.xml"));
  EXPECT_FALSE(r.loaded());
  const std::string bad = hemm::test::make_temp_dir() + "/no_robot_scene.xml";
  std::ofstream(bad) << "<mujoco><worldbody><geom type='plane' size='1 1 0.1'/></worldbody></mujoco>";
  const auto err = r.load(hemm::config::RobotConfig(), bad);
  ASSERT_TRUE(err);
  EXPECT_NE(err->find("robot"), std::string::npos) << *err;
  EXPECT_FALSE(r.loaded());
  hemm::config::RobotConfig bad_cfg;
  bad_cfg.mutable_laser()->set_beams(0);
  const auto cfg_err = r.load(bad_cfg, kScene);
  ASSERT_TRUE(cfg_err);
  EXPECT_NE(cfg_err->find("laser.beams"), std::string::npos) << *cfg_err;
  EXPECT_FALSE(r.loaded());
  r.step(10);  // harmless when unloaded
  EXPECT_EQ(r.time_ns(), 0);
}

TEST(RangeSensors, LaserAndSonarReadAWallAtAKnownDistance) {
  hemm::config::RobotConfig cfg;
  cfg.mutable_laser()->set_dropout_probability(0.0);
  cfg.mutable_sonar()->set_dropout_probability(0.0);
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(cfg, kScene));
  // Facing the west wall (inner face x = -0.95) from the origin.
  r.set_base_pose_sim({0.0, 0.0, std::numbers::pi});
  r.step(100);
  const hr::Pose2 p = r.state().T_W_R_truth;
  const auto& lp = r.laser_params();
  const double sensor_x = p.x + std::cos(p.theta) * lp.T_R_S.translation().x();
  const double d_wall = sensor_x - (-0.95);
  const auto scans = collect(r, hr::RangeSensorKind::kLaser, 1000);
  ASSERT_GE(scans.size(), 25u);
  const double sigma = cfg.laser().sigma_m();
  double sum = 0.0, worst = 0.0;
  int n = 0;
  for (const auto& s : scans) {
    for (size_t i = 0; i < s.size(); ++i) {
      const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
      if (std::abs(a) > 0.8) continue;  // the west wall fills +-46 deg and more
      ASSERT_TRUE(s.valid[i]);
      const double expected = d_wall / std::cos(a + p.theta - std::numbers::pi);
      const double e = s.ranges[i] - expected;
      sum += e;
      worst = std::max(worst, std::abs(e));
      ++n;
    }
  }
  const double mean = sum / n;
  std::printf("laser on the wall at %.3f m: %d beams, mean error %.5f m, worst %.4f m (sigma %.3f)\n", d_wall, n, mean,
              worst, sigma);
  EXPECT_LT(std::abs(mean), 4 * sigma / std::sqrt(n) + 1e-4);
  EXPECT_LT(worst, 5.5 * sigma);

  // Sonar beam 0 looks forward too; its range is measured from the ring centre.
  const auto sonar = collect(r, hr::RangeSensorKind::kSonar, 1000);
  ASSERT_GE(sonar.size(), 9u);
  const double d_sonar = p.x + std::cos(p.theta) * r.sonar_params().T_R_S.translation().x() - (-0.95);
  for (const auto& s : sonar) {
    ASSERT_TRUE(s.valid[0]);
    EXPECT_NEAR(s.ranges[0], d_sonar, 5.5 * cfg.sonar().sigma_m());
    EXPECT_NEAR(s.beam_width, cfg.sonar().cone_deg() * std::numbers::pi / 180, 1e-12);
    EXPECT_EQ(s.size(), cfg.sonar().count());
  }
}

TEST(RangeSensors, BinRadiusRecoveredFromLaserScansWithinOneCentimetre) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  r.set_base_pose_sim({0.5, -1.2, 0.0});  // facing the bin at (1.5, -1.2), r = 0.15
  r.step(100);
  std::vector<Eigen::Vector2d> pts;
  for (const auto& s : collect(r, hr::RangeSensorKind::kLaser, 400)) {
    for (size_t i = 0; i < s.size(); ++i) {
      if (!s.valid[i]) continue;
      // Segment: the bin is the only object within 1.2 m and +-23 deg ahead
      // (it spans +-10.5 deg; the sofa to the right is farther round).
      const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
      if (s.ranges[i] < 1.2 && std::abs(a) < 0.4) pts.push_back(beam_point_W(s, i));
    }
  }
  ASSERT_GE(pts.size(), 50u);
  const Eigen::Vector3d c = fit_circle(pts);
  std::printf("bin fit from %zu points: centre (%.4f, %.4f), radius %.4f m\n", pts.size(), c.x(), c.y(), c.z());
  EXPECT_NEAR(c.z(), 0.15, 0.01);
  EXPECT_NEAR(c.x(), 1.5, 0.01);
  EXPECT_NEAR(c.y(), -1.2, 0.01);
}

TEST(RangeSensors, DropoutsAreFlaggedNeverZero) {
  hemm::config::RobotConfig cfg;
  cfg.mutable_laser()->set_dropout_probability(0.3);
  cfg.mutable_sonar()->set_dropout_probability(0.3);
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(cfg, kScene));
  r.set_base_pose_sim({0.0, 0.0, std::numbers::pi});
  int total = 0, dropped = 0;
  for (const auto& s : collect(r, hr::RangeSensorKind::kLaser, 1000)) {
    for (size_t i = 0; i < s.size(); ++i) {
      const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
      EXPECT_GT(s.ranges[i], 0.0f);
      if (std::abs(a) > 0.8) continue;  // beams that surely hit the wall
      ++total;
      if (!s.valid[i]) {
        ++dropped;
        EXPECT_EQ(s.ranges[i], static_cast<float>(s.range_max));
      }
    }
  }
  const double rate = static_cast<double>(dropped) / total;
  const double sd = std::sqrt(0.3 * 0.7 / total);
  std::printf("dropouts: %d of %d (%.3f, expected 0.3 +- %.3f)\n", dropped, total, rate, sd);
  EXPECT_NEAR(rate, 0.3, 5 * sd);
  // A wall beyond the maximum range is no return: invalid, not zero.
  hemm::config::RobotConfig short_cfg;
  short_cfg.mutable_laser()->set_range_max_m(0.5);
  hr::SimulatedRobot r2;
  ASSERT_FALSE(r2.load(short_cfg, kScene));
  r2.set_base_pose_sim({0.0, 0.0, std::numbers::pi});
  for (const auto& s : collect(r2, hr::RangeSensorKind::kLaser, 100)) {
    const size_t mid = s.size() / 2;
    EXPECT_FALSE(s.valid[mid]);
    EXPECT_EQ(s.ranges[mid], 0.5f);
  }
}

TEST(RangeSensors, ScansCarryStampsPosesAndRates) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  r.set_time_origin_ns(1'000'000'000);
  r.take_scans();
  r.step(1000);
  int lasers = 0, sonars = 0;
  uint32_t last_id = 0;
  bool first = true;
  for (const auto& s : r.take_scans()) {
    (s.kind == hr::RangeSensorKind::kLaser ? lasers : sonars)++;
    EXPECT_GT(s.stamp_ns, 1'000'000'000);
    EXPECT_LE(s.stamp_ns, r.time_ns());
    if (!first) {
      EXPECT_GT(s.scan_id, last_id);
    }
    last_id = s.scan_id;
    first = false;
    EXPECT_NEAR(s.T_W_R_odom.x, s.T_W_R_truth.x, 1e-3);  // standing still
  }
  EXPECT_NEAR(lasers, 30, 1);
  EXPECT_NEAR(sonars, 10, 1);
}

TEST(SimulatedRobot, PacedSteppingNeverRunsAheadOfTheClock) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  const int64_t t0 = hr::steady_now_ns();
  hemm::rt::TimingStats timing;
  const hr::PacingStats st = hr::step_realtime(r, 100, &timing);
  const int64_t wall = hr::steady_now_ns() - t0;
  EXPECT_EQ(st.steps, 100);
  // Every step is in the deadline histograms; none woke early.
  EXPECT_EQ(timing.ticks.load(), 100u);
  EXPECT_EQ(timing.compute.count(), 100u);
  EXPECT_EQ(timing.period.count(), 99u);
  EXPECT_EQ(timing.wake_latency.max_ns(), st.max_lateness_ns);
  EXPECT_EQ(timing.worst.sorted().size(), 10u);
  // 100 steps at 1 kHz: step 99 starts no earlier than 99 ms after the first
  // (a lower bound only: the shared machine may stall us for longer).
  EXPECT_GE(wall, 99'000'000);
  // The robot's clock is the steady clock now.
  EXPECT_LE(std::llabs(r.time_ns() - hr::steady_now_ns()), 1'000'000'000);
}

TEST(DepthCamera, WristCameraSeesTheWallAndFloorWhereTheyAre) {
  hemm::config::RobotConfig cfg;
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(cfg, kScene));
  hr::SimDepthCameraParams bad;
  bad.width = 0;
  EXPECT_TRUE(r.enable_depth_camera(bad));
  hr::SimDepthCameraParams cam;
  ASSERT_FALSE(r.enable_depth_camera(cam));
  // Facing the west wall (inner face x = -0.95) from the origin, arm at rest.
  r.set_base_pose_sim({0.0, 0.0, std::numbers::pi});
  r.take_depth_images();
  const auto t0 = std::chrono::steady_clock::now();
  r.step(1000);
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto imgs = r.take_depth_images();
  ASSERT_EQ(imgs.size(), 4u);  // 15 frames in 1 s; the newest 4 kept
  std::printf("1 s simulated with the depth camera at 15 Hz: %.0f ms wall (loaded machine)\n", 1e3 * wall_s);
  int valid = 0;
  for (const auto& img : imgs) {
    EXPECT_EQ(img.K.width, 80);
    EXPECT_LT((img.T_W_S.translation() - img.T_W_S_truth.translation()).norm(), 0.02);  // odometry barely drifts standing
    for (int v = 0; v < img.K.height; ++v) {
      for (int u = 0; u < img.K.width; ++u) {
        const auto i = static_cast<std::size_t>(v * img.K.width + u);
        if (img.status[i] != hemm::mapping::DepthStatus::kValid) continue;
        ++valid;
        const Eigen::Vector3d ray = hemm::mapping::pixel_ray_z1(img.K, u, v);
        const Eigen::Vector3d x = img.T_W_S_truth * (img.depth[i] * ray);
        const double r_m = img.depth[i] * ray.norm();
        const double tol = 5 * (cam.sigma_0 + cam.sigma_2 * r_m * r_m) + 1e-4;
        // Every return lies on the wall's face or on the floor (at rest the
        // tool, and so the camera, points down ahead of the base).
        EXPECT_LT(std::min(std::abs(x.x() + 0.95), std::abs(x.z())), tol) << x.transpose();
      }
    }
  }
  EXPECT_GT(valid, 4 * 1500);
}

// ---------------------------------------------------------------- 3D arm keep-out (issue 13)
// The robot before the west chair of the home scene (seat top z 0.46 from
// 0.36 m ahead of the base centre, the front face of its legs 0.38 m: the
// folded arm's tool, 0.32 m ahead, clears it), its mast camera
// pitched 60 deg down so it sees the seat in front of the arm. The table
// (top 0.75 m) is out of the arm's reach: the tool tip reaches at most
// 0.80 m high, straight above the shoulder.
namespace {
hr::BaseArmCommand arm_command(const Eigen::Vector3d& p_R, std::uint64_t seq) {
  hr::BaseArmCommand c;
  c.mode = hemm::wire::MODE_MANIPULATION;
  c.arm_target_R = p_R;
  c.deadman = true;
  c.seq = seq;
  return c;
}

// The robot before the west chair with its mast camera on, 6 frames seen.
void stand_before_the_chair(hr::SimulatedRobot& r) {
  hemm::config::RobotConfig cfg;
  cfg.mutable_depth_camera()->set_mast_pitch_deg(60);
  ASSERT_FALSE(r.load(cfg, kScene));
  r.set_base_pose_sim({0.55, 1.42, std::numbers::pi / 2});
  r.set_operator_in_control(true);
  ASSERT_FALSE(r.enable_depth_camera(hr::depth_camera_params_from_config(cfg)));
  r.step(400);  // 6 frames, laser scans
}

// The arm raised: the upper arm nearly upright, the tool tip 0.34 m ahead
// and 0.65 m high, above the seat's front edge.
const hk::Arm5Vector kRaised = (hk::Arm5Vector() << 0.0, 1.5, -1.0, 0.0, 0.0).finished();
}  // namespace

TEST(ArmKeepOut3dSim, TheMastCameraLetsTheArmReachOverTheSeatButNotIntoIt) {
  hr::SimulatedRobot r;
  stand_before_the_chair(r);
  // The arm raised (from the fold its path to the seat would sweep through
  // the chair: ThePathToAGoalIsCheckedNotOnlyTheGoal).
  r.set_arm_q_sim(kRaised);
  const hr::SeenVoxelsStats st = r.seen_voxels_stats();
  std::printf("seen voxels %zu (%.0f kB), %llu frames, integrate max %.0f us\n", st.voxels, st.memory_bytes / 1e3,
              static_cast<unsigned long long>(st.frames), st.max_integrate_us);
  ASSERT_GE(st.frames, 5u);
  EXPECT_GT(st.voxels, 200u);
  const double seat = 0.46, reach = 0.04;  // link radius + clearance + pad
  const int64_t t = r.time_ns();
  // Over the seat, 6 cm above its top: allowed, although the laser sees the
  // chair's front 0.38 m ahead (its column is capped: the camera sees above it).
  EXPECT_FALSE(r.set_command(arm_command({0.45, 0.0, seat + reach + 0.02}, 10), t));
  // 1.5 cm above it (the tool's payload sphere would be in the seat's cushion
  // of 0.04 m): refused, as seen geometry.
  auto err = r.set_command(arm_command({0.45, 0.0, seat + 0.015}, 11), t);
  ASSERT_TRUE(err);
  EXPECT_EQ(r.arm_refusals().scene, 1u);
  EXPECT_EQ(r.arm_refusals().last, hr::ArmRefusal::kScene);
  EXPECT_EQ(r.arm_refusals().last_seq, 11u);
  // Into the floor beside the robot, and onto the laser head.
  EXPECT_TRUE(r.set_command(arm_command({0.02, 0.30, -0.2}, 12), t));
  EXPECT_EQ(r.arm_refusals().floor, 1u);
  EXPECT_TRUE(r.set_command(arm_command({0.18, 0.0, 0.34}, 13), t));
  EXPECT_EQ(r.arm_refusals().base, 1u);
  const hr::RobotStateSim s = r.state();
  EXPECT_EQ(s.arm_refusals, 3u);
  EXPECT_EQ(s.last_arm_refusal, static_cast<int>(hr::ArmRefusal::kBase));
  EXPECT_EQ(s.last_refused_seq, 13u);
  EXPECT_EQ(s.last_command_seq, 10u);  // the allowed one is what the arm follows
  EXPECT_GT(r.seen_voxels_stats().checks, 3u);
  // Without the camera the laser's columns are infinite: the reach over the
  // seat is refused too.
  r.disable_depth_camera();
  EXPECT_TRUE(r.set_command(arm_command({0.45, 0.0, seat + reach + 0.02}, 14), t));
  EXPECT_EQ(r.arm_refusals().scene, 2u);
}

TEST(ArmKeepOut3dSim, ThePathToAGoalIsCheckedNotOnlyTheGoal) {
  hr::SimulatedRobot r;
  stand_before_the_chair(r);
  const Eigen::Vector3d over_seat(0.45, 0.0, 0.46 + 0.06);  // allowed as a pose from above (test above)
  // From the folded arm the reference unfolds each joint at the speed limit:
  // the tool sweeps forward low, through the chair. Refused as seen geometry.
  const hk::Arm5Vector fold = r.state().q;
  const int64_t t = r.time_ns();
  ASSERT_TRUE(r.set_command(arm_command(over_seat, 20), t));
  EXPECT_EQ(r.arm_refusals().last, hr::ArmRefusal::kScene);
  EXPECT_EQ(r.arm_refusals().scene, 1u);
  // Truth (MuJoCo): that path really meets the chair. Put the arm at the
  // path's poses and read the arm's contacts with the scene.
  const hk::IkResult ik = hk::inverse_kinematics(r.arm_model(), {r.T_R_A().inverse() * over_seat, 0.0, 0.0}, fold);
  ASSERT_EQ(ik.status, hk::IkStatus::kConverged);
  const hk::Arm5Vector goal = ik.q;
  const double span = (goal - fold).cwiseAbs().maxCoeff();
  int touching = 0;
  for (int k = 0; k <= 50; ++k) {
    r.set_arm_q_sim(hr::arm_reference_after(fold, goal, span * k / 50));
    r.step(1);
    if (r.robot_contacts_sim() > 0) ++touching;  // any scene geom but the floor
  }
  std::printf("fold -> over the seat: %d of 51 poses on the path touch the chair\n", touching);
  EXPECT_GT(touching, 0);
  // From the raised arm the same goal's path is clear: accepted, and the
  // arm gets there without touching anything.
  r.set_arm_q_sim(kRaised);
  r.step(1);
  const std::uint64_t touched = r.arm_contacts_sim().contact_steps;  // on the path poses above
  const std::uint64_t checks0 = r.seen_voxels_stats().checks;
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_FALSE(r.set_command(hr::BaseArmCommand{}, r.time_ns()));  // neutral first: the robot re-arms
  const auto err = r.set_command(arm_command(over_seat, 21), r.time_ns());
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(err) << *err;
  std::printf("raised -> over the seat: accepted after %llu pose checks in %.2f ms\n",
              static_cast<unsigned long long>(r.seen_voxels_stats().checks - checks0), ms);
  for (int i = 0; i < 2000; ++i) {  // 2 s (1.5 rad/s), the command refreshed as an operator's would be
    if (i % 5 == 0) {
      ASSERT_FALSE(r.set_command(arm_command(over_seat, 22 + i), r.time_ns()));
    }
    r.step(1);
  }
  const Eigen::Vector3d tip = (r.T_R_A() * r.mujoco_T_A_E_sim()).translation();
  EXPECT_LT((tip - over_seat).norm(), 0.02) << tip.transpose();
  EXPECT_EQ(r.arm_contacts_sim().contact_steps, touched);
  EXPECT_EQ(r.arm_refusals().scene, 1u);
}

TEST(ArmKeepOut3dSim, ArmContactsAndTheToolsTrueClearanceToTheSeat) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  r.set_base_pose_sim({0.55, 1.42, std::numbers::pi / 2});
  const hk::Arm5Model& m = r.arm_model();
  const double seat = 0.46, payload_radius = 0.02;
  // The tool level over the seat at height z: its payload sphere (radius
  // 0.02, at the tip) is the nearest part, the sphere-box distance exact.
  auto put_tip_at = [&](double z) {
    const Eigen::Vector3d p_R(0.40, 0.0, z);
    const hk::IkResult ik = hk::inverse_kinematics(m, {r.T_R_A().inverse() * p_R, 0.0, 0.0},
                                                   (hk::Arm5Vector() << 0, 0.5, -1.0, 0, 0).finished());
    ASSERT_EQ(ik.status, hk::IkStatus::kConverged);
    r.set_arm_q_sim(ik.q);
    r.step(1);
  };
  for (double gap : {0.08, 0.03, 0.005}) {
    put_tip_at(seat + payload_radius + gap);
    const double tip_z = (r.T_R_A() * r.mujoco_T_A_E_sim()).translation().z();
    EXPECT_NEAR(r.arm_contacts_sim().tool_clearance, tip_z - seat - payload_radius, 1e-4) << gap;
  }
  EXPECT_EQ(r.arm_contacts_sim().contact_steps, 0u);
  EXPECT_NEAR(r.arm_contacts_sim().tool_min_clearance, 0.005, 1e-3);
  EXPECT_EQ(r.robot_contacts_sim(), 0);  // the clearance probes are not contacts
  // 5 mm into the seat: a contact.
  put_tip_at(seat + payload_radius - 0.005);
  EXPECT_GE(r.arm_contacts_sim().contact_steps, 1u);
  EXPECT_LT(r.arm_contacts_sim().tool_clearance, 0.0);
  EXPECT_GT(r.robot_contacts_sim("chair_w_seat"), 0);
}

// ---------------------------------------------------------------- re-arm (issue 23 item 1)
namespace {
hr::BaseArmCommand drive_command(double v, bool deadman, std::uint64_t seq) {
  hr::BaseArmCommand c;
  c.mode = hemm::wire::MODE_NAVIGATION;
  c.v = v;
  c.deadman = deadman;
  c.seq = seq;
  return c;
}
// Streams c every 10 ms for ms milliseconds; returns the largest |true speed|.
double stream(hr::SimulatedRobot& r, const hr::BaseArmCommand& c, int ms) {
  double v = 0.0;
  for (int i = 0; i < ms; ++i) {
    if (i % 10 == 0) {
      EXPECT_FALSE(r.set_command(c, r.time_ns()));
    }
    r.step(1);
    v = std::max(v, std::abs(r.state().v_truth));
  }
  return v;
}
}  // namespace

// Every stop leaves the robot disarmed (SAFETY_REARM) until a neutral command
// and then a pressed one: at start-up, after the e-stop (even one set and
// cleared between two steps), a lost link and a time without the operator.
// Zero motion with the dead-man pressed is neutral too; the robot's own
// neutral command (a mode change) is not the operator's and re-arms nothing.
TEST(SimulatedRobot, AfterEveryStopOnlyANeutralCommandThenAPressedOneMovesTheRobot) {
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(hemm::config::RobotConfig(), kScene));
  r.set_base_pose_sim({-0.5, -0.3, 0.0});
  r.set_operator_in_control(true);
  r.step(200);
  std::uint64_t seq = 0;
  // Start-up: pressed at once is not followed.
  EXPECT_LT(stream(r, drive_command(0.3, true, ++seq), 500), 0.005);
  EXPECT_NE(r.state().safety & hemm::wire::SAFETY_REARM, 0u);
  EXPECT_FALSE(r.armed());
  stream(r, drive_command(0.0, true, ++seq), 20);  // zero motion, pressed: neutral
  EXPECT_GT(stream(r, drive_command(0.3, true, ++seq), 800), 0.25);
  EXPECT_TRUE(r.armed());
  EXPECT_EQ(r.state().safety & hemm::wire::SAFETY_REARM, 0u);
  // The e-stop set and cleared before the next step still disarms.
  r.set_estop(true);
  r.set_estop(false);
  EXPECT_FALSE(r.armed());
  r.step(600);  // the base comes to rest (the watchdog too has expired by now)
  EXPECT_LT(stream(r, drive_command(0.3, true, ++seq), 500), 0.01);
  // The robot's own neutral command re-arms nothing.
  r.stop_commanded_motion(seq);
  EXPECT_LT(stream(r, drive_command(0.3, true, ++seq), 300), 0.01);
  // Neutral commands during a stop do not count: only after it cleared.
  r.set_link_lost(true);
  stream(r, drive_command(0.0, false, ++seq), 50);
  r.set_link_lost(false);
  EXPECT_LT(stream(r, drive_command(0.3, true, ++seq), 300), 0.01);
  stream(r, drive_command(0.3, false, ++seq), 20);  // released: neutral
  EXPECT_GT(stream(r, drive_command(0.3, true, ++seq), 800), 0.25);
  // Control lost and given back: not followed until re-armed.
  r.set_operator_in_control(false);
  r.set_operator_in_control(true);
  EXPECT_FALSE(r.armed());
}

// ---------------------------------------------------------------- pan-tilt head (issue 24)
// The SIMULATED pan-tilt head facing the west wall (inner face x = -0.95)
// from the origin, off-centre on the mast (head_y_m 0.05): the operator's
// gaze alternates between two points on the wall; every frame, taken while
// the head moves or stands, carries its pose at acquisition: the truth that
// of the head's true joints in that very step (MuJoCo's base pose), every
// return placed with it on the wall or the floor, and the reported pose off
// it by the encoders' bias and noise only. Once settled the optical axis
// goes through the gaze point; without commands the head goes home.
TEST(PanTiltHead, FramesCarryTheHeadsPoseAtAcquisitionWhileItMoves) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  hemm::config::RobotConfig cfg;
  cfg.mutable_depth_camera()->set_enabled(true);
  cfg.mutable_depth_camera()->set_mount("pan-tilt");
  cfg.mutable_depth_camera()->set_head_y_m(0.05);
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(cfg, kScene));
  r.set_base_pose_sim({0.0, 0.0, std::numbers::pi});
  r.set_operator_in_control(true);
  const hr::SimDepthCameraParams cam = hr::depth_camera_params_from_config(cfg);
  ASSERT_TRUE(cam.pan_tilt);
  ASSERT_FALSE(r.enable_depth_camera(cam));
  const Eigen::Vector3d targets[2] = {{-0.95, 0.45, 0.85}, {-0.95, -0.40, 1.15}};
  std::uint64_t seq = 0;
  int frames = 0, moving_frames = 0, settled_checks = 0;
  double last_pan = 0.0;
  for (int phase = 0; phase < 4; ++phase) {
    const Eigen::Vector3d& target = targets[phase % 2];
    for (int ms = 0; ms < 1000; ++ms) {
      if (ms % 10 == 0) {
        hr::BaseArmCommand c;
        c.mode = hemm::wire::MODE_EXPLORATION;
        c.seq = ++seq;
        c.gaze = {true, true, target};
        ASSERT_FALSE(r.set_command(c, r.time_ns()));
      }
      r.step(1);
      const auto imgs = r.take_depth_images();
      if (imgs.empty()) continue;
      ASSERT_EQ(imgs.size(), 1u);  // inline casting: the frame of this step
      const hemm::mapping::DepthImage& img = imgs.front();
      const hr::RobotStateSim st = r.state();
      ASSERT_TRUE(st.head.present);
      ++frames;
      // The truth's optical axis, in R (the base's true yaw), is the head's
      // true pan and tilt of this step: within 2e-4 rad, the chassis' own
      // pitch and roll on its wheels (MuJoCo's 3D base pose), while one step
      // late would be off by up to the head's rate times 1 ms, 1.6e-3 rad.
      const Eigen::Vector3d z_W = img.T_W_S_truth.linear().col(2);
      const Eigen::Vector3d z_R = Eigen::AngleAxisd(-st.T_W_R_truth.theta, Eigen::Vector3d::UnitZ()) * z_W;
      EXPECT_NEAR(std::atan2(z_R.y(), z_R.x()), st.head.pan_truth, 2e-4);
      EXPECT_NEAR(std::atan2(-z_R.z(), z_R.head<2>().norm()), st.head.tilt_truth, 2e-4);
      if (std::abs(st.head.pan_truth - last_pan) > 0.5 * kDeg) ++moving_frames;
      last_pan = st.head.pan_truth;
      // Reported against truth: the encoders' bias (0.3 and -0.2 deg) and noise (0.05 deg).
      const Eigen::Isometry3d E = img.T_W_S_truth.inverse() * img.T_W_S;
      const double angle = Eigen::AngleAxisd(E.linear()).angle();
      EXPECT_GT(angle, 0.2 * kDeg);
      EXPECT_LT(angle, 0.6 * kDeg);
      EXPECT_LT(E.translation().norm(), 0.01);
      // Every return placed with the truth lies on the wall's face or the floor.
      for (int v = 0; v < img.K.height; v += 3)
        for (int u = 0; u < img.K.width; u += 3) {
          const auto i = static_cast<std::size_t>(v * img.K.width + u);
          if (img.status[i] != hemm::mapping::DepthStatus::kValid) continue;
          const Eigen::Vector3d ray = hemm::mapping::pixel_ray_z1(img.K, u, v);
          const Eigen::Vector3d x = img.T_W_S_truth * (img.depth[i] * ray);
          const double rm = img.depth[i] * ray.norm();
          EXPECT_LT(std::min(std::abs(x.x() + 0.95), std::abs(x.z())), 5 * (cam.sigma_0 + cam.sigma_2 * rm * rm) + 1e-4)
              << x.transpose();
        }
      if (ms > 900) {
        // Settled: the optical axis meets the wall at the gaze point (truth),
        // and within the encoders' error from the reported pose (~6 mm at 0.9 m).
        for (const auto& [T, tol] : {std::pair{img.T_W_S_truth, 0.008}, std::pair{img.T_W_S, 0.02}}) {
          const Eigen::Vector3d o = T.translation(), d = T.linear().col(2);
          const Eigen::Vector3d hit = o + d * ((-0.95 - o.x()) / d.x());
          EXPECT_LT((hit - target).norm(), tol) << hit.transpose();
        }
        ++settled_checks;
      }
    }
  }
  EXPECT_EQ(frames, 4000 / 67);  // 15 Hz: a frame every 67 steps
  EXPECT_GT(moving_frames, 20);
  EXPECT_GE(settled_checks, 4);
  // No more commands: the watchdog expires and the head goes home (pan 0, tilt 35 deg).
  r.step(1500);
  const hr::RobotStateSim st = r.state();
  EXPECT_NEAR(st.head.pan_truth, 0.0, 0.001);
  EXPECT_NEAR(st.head.tilt_truth, 35 * kDeg, 0.001);
  EXPECT_FALSE(st.head.gaze_active);
  EXPECT_EQ(st.head.gaze_refusals, 0u);
}

TEST(PanTiltHead, BadGazeTargetsAreRefusedAndTheHeadHolds) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  hemm::config::RobotConfig cfg;
  cfg.mutable_depth_camera()->set_enabled(true);
  cfg.mutable_depth_camera()->set_mount("pan-tilt");
  hr::SimulatedRobot r;
  ASSERT_FALSE(r.load(cfg, kScene));
  r.set_operator_in_control(true);
  ASSERT_FALSE(r.enable_depth_camera(hr::depth_camera_params_from_config(cfg)));
  // The robot at the origin facing +x: a point 1 m away at pan 30 deg, tilt
  // about 20 deg from the head (its height above W's floor is the base's
  // plus 1.10 m; only the pan is checked).
  const Eigen::Vector3d head_W(0.10, 0.0, 1.10);
  hr::BaseArmCommand c;
  c.mode = hemm::wire::MODE_EXPLORATION;
  auto send = [&](const Eigen::Vector3d& p, std::uint64_t seq) {
    c.seq = seq;
    c.gaze = {true, true, p};
    return r.set_command(c, r.time_ns());
  };
  const Eigen::Vector3d good = head_W + Eigen::Vector3d(std::cos(20 * kDeg) * std::cos(30 * kDeg),
                                                        std::cos(20 * kDeg) * std::sin(30 * kDeg), -std::sin(20 * kDeg));
  for (int k = 0; k < 100; ++k) {
    ASSERT_FALSE(send(good, 1));
    r.step(10);
  }
  const hr::RobotStateSim s0 = r.state();
  EXPECT_TRUE(s0.head.gaze_active);
  EXPECT_NEAR(s0.head.pan_truth, 30 * kDeg, 0.2 * kDeg);
  // A non-finite target: the command is rejected as a whole, nothing changes.
  const std::uint64_t rejected = r.rejected_commands();
  EXPECT_TRUE(send(Eigen::Vector3d(std::nan(""), 0, 1), 2));
  EXPECT_EQ(r.rejected_commands(), rejected + 1);
  // Beyond the pan limit (behind the robot): refused by the head, counted; it holds.
  for (int k = 0; k < 30; ++k) {
    ASSERT_FALSE(send(Eigen::Vector3d(-2.0, 0.1, 1.0), 3 + k));
    r.step(10);
  }
  const hr::RobotStateSim s1 = r.state();
  EXPECT_EQ(s1.head.gaze_refusals, 30u);
  EXPECT_EQ(s1.head.last_gaze_refusal, static_cast<int>(hr::GazeRefusal::kPanLimit));
  EXPECT_EQ(s1.head.last_gaze_refused_seq, 32u);
  EXPECT_NEAR(s1.head.pan_truth, s0.head.pan_truth, 0.01 * kDeg);
  // Too far and too near are refused too.
  ASSERT_FALSE(send(Eigen::Vector3d(8.0, 0.0, 1.0), 40));
  ASSERT_FALSE(send(head_W + Eigen::Vector3d(0.1, 0.0, 0.0), 41));
  EXPECT_EQ(r.state().head.last_gaze_refusal, static_cast<int>(hr::GazeRefusal::kTooNear));
  EXPECT_EQ(r.state().head.gaze_refusals, 32u);
  // Link lost: home, though commands (good ones) keep coming.
  r.set_link_lost(true);
  for (int k = 0; k < 150; ++k) {
    send(good, 50 + k);
    r.step(10);
  }
  EXPECT_NEAR(r.state().head.pan_truth, 0.0, 0.001);
  EXPECT_FALSE(r.state().head.gaze_active);
}
