// Round trip: a device recorded through RecordingDevice (writer thread) is
// loaded back and replayed by ReplayDevice sample for sample: the simulated
// Omni (one end-effector) and a two-end-effector test double whose every
// pose, twist and handle input must come back exactly.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <vector>

#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/servo/trajectory_recorder.h"
#include "tests/operator/servo/two_hand_device.h"
#include "tests/temp_dir.h"

namespace hemm::servo {
namespace {

using Eigen::Vector3d;

TEST(TrajectoryRecorder, RecordThenReplayReproducesEverySample) {
  const std::string path = hemm::test::make_temp_dir() + "/rec_omni.csv";
  auto motion = std::make_shared<device::WaypointScript>(std::vector<device::Waypoint>{
      {0.0, Vector3d(0, 0, 0), 0},
      {0.2, Vector3d(0.03, 0.01, -0.01), device::kButton1},
      {0.5, Vector3d(-0.02, 0.04, 0.02), device::kButton2}});
  device::SimulatedOmni omni(device::SimulatedOmniModel{}, motion);
  auto recorder = make_trajectory_recorder(1, 1024);
  ASSERT_FALSE(recorder.start(path));
  RecordingDevice rec_dev(omni, recorder, 0.001);
  std::vector<device::DeviceSample> live;
  device::DeviceSample s;
  for (int i = 0; i < 600; ++i) {
    rec_dev.read(s);
    live.push_back(s);
    rec_dev.write(device::force_command(Vector3d(0.1, 0, 0)));
  }
  recorder.stop();
  EXPECT_EQ(recorder.dropped(), 0u);

  device::Trajectory traj;
  const auto err = device::load_trajectory_csv(path, omni.limits(), &traj);
  ASSERT_FALSE(err) << err->to_string();
  ASSERT_EQ(traj.samples.size(), live.size());
  EXPECT_TRUE(traj.has_orientation);
  EXPECT_TRUE(traj.has_twist);

  device::ReplayDevice replay(traj, omni.limits(), 0.001);
  for (std::size_t i = 0; i < live.size(); ++i) {
    replay.read(s);
    // Sample times are exact multiples of dt, so replay hits the samples.
    EXPECT_LT((s.ee[0].position_H - live[i].ee[0].position_H).norm(), 1e-15) << i;
    EXPECT_EQ(s.ee[0].handle.buttons, live[i].ee[0].handle.buttons) << i;
    if (i + 1 < live.size()) {
      EXPECT_EQ(s.ee[0].velocity_H, live[i].ee[0].velocity_H) << i;
    }
    replay.write(device::force_command(Vector3d(0, 0, 0.5)));
  }
  EXPECT_EQ(replay.commands_recorded(), live.size());
  EXPECT_EQ(replay.command(10).command.ee[0].force_H, Vector3d(0, 0, 0.5));
  std::remove(path.c_str());
}

void expect_same(const device::EndEffectorSample& got, const device::EndEffectorSample& want, std::size_t i) {
  EXPECT_EQ(got.position_H, want.position_H) << i;
  EXPECT_EQ(got.orientation_H.coeffs(), want.orientation_H.coeffs()) << i;
  EXPECT_EQ(got.velocity_H, want.velocity_H) << i;
  EXPECT_EQ(got.angular_velocity_H, want.angular_velocity_H) << i;
  EXPECT_EQ(got.enabled, want.enabled) << i;
  const device::HandleInputs &g = got.handle, &w = want.handle;
  EXPECT_EQ(g.buttons, w.buttons) << i;
  EXPECT_EQ(device::handle_input_bits(g), device::handle_input_bits(w)) << i;
  EXPECT_EQ(g.deadman, w.deadman) << i;
  EXPECT_EQ(g.grip_position, w.grip_position) << i;
  EXPECT_EQ(g.grip_velocity, w.grip_velocity) << i;
  EXPECT_EQ(g.joystick, w.joystick) << i;
  EXPECT_EQ(g.switch_on, w.switch_on) << i;
  EXPECT_EQ(g.attached, w.attached) << i;
}

TEST(TrajectoryRecorder, TwoEndEffectorsRoundTripExactly) {
  const std::string path = hemm::test::make_temp_dir() + "/rec_two_hands.csv";
  constexpr int kTicks = 700;  // through the disabled window and several button/switch changes
  test::TwoHandDevice dev(kTicks);
  auto for_one = make_trajectory_recorder(1, 8);
  EXPECT_THROW(RecordingDevice(dev, for_one), std::invalid_argument);  // another end-effector count
  auto recorder = make_trajectory_recorder(2, 1024);
  ASSERT_FALSE(recorder.start(path));
  RecordingDevice rec_dev(dev, recorder, 0.001);
  device::DeviceSample s;
  for (int i = 0; i < kTicks; ++i) {
    rec_dev.read(s);
    rec_dev.write(device::DeviceCommand{});
  }
  recorder.stop();
  ASSERT_EQ(recorder.dropped(), 0u);

  device::Trajectory traj;
  const auto err = device::load_trajectory_csv(path, dev.limits(), &traj);
  ASSERT_FALSE(err) << err->to_string();
  ASSERT_EQ(traj.samples.size(), static_cast<std::size_t>(kTicks));
  EXPECT_EQ(traj.end_effectors, 2);

  device::ReplayDevice replay(traj, dev.limits(), 0.001);
  EXPECT_EQ(replay.limits().end_effectors, 2);
  for (std::size_t i = 0; i + 1 < static_cast<std::size_t>(kTicks); ++i) {
    replay.read(s);
    const device::DeviceSample want = dev.expected(i);
    ASSERT_EQ(s.end_effectors, 2);
    expect_same(s.ee[0], want.ee[0], i);
    expect_same(s.ee[1], want.ee[1], i);
    replay.write(device::DeviceCommand{});
  }
  // The window where end-effector 1 was disabled came back too.
  EXPECT_FALSE(traj.samples[test::TwoHandDevice::kDisabledFrom].ee[1].enabled);
  EXPECT_TRUE(traj.samples[test::TwoHandDevice::kDisabledTo].ee[1].enabled);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace hemm::servo
