// Round trip: a simulated Omni recorded through RecordingDevice (writer thread)
// is loaded back and replayed by ReplayDevice sample for sample.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <vector>

#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/servo/trajectory_recorder.h"

namespace hemm::servo {
namespace {

using Eigen::Vector3d;

TEST(TrajectoryRecorder, RecordThenReplayReproducesEverySample) {
  for (bool with_q : {false, true}) {
    const std::string path = testing::TempDir() + (with_q ? "rec_q.csv" : "rec_p.csv");
    auto motion = std::make_shared<device::WaypointScript>(std::vector<device::Waypoint>{
        {0.0, Vector3d(0, 0, 0), 0},
        {0.2, Vector3d(0.03, 0.01, -0.01), device::kButton1},
        {0.5, Vector3d(-0.02, 0.04, 0.02), device::kButton2}});
    device::SimulatedOmni omni(device::SimulatedOmniModel{}, motion);
    auto recorder = make_trajectory_recorder(with_q, 1024);
    ASSERT_FALSE(recorder.start(path));
    RecordingDevice rec_dev(omni, recorder, 0.001);
    std::vector<device::DeviceSample> live;
    device::DeviceSample s;
    for (int i = 0; i < 600; ++i) {
      rec_dev.read(s);
      live.push_back(s);
      rec_dev.write(Vector3d(0.1, 0, 0));
    }
    recorder.stop();
    EXPECT_EQ(recorder.dropped(), 0u);

    device::Trajectory traj;
    const auto err = device::load_trajectory_csv(path, omni.limits(), &traj);
    ASSERT_FALSE(err) << err->to_string();
    ASSERT_EQ(traj.samples.size(), live.size());
    EXPECT_EQ(traj.has_orientation, with_q);

    device::ReplayDevice replay(traj, omni.limits(), 0.001);
    for (std::size_t i = 0; i < live.size(); ++i) {
      replay.read(s);
      // Sample times are exact multiples of dt, so replay hits the samples.
      EXPECT_LT((s.position_H - live[i].position_H).norm(), 1e-15) << i;
      EXPECT_EQ(s.buttons, live[i].buttons) << i;
      replay.write(Vector3d(0, 0, 0.5));
    }
    EXPECT_EQ(replay.forces_recorded(), live.size());
    EXPECT_EQ(replay.force(10).force_H, Vector3d(0, 0, 0.5));
    std::remove(path.c_str());
  }
}

}  // namespace
}  // namespace hemm::servo
