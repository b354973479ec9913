// The live view's taps on the operator station (operator/view/view_feed.h):
// the servo task's tick with the view attached allocates nothing and puts the
// tick's record (the same one the world log gets) into the mailbox; a key
// press reaches the task as a button press, once; the model thread's
// snapshots are copied whole; the servo health meter reads the period
// histogram's quantiles over a window.
#include <gtest/gtest.h>
#include <numbers>

#include <cmath>
#include <thread>

#include "operator/view/view_feed.h"
#include "tests/operator/servo/alloc_counter.h"

namespace ho = hemm::op;
namespace hm = hemm::math;
namespace hd = hemm::device;
namespace hs = hemm::servo;
namespace hmap = hemm::mapping;

namespace {

std::unique_ptr<ho::OperatorModelSnapshot> wall_snapshot(hm::Pose2 T_W_R) {
  hmap::LocalMap lm;
  for (int i = 0; i < 3; ++i) {
    hmap::Segment2 s;
    s.a = Eigen::Vector2d(-3 + 2 * i, 1);
    s.b = Eigen::Vector2d(-1 + 2 * i, 1);
    s.normal = Eigen::Vector2d(0, -1);
    s.kind = i == 2 ? hmap::SensorKind::kSonar : hmap::SensorKind::kLaser;
    lm.segments.push_back(s);
  }
  auto snap = std::make_unique<ho::OperatorModelSnapshot>();
  snap->map = hmap::build_snapshot(hmap::MapParams{}, lm);
  snap->segments = lm.segments.size();
  snap->T_W_R = T_W_R;
  snap->have_state = true;
  snap->state.T_W_R_odom = hm::Pose2{T_W_R.x - 0.1, T_W_R.y, T_W_R.theta};
  snap->state.stamp_local_ns = 5;
  snap->stamp_ns = 0;
  snap->version = 7;
  return snap;
}

Eigen::Vector3d H(double xb, double yb, double zb) { return ho::R_B_H().transpose() * Eigen::Vector3d(xb, yb, zb); }

hs::TickOutput tick(ho::OperatorServoTask& task, const hs::ModelSnapshot& m, std::int64_t t, const Eigen::Vector3d& p_H) {
  hd::DeviceSample s;
  s.t_ns = t;
  s.ee[0].position_H = p_H;
  hs::TickOutput out;
  task.tick(s, m, out);
  return out;
}

TEST(ViewFeed, TickWithTheViewAttachedNeverAllocatesAndPublishesTheLogRecord) {
  ho::ViewFeed feed;
  auto log = ho::make_station_logger(256);  // not started: the ring fills, then drops are counted
  ho::OperatorServoTask task(ho::OperatorTaskParams{}, &log);
  task.set_view_outputs(&feed.ticks(), &feed.presses());
  // The session recorder's tap too (operator/record): nobody drains it here,
  // so it fills and then counts drops, without allocating either way.
  ho::ServoTickTap tap(1024);
  task.set_tick_tap(&tap);
  const auto snap = wall_snapshot({0, 0, std::numbers::pi / 2});
  std::int64_t t = 0;
  for (int i = 0; i < 10; ++i) tick(task, *snap, t += 1'000'000, H(0.001, 0, 0));  // warm up
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int i = 0; i < 3000; ++i) {
    const double s = std::sin(i * 0.005);
    tick(task, *snap, t += 1'000'000, H(0.022 * s, 0.01 * s, 0));
    if (i % 700 == 0) feed.press(hd::kButton2);  // as the view thread would
  }
  const std::uint64_t allocs = hemm::test::counted_allocations() - before;
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocs, 0u);
  EXPECT_EQ(tap.dropped.load(), 10u + 3000u - tap.ring.capacity());
  ho::ServoTickRecord first;
  ASSERT_TRUE(tap.ring.try_pop(first));
  EXPECT_EQ(first.model_version, 7u);
  EXPECT_EQ(first.in.ee[0].position_H, H(0.001, 0, 0));

  // The mailbox holds the last tick's record: the task's own state.
  ho::StationLogRecord r;
  ASSERT_TRUE(feed.take_tick(r));
  EXPECT_EQ(r.t_ns, t);
  EXPECT_DOUBLE_EQ(r.robot[0], task.robot_pose().x);
  EXPECT_DOUBLE_EQ(r.robot[2], task.robot_pose().theta);
  EXPECT_DOUBLE_EQ(r.proxy_W[0], task.proxy().proxy_W.x());
  EXPECT_DOUBLE_EQ(r.proxy_W[1], task.proxy().proxy_W.y());
  EXPECT_DOUBLE_EQ(r.force_W[1], task.proxy().force_W.y());
  EXPECT_EQ(r.mode, static_cast<std::uint32_t>(ho::to_wire_mode(task.mode())));
  EXPECT_DOUBLE_EQ(r.scale, task.map_of(task.mode()).scale);
  EXPECT_EQ(r.model_version, 7u);
  EXPECT_DOUBLE_EQ(r.odom[0], -0.1);
  EXPECT_FALSE(feed.take_tick(r));  // newest wins: one value per take
  // Five presses of button 2 (exploration <-> navigation), each taken once.
  EXPECT_EQ(task.mode_switches(), 5u);
}

