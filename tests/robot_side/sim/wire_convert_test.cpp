// Conversions to and from the wire protos: exact round trips, chunking of
// large scans under the payload limit, and rejection of hostile messages.
#include "robot_side/sim/wire_convert.h"

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

namespace hr = hemm::robot;

namespace {
hr::RangeScanData make_scan(size_t n) {
  hr::RangeScanData s;
  s.stamp_ns = 123456789;
  s.scan_id = 42;
  s.kind = hr::RangeSensorKind::kLaser;
  s.sensor_name = "laser";
  s.T_W_R_odom = {1.0, -2.0, 0.3};
  s.T_W_R_truth = {1.01, -2.02, 0.31};
  s.T_R_S.translation() << 0.18, 0.0, 0.3;
  s.T_R_S.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  s.angle_min = -std::numbers::pi / 2;
  s.angle_step = std::numbers::pi / static_cast<double>(n - 1);
  s.range_min = 0.05;
  s.range_max = 10.0;
  for (size_t i = 0; i < n; ++i) {
    s.ranges.push_back(0.5f + 0.01f * static_cast<float>(i % 300));
    s.valid.push_back(i % 7 != 0);
    s.no_return.push_back(i % 14 == 0);  // half the invalid beams saw nothing, half dropped out
  }
  return s;
}
}  // namespace

TEST(WireConvert, LargeScanIsChunkedUnderThePayloadLimitAndReassembles) {
  for (size_t n : {16u, 181u, 721u, 1081u}) {
    const hr::RangeScanData s = make_scan(n);
    const auto chunks = hr::to_wire_chunks(s, hr::kMaxScanPayloadBytes);
    std::vector<float> ranges(n, -1.0f);
    std::vector<uint8_t> valid(n, 2), no_return(n, 2);
    uint32_t expected_first = 0;
    for (const auto& m : chunks) {
      EXPECT_LE(m.ByteSizeLong(), hr::kMaxScanPayloadBytes);
      hr::RangeScanData back;
      uint32_t first = 0;
      ASSERT_FALSE(hr::from_wire(m, &back, &first));
      EXPECT_EQ(first, expected_first);  // consecutive beams
      EXPECT_EQ(m.beam_count(), n);
      EXPECT_EQ(back.scan_id, s.scan_id);
      EXPECT_EQ(back.stamp_ns, s.stamp_ns);
      EXPECT_DOUBLE_EQ(back.T_W_R_odom.theta, s.T_W_R_odom.theta);
      EXPECT_LT((back.T_R_S.matrix() - s.T_R_S.matrix()).norm(), 1e-12);
      for (size_t i = 0; i < back.size(); ++i) {
        ranges[first + i] = back.ranges[i];
        valid[first + i] = back.valid[i];
        no_return[first + i] = back.no_return.at(i);
      }
      expected_first += static_cast<uint32_t>(back.size());
    }
    EXPECT_EQ(expected_first, n);
    EXPECT_EQ(ranges, s.ranges);
    EXPECT_EQ(valid, s.valid);
    EXPECT_EQ(no_return, s.no_return);
    // 6 bytes a beam plus ~150 bytes of header: the default 181-beam laser
    // scan needs two datagrams, the 16-beam sonar one.
    EXPECT_EQ(chunks.size() > 1, n >= 181) << n << " beams, " << chunks.size() << " chunks";
  }
}

