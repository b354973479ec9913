#include "robot_side/truth/truth_eval.h"

#include <numbers>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include <gtest/gtest.h>

#include "common/config/config.h"
#include "common/math/frames.h"
#include "report.pb.h"
#include "tests/common/config/report_json.h"

namespace hemm::robot {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using math::Pose2;

constexpr std::int64_t kMs = 1'000'000;
constexpr double kScale = 10.0;  // W m per device m: 2 cm in W is 2 mm at the hand

// A vertical wall at x = 1 (a segment; the proxy disc touches it at x = 0.97).
haptics::ExactScene wall_x1() {
  haptics::ExactScene s;
  s.segments.push_back({{1.0, -2.0}, {1.0, 2.0}});
  return s;
}

// Goal path in a frame where the wall is at x = 1: from x = 0.9 to 2 cm of
// penetration (0.99) in 100 ticks, then held for 300 ticks.
std::vector<Vector3d> push_path() {
  std::vector<Vector3d> p;
  for (int i = 0; i <= 100; ++i) p.emplace_back(0.9 + 0.09 * i / 100.0, 0.1, 0.4);
  for (int i = 0; i < 300; ++i) p.push_back(p.back());
  return p;
}

// Forces of the reference proxy along a path (what a perfect local model renders).
std::vector<Vector2d> reference_forces(const haptics::ExactScene& s, const haptics::ProxyModel& m,
                                       const std::vector<Vector3d>& path) {
  haptics::ProxyData d = haptics::make_proxy_data(m);
  haptics::proxy_reset(d, path.front().head<2>());
  std::vector<Vector2d> f;
  for (const auto& g : path) {
    haptics::reference_tick(m, s, d, g, kScale);
    f.push_back(d.force_W.head<2>());
  }
  return f;
}

// Rows with a truth sample per tick (stamp = t).
std::vector<WorldLogRow> make_rows(const Pose2& pred, const Pose2& truth, const std::vector<Vector3d>& goals_W,
                                   const std::vector<Vector2d>& fw) {
  std::vector<WorldLogRow> rows;
  for (std::size_t i = 0; i < goals_W.size(); ++i) {
    WorldLogRow r;
    r.t_ns = 1'000 * kMs + static_cast<std::int64_t>(i) * kMs;
    r.robot_x = pred.x;
    r.robot_y = pred.y;
    r.robot_theta = pred.theta;
    r.goal_x = goals_W[i].x();
    r.goal_y = goals_W[i].y();
    r.goal_z = goals_W[i].z();
    r.fw_x = fw[i].x();
    r.fw_y = fw[i].y();
    r.scale = kScale;
    r.state_stamp_ns = r.t_ns;
    r.truth_x = truth.x;
    r.truth_y = truth.y;
    r.truth_theta = truth.theta;
    r.has_truth = true;
    rows.push_back(r);
  }
  return rows;
}

TEST(TruthEval, PerfectRenderingHasZeroError) {
  const haptics::ProxyModel m;
  const auto scene = wall_x1();
  const auto path = push_path();
  const auto rows = make_rows({}, {}, path, reference_forces(scene, m, path));
  TruthOptions o;
  o.per_tick = true;
  const TruthReport r = evaluate_against_truth(rows, scene, m, o);
  EXPECT_EQ(r.rows, path.size());
  EXPECT_EQ(r.ticks, path.size());
  EXPECT_EQ(r.skipped_before_truth + r.skipped_invalid + r.held_after_truth, 0u);
  EXPECT_EQ(r.rms_n, 0.0);
  EXPECT_EQ(r.max_n, 0.0);
  EXPECT_GT(r.contact_ticks, 300u);
  EXPECT_EQ(r.mean_force_rendered_n, r.mean_force_truth_n);
  EXPECT_EQ(r.pose_error_max_m, 0.0);
  // Held 2 cm in W behind the contact: k * penetration / scale, along -x.
  ASSERT_EQ(r.per_tick.size(), path.size());
  EXPECT_NEAR(r.per_tick.back().f_truth_R.x(), -m.stiffness * 0.02 / kScale, 1e-9);
  EXPECT_NEAR(r.per_tick.back().f_truth_R.y(), 0.0, 1e-12);
  EXPECT_NEAR(r.per_tick.back().proxy_true_W.x(), 1.0 - m.probe_radius, 1e-9);
}

TEST(TruthEval, ConstantOffsetGivesItsMagnitude) {
  // Robot at a general pose (predicted = true): the offset is added in R.
  const haptics::ProxyModel m;
  const auto scene = wall_x1();
  const auto path = push_path();
  const Pose2 pose{0.2, 0.1, 0.3};
  auto fw = reference_forces(scene, m, path);
  const Vector2d offset_R(0.1, -0.05);
  for (auto& f : fw) f += math::rotate(pose, offset_R);
  const TruthReport r = evaluate_against_truth(make_rows(pose, pose, path, fw), scene, m);
  EXPECT_EQ(r.ticks, path.size());
  EXPECT_NEAR(r.rms_n, offset_R.norm(), 1e-9);
  EXPECT_NEAR(r.max_n, offset_R.norm(), 1e-9);
  EXPECT_EQ(r.contact_ticks, path.size());  // the offset alone exceeds 0.05 N
  EXPECT_NEAR(r.contact_rms_n, offset_R.norm(), 1e-9);
  EXPECT_NEAR(r.pose_error_max_m, 0.0, 1e-12);
}

TEST(TruthEval, PoseOffsetMovesTheTruePoint) {
  // The true robot is 5 mm further +x than predicted: the robot-relative
  // interaction point is 5 mm deeper in the true wall.
  const haptics::ProxyModel m;
  const auto scene = wall_x1();
  const auto path = push_path();
  const Pose2 pred{0, 0, 0}, truth{0.005, 0, 0};
  TruthOptions o;
  o.per_tick = true;
  const TruthReport r =
      evaluate_against_truth(make_rows(pred, truth, path, reference_forces(scene, m, path)), scene, m, o);
  EXPECT_NEAR(r.pose_error_mean_m, 0.005, 1e-12);
  EXPECT_NEAR(r.pose_error_max_m, 0.005, 1e-12);
  const TruthTick& last = r.per_tick.back();
  EXPECT_NEAR(last.f_truth_R.x(), -m.stiffness * 0.025 / kScale, 1e-9);
  EXPECT_NEAR(last.f_rendered_R.x(), -m.stiffness * 0.020 / kScale, 1e-9);
  EXPECT_NEAR(last.df, m.stiffness * 0.005 / kScale, 1e-9);
  EXPECT_GE(r.max_n, last.df - 1e-12);
  EXPECT_GT(r.mean_force_truth_n, r.mean_force_rendered_n);
}

TEST(TruthEval, ForcesAreComparedInTheRobotFrame) {
  // Predicted heading 0 with the wall ahead at x = 1 of the predicted W; the
  // true robot faces +y and the true wall is at y = 1: the same wall seen from
  // the robot, so the forces in R agree although they differ in W.
  const haptics::ProxyModel m;
  const auto path = push_path();
  haptics::ExactScene true_scene;
  true_scene.segments.push_back({{-2.0, 1.0}, {2.0, 1.0}});
  const Pose2 pred{0, 0, 0}, truth{0, 0, std::numbers::pi / 2};
  TruthOptions o;
  o.per_tick = true;
  const TruthReport r =
      evaluate_against_truth(make_rows(pred, truth, path, reference_forces(wall_x1(), m, path)), true_scene, m, o);
  EXPECT_LT(r.max_n, 1e-9);
  EXPECT_GT(r.contact_ticks, 300u);
  EXPECT_NEAR(r.heading_error_max_rad, std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(r.per_tick.back().proxy_true_W.y(), 1.0 - m.probe_radius, 1e-9);
}

TEST(TruthEval, InterpolatesSkipsAndHoldsTruth) {
  // Ticks every 1 ms at t = 0..30 ms; truth sample A (stamp 5 ms) arrives at
  // 8 ms, sample B (stamp 15 ms) at 20 ms. Nothing to touch (empty scene).
  std::vector<WorldLogRow> rows;
  for (int i = 0; i <= 30; ++i) {
    WorldLogRow r;
    r.t_ns = i * kMs;
    r.goal_x = 0.5;
    r.scale = kScale;
    if (i >= 8) {
      r.has_truth = true;
      const bool b = i >= 20;
      r.state_stamp_ns = (b ? 15 : 5) * kMs;
      r.truth_x = b ? 0.1 : 0.0;
      r.truth_theta = b ? -3.0 : 3.0;
    }
    rows.push_back(r);
  }
  TruthOptions o;
  o.per_tick = true;
  const TruthReport r = evaluate_against_truth(rows, haptics::ExactScene{}, haptics::ProxyModel{}, o);
  EXPECT_EQ(r.truth_samples, 2u);
  EXPECT_NEAR(r.truth_max_gap_s, 0.010, 1e-12);
  EXPECT_EQ(r.skipped_before_truth, 5u);  // t = 0..4 ms
  EXPECT_EQ(r.ticks, 26u);
  EXPECT_EQ(r.held_after_truth, 15u);     // t = 16..30 ms
  ASSERT_EQ(r.per_tick.size(), 26u);
  const TruthTick& mid = r.per_tick[5];   // t = 10 ms
  EXPECT_EQ(mid.t_ns, 10 * kMs);
  EXPECT_NEAR(mid.true_x, 0.05, 1e-12);
  // Shortest way from 3.0 to -3.0 passes through pi, not through 0.
  EXPECT_NEAR(math::wrap_angle(mid.true_theta - (3.0 + 0.5 * (2 * std::numbers::pi - 6.0))), 0.0, 1e-12);
  // Predicted at the origin: error |x_true| = 0.01 (t - 5) for t = 5..15, then 0.1 held.
  EXPECT_NEAR(r.pose_error_max_m, 0.1, 1e-12);
  EXPECT_NEAR(r.pose_error_mean_m, (0.55 + 15 * 0.1) / 26.0, 1e-12);
  EXPECT_EQ(r.contact_ticks, 0u);

  o.from_s = 0.010;
  o.to_s = 0.020;
  const TruthReport w = evaluate_against_truth(rows, haptics::ExactScene{}, haptics::ProxyModel{}, o);
  EXPECT_EQ(w.window_rows, 11u);
  EXPECT_EQ(w.ticks, 11u);
  EXPECT_EQ(w.skipped_before_truth, 0u);
  EXPECT_EQ(w.held_after_truth, 5u);
}

// ---------------------------------------------------------------- files

class TempDir {
 public:
  TempDir() {
    std::string t = (std::filesystem::temp_directory_path() / "hemm_truth_XXXXXX").string();
    if (mkdtemp(t.data()) != nullptr) path_ = t;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name, const std::string& text) const {
    const std::string p = path_ + "/" + name;
    std::ofstream(p, std::ios::binary) << text;
    return p;
  }

 private:
  std::string path_;
};

// The operator's header (operator/station/operator_task.cpp).
const std::string kHeader =
    "t_ns,mode,robot_x,robot_y,robot_theta,goal_x,goal_y,goal_z,proxy_x,proxy_y,fw_x,fw_y,fh_x,fh_y,fh_z,v,omega,"
    "contacts,model_version,model_age_ns,scale,state_stamp_ns,odom_x,odom_y,odom_theta,truth_x,truth_y,truth_theta,"
    "has_truth\n";
std::string row(int t_ms, const char* goal_x = "0.500000") {
  return std::to_string(t_ms * kMs) + ",1,0.1,0.2,0.3," + goal_x +
         ",0.6,0.7,0.8,0.9,0.01,0.02,0,0,0,0,0,1,3,1000,4.0," + std::to_string(t_ms * kMs - 5) +
         ",0,0,0,0.11,0.22,0.33,1\n";
}

TEST(WorldLogFile, ReadsColumnsByName) {
  TempDir dir;
  const std::string p = dir.file("ok.csv", kHeader + row(1) + row(2) + row(3));
  WorldLog log;
  std::string err;
  ASSERT_TRUE(read_world_log(p, &log, &err)) << err;
  ASSERT_EQ(log.rows.size(), 3u);
  EXPECT_EQ(log.truncated_lines, 0u);
  const WorldLogRow& r = log.rows[1];
  EXPECT_EQ(r.t_ns, 2 * kMs);
  EXPECT_DOUBLE_EQ(r.robot_theta, 0.3);
  EXPECT_DOUBLE_EQ(r.goal_x, 0.5);
  EXPECT_DOUBLE_EQ(r.goal_z, 0.7);
  EXPECT_DOUBLE_EQ(r.proxy_y, 0.9);
  EXPECT_DOUBLE_EQ(r.fw_y, 0.02);
  EXPECT_DOUBLE_EQ(r.scale, 4.0);
  EXPECT_EQ(r.state_stamp_ns, 2 * kMs - 5);
  EXPECT_DOUBLE_EQ(r.truth_theta, 0.33);
  EXPECT_TRUE(r.has_truth);

  // Another column order plus an unknown column: same values.
  const std::string q = dir.file("reordered.csv",
                                 "extra,scale,has_truth,truth_theta,truth_y,truth_x,state_stamp_ns,fw_y,fw_x,proxy_y,"
                                 "proxy_x,goal_z,goal_y,goal_x,robot_theta,robot_y,robot_x,t_ns\n"
                                 "9,4.0,1,0.33,0.22,0.11,1999995,0.02,0.01,0.9,0.8,0.7,0.6,0.5,0.3,0.2,0.1,2000000\n");
  WorldLog log2;
  ASSERT_TRUE(read_world_log(q, &log2, &err)) << err;
  ASSERT_EQ(log2.rows.size(), 1u);
  EXPECT_EQ(log2.rows[0].t_ns, r.t_ns);
  EXPECT_DOUBLE_EQ(log2.rows[0].goal_y, r.goal_y);
  EXPECT_DOUBLE_EQ(log2.rows[0].truth_x, r.truth_x);
}

TEST(WorldLogFile, TruncatedLastLineIsDroppedAndCounted) {
  TempDir dir;
  std::string last = row(3);
  last = last.substr(0, last.size() / 2);  // cut mid-number, no newline
  WorldLog log;
  std::string err;
  ASSERT_TRUE(read_world_log(dir.file("cut.csv", kHeader + row(1) + row(2) + last), &log, &err)) << err;
  EXPECT_EQ(log.rows.size(), 2u);
  EXPECT_EQ(log.truncated_lines, 1u);
}

TEST(WorldLogFile, BadFilesGiveClearErrors) {
  TempDir dir;
  WorldLog log;
  log.truncated_lines = 77;  // untouched on error
  std::string err;
  auto fails = [&](const std::string& path) {
    err.clear();
    const bool ok = read_world_log(path, &log, &err);
    return !ok && err.find(path) != std::string::npos;
  };
  EXPECT_TRUE(fails(dir.file("empty.csv", "")));
  EXPECT_NE(err.find("empty"), std::string::npos) << err;

  EXPECT_TRUE(fails("/nonexistent/run.csv.world.csv"));

  std::string no_scale = kHeader;
  no_scale.replace(no_scale.find("scale"), 5, "scalf");
  EXPECT_TRUE(fails(dir.file("nocol.csv", no_scale + row(1))));
  EXPECT_NE(err.find("missing column 'scale'"), std::string::npos) << err;

  // Line 3 (header is line 1), goal_x is field 6 at character column 1 + len("2000000,1,0.1,0.2,0.3,") = 23.
  EXPECT_TRUE(fails(dir.file("nan.csv", kHeader + row(1) + row(2, "abc") + row(3))));
  EXPECT_NE(err.find(":3:23:"), std::string::npos) << err;
  EXPECT_NE(err.find("goal_x"), std::string::npos) << err;
  EXPECT_NE(err.find("'abc'"), std::string::npos) << err;

  EXPECT_TRUE(fails(dir.file("short.csv", kHeader + row(1) + "1,2,3\n" + row(3))));
  EXPECT_NE(err.find(":3:"), std::string::npos) << err;

  EXPECT_TRUE(fails(dir.file("back.csv", kHeader + row(2) + row(1))));
  EXPECT_NE(err.find(":3:"), std::string::npos) << err;

  EXPECT_EQ(log.truncated_lines, 77u);
}

TEST(TruthEval, JsonReadsBackIntoTheTruthReport) {
  TruthReport r;
  r.rows = 12000;
  r.ticks = 10;
  r.contact_ticks = 4;
  r.rms_n = 0.25;
  r.max_n = 1.0 / 3.0;  // the old writer kept 9 digits
  r.max_t_s = 7.5;
  r.pose_error_max_m = 0.0125;
  report::Truth j = to_report(r);
  j.set_height_m(0.3);  // hemm-truth's run fields, set by the caller
  j.set_from_s(2.0);
  const report::Truth t = test::read_report_json<report::Truth>(config::to_json(j));
  EXPECT_EQ(t.rows(), 12000u);
  EXPECT_EQ(t.ticks(), 10u);
  EXPECT_EQ(t.contact_ticks(), 4u);
  ASSERT_TRUE(t.has_rms_n());
  EXPECT_EQ(t.rms_n(), 0.25);
  EXPECT_EQ(t.max_n(), 1.0 / 3.0);
  EXPECT_EQ(t.max_t_s(), 7.5);
  EXPECT_EQ(t.pose_error_max_m(), 0.0125);
  ASSERT_TRUE(t.has_contact_rms_n());  // evaluated: contact numbers are there (0 here)
  EXPECT_EQ(t.contact_rms_n(), 0.0);
  EXPECT_EQ(t.height_m(), 0.3);
  ASSERT_TRUE(t.has_from_s());
  EXPECT_EQ(t.from_s(), 2.0);
  EXPECT_FALSE(t.has_to_s());  // not given: absent, not NaN
}

TEST(TruthEval, NothingEvaluatedLeavesTheNumbersOut) {
  // A mean or maximum over no ticks has no value: absent from the JSON (a
  // reader's lookup fails) rather than 0 or a "NaN" string.
  const std::string json = config::to_json(to_report(TruthReport{}));
  const report::Truth t = test::read_report_json<report::Truth>(json);
  EXPECT_FALSE(t.has_rms_n());
  EXPECT_FALSE(t.has_max_n());
  EXPECT_FALSE(t.has_pose_error_max_m());
  EXPECT_FALSE(t.has_heading_error_max_rad());
  EXPECT_EQ(json.find("rms_n"), std::string::npos) << json;
  EXPECT_EQ(json.find("NaN"), std::string::npos) << json;
  EXPECT_NE(json.find("\"ticks\": \"0\""), std::string::npos) << json;  // counts are there, zeros too
}

}  // namespace
}  // namespace hemm::robot