TEST(ViewFeed, AKeyPressIsOneButtonPressOnTheNextTick) {
  ho::ViewFeed feed;
  ho::OperatorServoTask task(ho::OperatorTaskParams{});
  task.set_view_outputs(&feed.ticks(), &feed.presses());
  hs::ModelSnapshot empty;
  std::int64_t t = 0;
  for (int i = 0; i < 5; ++i) tick(task, empty, t += 1'000'000, H(0, 0, 0));
  ASSERT_EQ(task.mode(), hm::Mode::kExploration);
  feed.press(hd::kButton1);
  tick(task, empty, t += 1'000'000, H(0, 0, 0));
  EXPECT_EQ(task.mode(), hm::Mode::kNavigation);  // button 1: exploration -> navigation
  for (int i = 0; i < 5; ++i) tick(task, empty, t += 1'000'000, H(0, 0, 0));
  EXPECT_EQ(task.mode(), hm::Mode::kNavigation);  // taken once, not held
  EXPECT_EQ(task.mode_switches(), 1u);
}

TEST(ViewFeed, SnapshotsAreCopiedWholeAndOnlyTheNewestIsTaken) {
  ho::ViewFeed feed(2);  // at most two pieces kept
  ho::ViewModel m;
  EXPECT_FALSE(feed.take_model(m));
  auto a = wall_snapshot({1, 2, 0.5});
  feed.on_snapshot(*a);
  auto b = wall_snapshot({3, 4, 0.25});
  b->version = 8;
  feed.on_snapshot(*b);
  ASSERT_TRUE(feed.take_model(m));
  EXPECT_EQ(m.version, 8u);
  EXPECT_DOUBLE_EQ(m.T_W_R.x, 3);
  EXPECT_DOUBLE_EQ(m.state.T_W_R_odom.x, 2.9);
  EXPECT_TRUE(m.have_state);
  EXPECT_EQ(m.pieces_total, b->map.segments.size());
  ASSERT_EQ(m.segments.size(), 2u);  // bounded copy
  EXPECT_EQ(m.segments[0].a, b->map.segments[0].a);
  EXPECT_EQ(m.segments[1].b, b->map.segments[1].b);
  EXPECT_EQ(m.map_segments, 3u);
  EXPECT_FALSE(feed.take_model(m));
  EXPECT_EQ(feed.copies(), 2u);
}

TEST(ServoHealth, QuantilesOfTheWindowOnly) {
  hs::TimingStats t;
  ho::ServoHealthMeter meter;
  // First window: 1000 periods of 1.0 ms and 10 of 3.0 ms.
  for (int i = 0; i < 1000; ++i) t.period.record(1'000'200);
  for (int i = 0; i < 10; ++i) t.period.record(3'000'200);
  t.ticks.store(1010);
  t.misses.store(10);
  ho::ServoHealth h = meter.update(t, 1'000'000'000);
  EXPECT_NEAR(h.period_median_ms, 1.002, 1e-9);  // the log-spaced bin [1000, 1004) us, centre
  EXPECT_NEAR(h.period_p99_ms, 1.002, 1e-9);     // 10 of 1010 is under 1 %
  // The plot: the period's bins from 1 ms to 3 ms, log10 of the counts.
  ASSERT_EQ(h.histogram.lines.size(), 3u);
  EXPECT_TRUE(h.histogram.lines[0].x.empty());  // no compute recorded
  const auto& period = h.histogram.lines[2];
  ASSERT_FALSE(period.x.empty());
  EXPECT_NEAR(period.x.front(), std::log10(1002.0), 1e-6);        // [1000, 1004) us, centre
  EXPECT_NEAR(period.y.front(), std::log10(1001.0), 1e-5);        // 1000 ticks in it
  EXPECT_NEAR(period.x.back(), std::log10(3000.0), 1e-6);         // [2992, 3008) us, centre
  EXPECT_NEAR(period.y.back(), std::log10(11.0), 1e-5);
  EXPECT_EQ(h.window_misses, 10u);
  // Second window: 100 periods of 2.0 ms only.
  for (int i = 0; i < 100; ++i) t.period.record(2'000'500);
  t.ticks.store(1110);
  t.misses.store(12);
  h = meter.update(t, 1'500'000'000);
  EXPECT_NEAR(h.period_median_ms, 2.004, 1e-9);  // [2000, 2008) us
  EXPECT_NEAR(h.period_p99_ms, 2.004, 1e-9);
  EXPECT_EQ(h.window_ticks, 100u);
  EXPECT_EQ(h.window_misses, 2u);
  EXPECT_EQ(h.misses, 12u);
  EXPECT_NEAR(h.window_s, 0.5, 1e-12);
}

}  // namespace