TEST(WireConvert, RobotStateAndCommandRoundTrip) {
  hr::RobotStateSim s;
  s.stamp_ns = 99;
  s.T_W_R_odom = {1, 2, 3};
  s.T_W_R_truth = {1.1, 2.1, 3.1};
  s.v = 0.4;
  s.omega = -0.2;
  s.wheel_left = 0.3;
  s.wheel_right = 0.5;
  s.q << 0.1, 0.2, -0.3, 0.4, 0.5;
  s.qd << 1, 2, 3, 4, 5;
  s.tau << -1, -2, -3, -4, -5;
  s.T_R_E.translation() << 0.3, 0.1, 0.4;
  s.T_R_E.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  s.safety = hemm::wire::SAFETY_WATCHDOG | hemm::wire::SAFETY_COLLISION_GUARD;
  s.mode = hemm::wire::MODE_MANIPULATION;
  s.last_command_seq = 77;
  s.arm_refusals = 4;
  s.last_arm_refusal = hemm::wire::ARM_REFUSAL_SCENE;
  s.last_refused_seq = 75;
  hemm::wire::RobotState m;
  hr::to_wire(s, &m);
  hr::RobotStateSim b;
  ASSERT_FALSE(hr::from_wire(m, &b));
  EXPECT_EQ(b.arm_refusals, 4u);
  EXPECT_EQ(b.last_arm_refusal, hemm::wire::ARM_REFUSAL_SCENE);
  EXPECT_EQ(b.last_refused_seq, 75u);
  // An unknown refusal reason, or a count without a reason: refused.
  for (int reason : {9, 0}) {
    hemm::wire::RobotState bad = m;
    bad.set_last_arm_refusal(static_cast<hemm::wire::ArmRefusalReason>(reason));
    hr::RobotStateSim untouched;
    untouched.stamp_ns = -5;
    EXPECT_TRUE(hr::from_wire(bad, &untouched));
    EXPECT_EQ(untouched.stamp_ns, -5);
  }
  EXPECT_EQ(b.q, s.q);
  EXPECT_EQ(b.tau, s.tau);
  EXPECT_LT((b.T_R_E.matrix() - s.T_R_E.matrix()).norm(), 1e-12);
  EXPECT_EQ(b.safety, s.safety);
  EXPECT_EQ(b.mode, s.mode);
  EXPECT_EQ(b.last_command_seq, 77u);

  hr::BaseArmCommand c;
  c.stamp_ns = 5;
  c.mode = hemm::wire::MODE_NAVIGATION;
  c.v = 0.3;
  c.omega = 0.1;
  c.arm_target_R << 0.3, 0.0, 0.5;
  c.wrist_pitch = -0.2;
  c.wrist_roll = 0.1;
  c.deadman = true;
  hemm::wire::Command cm;
  hr::to_wire(c, &cm);
  hr::BaseArmCommand cb;
  ASSERT_FALSE(hr::from_wire(cm, 11, &cb));
  EXPECT_EQ(cb.seq, 11u);
  EXPECT_EQ(cb.arm_target_R, c.arm_target_R);
  EXPECT_EQ(cb.v, c.v);
  EXPECT_TRUE(cb.deadman);
}

TEST(WireConvert, HostileMessagesAreRejectedWithoutTouchingTheOutput) {
  hemm::wire::Command cm;
  cm.set_mode(hemm::wire::MODE_NAVIGATION);
  cm.set_v(std::nan(""));
  hr::BaseArmCommand c;
  c.v = 123.0;
  EXPECT_TRUE(hr::from_wire(cm, 1, &c));
  EXPECT_EQ(c.v, 123.0);
  cm.set_v(0.1);
  cm.set_mode(static_cast<hemm::wire::Mode>(99));
  EXPECT_TRUE(hr::from_wire(cm, 1, &c));

  const auto chunks = hr::to_wire_chunks(make_scan(100));
  ASSERT_EQ(chunks.size(), 1u);
  hr::RangeScanData out;
  out.scan_id = 5;
  uint32_t first = 0;
  auto m = chunks[0];
  m.set_first_beam(50);  // 50 + 100 > beam_count
  EXPECT_TRUE(hr::from_wire(m, &out, &first));
  m = chunks[0];
  m.add_valid(true);  // lengths differ
  EXPECT_TRUE(hr::from_wire(m, &out, &first));
  m = chunks[0];
  m.mutable_t_r_s()->mutable_orientation()->set_w(2.0);  // not a unit quaternion
  EXPECT_TRUE(hr::from_wire(m, &out, &first));
  m = chunks[0];
  m.set_range_max(-1.0);
  EXPECT_TRUE(hr::from_wire(m, &out, &first));
  EXPECT_EQ(out.scan_id, 5u);
  // A "valid" beam with a range outside the limits is read as invalid.
  m = chunks[0];
  m.set_ranges(1, 0.0f);
  ASSERT_FALSE(hr::from_wire(m, &out, &first));
  EXPECT_EQ(out.valid[1], 0);
}
