// The "features" script, run through the device and the environment task as
// the servo loop would but in simulated time (no wall clock): each feature
// shows up in what the device does - the elbows move outwards, the planes
// push back, collision avoidance keeps the arms apart, the orientation
// springs render torque, the grip object pushes on the forefinger, and the
// magnetic clutch comes off at the end and that arm stays braked.
#include "operator/bimanual/bimanual_scripts.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "operator/bimanual/bimanual_task.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"

namespace hb = hemm::device::bimanual;
namespace hd = hemm::device;

TEST(BimanualScripts, NamesAndUnknownName) {
  EXPECT_EQ(hemm::op::bimanual_script_names(), (std::vector<std::string>{"features", "idle"}));
  EXPECT_THROW(hemm::op::make_bimanual_hands("dance", hb::SimulationConfig{}), std::invalid_argument);
}

TEST(BimanualScripts, FeaturesShowsEveryFeature) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kMagneticClutch};
  const hemm::op::BimanualHands hands = hemm::op::make_bimanual_hands("features", c);
  hb::SimulatedBimanualDevice dev(c, hands.hands);
  hemm::op::HandEnvironment env;
  env.grip_object = true;
  hemm::op::BimanualTask task({env, env});
  hemm::servo::ModelSnapshot model;
  hd::DeviceSample s;
  const Eigen::Vector3d elbow0 = dev.simulation().output(hb::ArmSide::kRight).elbow_D;
  double elbow_out = 0, plane_f = 0, torque = 0, grip_f = 0, grip_x = 0;
  const int n = static_cast<int>(hands.duration_s * 1000);
  for (int k = 0; k < n; ++k) {
    const double t = k * 1e-3;
    dev.read(s);
    hemm::servo::TickOutput out;
    task.tick(s, model, out);
    dev.write(out.command);
    if (t < 1.5) elbow_out = std::max(elbow_out, -(dev.simulation().output(hb::ArmSide::kRight).elbow_D - elbow0).y());
    if (t > 2.0 && t < 3.5) plane_f = std::max(plane_f, out.command.ee[0].force_H.norm());
    if (t > 7.5 && t < 9.5) torque = std::max(torque, out.command.ee[1].torque_H.norm());
    if (t > 9.5 && t < 11.0) {
      grip_f = std::max(grip_f, out.command.ee[0].grip_force);
      grip_x = std::max(grip_x, s.ee[0].handle.grip_position);
    }
  }
  dev.read(s);
  std::printf("features: elbow out %.3f m, plane force %.1f N, torque %.2f N m, grip %.1f mm / %.2f N, "
              "min gaps arm-arm %.3f m arm-table %.3f m, left clutch %s\n",
              elbow_out, plane_f, torque, 1e3 * grip_x, grip_f, dev.min_arm_arm_m(), dev.min_arm_table_m(),
              s.ee[1].handle.attached ? "on" : "off");
  EXPECT_GT(elbow_out, 0.01);
  EXPECT_GT(plane_f, 10.0);
  EXPECT_GT(torque, 0.3);
  EXPECT_GT(grip_x, 0.011);
  EXPECT_GT(grip_f, 1.0);
  EXPECT_LT(dev.min_arm_arm_m(), hb::CollisionParams{}.activation_m);  // avoidance engaged
  EXPECT_GT(dev.min_arm_arm_m(), 0.03);
  EXPECT_EQ(dev.simulation().truth().arm_arm_contact_steps, 0u);
  EXPECT_EQ(dev.simulation().truth().arm_table_contact_steps, 0u);
  EXPECT_FALSE(s.ee[1].handle.attached);
  EXPECT_FALSE(s.ee[1].enabled);
  EXPECT_TRUE(s.ee[0].enabled);
  EXPECT_EQ(dev.counters().nonfinite_commands, 0u);
  EXPECT_EQ(dev.counters().missing_input_commands, 0u);
}
