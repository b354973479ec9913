// The SIMULATED bimanual interface behind the HapticDevice API: limits that
// the servo loop accepts, read() reports what the simulation holds (poses in
// H = D, handle inputs by handle), write() applies the device-layer contract
// (non-finite -> zero and counted, peak clamp, a grip force on a handle
// without a grip counted and ignored, nothing on a disabled end-effector),
// the rendered wrench reaches the hand, and read/write allocate nothing.
#include "operator/device/bimanual/simulated_bimanual_device.h"

#include <chrono>
#include <cmath>
#include <thread>

#include <gtest/gtest.h>

#include "tests/operator/servo/alloc_counter.h"

namespace hb = hemm::device::bimanual;
namespace hd = hemm::device;
namespace hk = hemm::kinematics;
using Eigen::Vector3d;

namespace {

// Each hand on its own keyed script (right, left).
std::array<std::shared_ptr<const hb::HumanScript>, 2> keyed_hands(std::vector<hb::HumanKey> right,
                                                                  std::vector<hb::HumanKey> left) {
  return {std::make_shared<hb::HumanKeyScript>(std::move(right)), std::make_shared<hb::HumanKeyScript>(std::move(left))};
}

// Holds the hand where it starts, with a dead-man pressed.
std::array<std::shared_ptr<const hb::HumanScript>, 2> holding(const hb::SimulationConfig& c) {
  hb::BimanualSimulation s(c);
  const auto h = s.resting_targets();
  return keyed_hands({{0.0, h[0]}}, {{0.0, h[1]}});
}

}  // namespace

TEST(SimulatedBimanualDevice, LimitsAndReadings) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kJoystick};
  hb::SimulatedBimanualDevice dev(c, holding(c));
  const hd::DeviceLimits& l = dev.limits();
  EXPECT_EQ(hd::check_limits(l), nullptr);
  EXPECT_EQ(l.end_effectors, 2);
  EXPECT_TRUE(l.ee[0].renders_torque);
  EXPECT_GT(l.ee[0].peak_grip_force, 0.0);
  EXPECT_EQ(l.ee[1].peak_grip_force, 0.0);
  hd::DeviceSample s;
  dev.read(s);
  EXPECT_EQ(s.end_effectors, 2);
  for (int a = 0; a < 2; ++a) {
    const auto& e = s.ee[static_cast<size_t>(a)];
    const Eigen::Isometry3d& T = dev.simulation().end_effector(static_cast<hb::ArmSide>(a)).T_D_E;
    EXPECT_LT((e.position_H - T.translation()).norm(), 1e-12);
    EXPECT_NEAR(std::abs(e.orientation_H.dot(Eigen::Quaterniond(T.linear()))), 1.0, 1e-12);
    EXPECT_TRUE(e.enabled);
    EXPECT_TRUE(l.ee[static_cast<size_t>(a)].contains(e.position_H));
  }
  // The right hand is the one at -y; grip handle inputs on the right,
  // joystick (with dead-man) on the left.
  EXPECT_LT(s.ee[0].position_H.y(), 0.0);
  EXPECT_TRUE(s.ee[0].handle.has_grip);
  EXPECT_FALSE(s.ee[0].handle.has_deadman || s.ee[0].handle.has_joystick || s.ee[0].handle.has_clutch);
  EXPECT_TRUE(s.ee[1].handle.has_joystick && s.ee[1].handle.has_deadman && s.ee[1].handle.deadman);
  EXPECT_FALSE(s.ee[1].handle.has_grip);
}

TEST(SimulatedBimanualDevice, WriteEnforcesTheContractAndTheWrenchReachesTheHand) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kJoystick, hb::HandleKind::kMagneticClutch};
  hb::SimulatedBimanualDevice dev(c, holding(c));
  hd::DeviceCommand cmd;
  cmd.ee[0].force_H = Vector3d(0, 0, -12.0);  // pushes the right hand down
  cmd.ee[1].force_H = Vector3d(NAN, 0, 0);
  cmd.ee[0].grip_force = 3.0;  // the joystick handle has no grip
  for (int k = 0; k < 1500; ++k) dev.write(cmd);
  EXPECT_EQ(dev.counters().nonfinite_commands, 1500u);
  EXPECT_EQ(dev.counters().missing_input_commands, 1500u);
  EXPECT_TRUE(dev.simulation().output(hb::ArmSide::kLeft).w_env_applied_D.isZero(0.0));
  // The right hand, pushed down by 12 N rendered, settles where its arm
  // spring balances it: the grasp passes 12 N to the hand.
  const hb::HandTruth& h = dev.simulation().truth().hands[0];
  EXPECT_NEAR(h.grasp_force_D.z(), -12.0, 1.0);
  // Peak clamp.
  cmd.ee[0].force_H = Vector3d(0, 0, -1e4);
  cmd.ee[1].force_H = Vector3d::Zero();
  dev.write(cmd);
  EXPECT_EQ(dev.counters().limited_commands, 1u);
  EXPECT_NEAR(dev.simulation().output(hb::ArmSide::kRight).w_env_applied_D.head<3>().norm(), dev.limits().ee[0].peak_force,
              1e-9);
}

TEST(SimulatedBimanualDevice, DisabledEndEffectorGetsNothing) {
  // The left hand pulls its clutch off; from then its end-effector reads
  // disabled and commands to it are dropped and counted.
  hb::SimulationConfig c;
  hb::BimanualSimulation probe(c);
  auto h = probe.resting_targets();
  auto pull = h[1];
  pull.push_force_D = Vector3d(-250.0, 0, 0);
  hb::SimulatedBimanualDevice dev(c, keyed_hands({{0.0, h[0]}}, {{0.0, h[1]}, {0.3, pull}}));
  hd::DeviceCommand cmd;
  cmd.ee[1].force_H = Vector3d(0, 5, 0);
  hd::DeviceSample s;
  for (int k = 0; k < 1000; ++k) dev.write(cmd);
  dev.read(s);
  EXPECT_FALSE(s.ee[1].enabled);
  EXPECT_TRUE(s.ee[1].handle.has_clutch);
  EXPECT_FALSE(s.ee[1].handle.attached);
  EXPECT_FALSE(s.ee[1].handle.deadman);
  EXPECT_TRUE(s.ee[0].enabled);
  EXPECT_GT(dev.counters().disabled_commands, 100u);
  EXPECT_TRUE(dev.simulation().output(hb::ArmSide::kLeft).tau.isZero(0.0));
}

TEST(SimulatedBimanualDevice, ReadAndWriteAllocateNothing) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kJoystick};
  hb::SimulatedBimanualDevice dev(c, holding(c));
  hd::DeviceSample s;
  hd::DeviceCommand cmd;
  cmd.ee[0].force_H = Vector3d(1, 2, 3);
  cmd.ee[1].torque_H = Vector3d(0, 0, 0.2);
  cmd.ee[0].grip_force = 1.0;
  dev.read(s);
  dev.write(cmd);
  const auto before = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(true);
  for (int k = 0; k < 300; ++k) {
    dev.read(s);
    dev.write(cmd);
  }
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(hemm::test::counted_allocations() - before, 0u);
}

TEST(SimulatedBimanualDevice, RejectsNullScripts) {
  hb::SimulationConfig c;
  EXPECT_THROW(hb::SimulatedBimanualDevice(c, {nullptr, nullptr}), std::invalid_argument);
}

// Lock-step (the default) is the period as it always was: the controllers on
// the plant's readings, the plant one period with their torques, the
// hands where their scripts want them at the period's end. Written out here
// from the controller and the plant alone, bit for bit.
TEST(SimulatedBimanualDevice, LockStepIsTheControllersThenThePlantTickForTick) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kMagneticClutch};
  const auto hands = holding(c);
  hb::SimulatedBimanualDevice dev(c, hands);
  hb::BimanualPlant plant(c.plant);
  hb::BimanualController ctrl(c.plant.rig, c.plant.handles, c.control, c.plant.control_period_s);
  std::array<hb::ArmInput, 2> in{};
  std::array<hb::ArmOutput, 2> out{};
  for (std::size_t a = 0; a < 2; ++a) {
    in[a].q = plant.reading(static_cast<hb::ArmSide>(a)).q;
    in[a].qd = plant.reading(static_cast<hb::ArmSide>(a)).qd;
  }
  ctrl.update(in, out);
  hd::DeviceSample s;
  for (int k = 0; k < 400; ++k) {
    hd::DeviceCommand cmd;
    cmd.ee[0].force_H = Vector3d(3.0 * std::sin(0.01 * k), 2.0, -1.0);
    cmd.ee[1].torque_H = Vector3d(0.0, 0.3 * std::cos(0.02 * k), 0.0);
    cmd.ee[0].grip_force = 0.5;
    dev.read(s);
    dev.write(cmd);
    std::array<hb::ArmActuation, 2> act;
    for (std::size_t a = 0; a < 2; ++a) {
      const hb::ArmReading& r = plant.reading(static_cast<hb::ArmSide>(a));
      in[a].q = r.q;
      in[a].qd = r.qd;
      in[a].ft_J7 = r.ft_J7;
      in[a].w_env_D << cmd.ee[a].force_H, cmd.ee[a].torque_H;
      if (in[a].enabled != r.powered) ctrl.reset();
      in[a].enabled = r.powered;
    }
    ctrl.update(in, out);
    for (std::size_t a = 0; a < 2; ++a) {
      act[a].tau = out[a].tau;
      act[a].grip_force = cmd.ee[a].grip_force;
      act[a].power = true;
    }
    const double t = plant.time_s() + c.plant.control_period_s;
    plant.step(act, {hands[0]->at(t), hands[1]->at(t)});
    for (std::size_t a = 0; a < 2; ++a) {
      const auto side = static_cast<hb::ArmSide>(a);
      ASSERT_EQ(dev.simulation().output(side).tau, out[a].tau) << "tick " << k;
      ASSERT_EQ(dev.simulation().reading(side).q, plant.reading(side).q) << "tick " << k;
      ASSERT_EQ(dev.simulation().reading(side).qd, plant.reading(side).qd) << "tick " << k;
      ASSERT_EQ(dev.reading(side).ft_J7, plant.reading(side).ft_J7) << "tick " << k;
    }
  }
  EXPECT_EQ(dev.simulated_hardware(), nullptr);
}

// Threaded: the plant and the hands on their own thread; the servo side's
// read()/write() take the newest timestamped readings and hand over joint
// torques without allocating; the arms hold where the humans hold them.
TEST(SimulatedBimanualDevice, ThreadedThePlantStepsApartAndTheServoSideAllocatesNothing) {
  hb::SimulationConfig c;
  hb::SimulatedBimanualDevice dev(c, holding(c));
  hd::DeviceSample s0, s;
  dev.read(s0);
  hd::HardwareStart how;
  how.mode = hd::HardwareMode::kThreaded;
  std::vector<std::string> warnings;
  dev.start(how, &warnings);
  ASSERT_NE(dev.simulated_hardware(), nullptr);
  hd::DeviceCommand none;
  const auto before = hemm::test::counted_allocations();
  std::int64_t last = 0;
  int newer = 0;
  for (int k = 0; k < 600; ++k) {
    hemm::test::count_allocations_on_this_thread(true);
    dev.read(s);
    dev.write(none);
    hemm::test::count_allocations_on_this_thread(false);
    ASSERT_GE(s.measured_ns, last);
    if (s.measured_ns > last) ++newer;
    last = s.measured_ns;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  dev.stop();
  EXPECT_EQ(hemm::test::counted_allocations() - before, 0u);
  EXPECT_GT(newer, 50);  // new samples keep coming (one per plant period; fewer on a loaded machine)
  const hd::SimulatedHardwareStats& hw = *dev.simulated_hardware();
  EXPECT_GT(hw.commands_new.load(), 50u);
  EXPECT_NEAR(dev.simulation().time_s(), static_cast<double>(hw.timing.ticks.load()) * c.plant.control_period_s,
              1e-9);
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_TRUE(s.ee[a].enabled);
    EXPECT_LT((s.ee[a].position_H - s0.ee[a].position_H).norm(), 0.005) << "arm " << a;
  }
  EXPECT_TRUE(std::isfinite(dev.min_arm_arm_m()));
  // Lock-step again after stop(): a write steps the plant once more.
  const double t = dev.simulation().time_s();
  dev.write(none);
  EXPECT_NEAR(dev.simulation().time_s(), t + c.plant.control_period_s, 1e-12);
}

TEST(SimulatedBimanualDevice, CountsTheWritesInWhichItsOwnLimitsPushBack) {
  // At rest nothing of the device's own pushes on either hand; the right
  // hand then reaches 0.2 m below the workspace's floor (its arm spring
  // pulls it there): the arm-table avoidance stops it ~2 cm above the floor's
  // wall, and is counted for the right arm alone.
  hb::SimulationConfig c;
  hb::BimanualSimulation probe(c);
  auto h = probe.resting_targets();
  auto reach = h[0];
  reach.position_D.z() = c.control[0].workspace_D.min_D.z() - 0.2;
  hb::SimulatedBimanualDevice dev(c, keyed_hands({{0.0, h[0]}, {1.0, h[0]}, {1.5, reach}}, {{0.0, h[1]}}));
  const hd::DeviceCommand none;
  for (int k = 0; k < 900; ++k) dev.write(none);
  const hb::BimanualDeviceCounters& n = dev.counters();
  for (std::size_t a = 0; a < 2; ++a) {
    EXPECT_EQ(n.wall_writes[a], 0u) << "arm " << a;
    EXPECT_EQ(n.joint_limit_writes[a], 0u) << "arm " << a;
    EXPECT_EQ(n.collision_writes[a], 0u) << "arm " << a;
    EXPECT_EQ(n.stretched_writes[a], 0u) << "arm " << a;
  }
  for (int k = 0; k < 2100; ++k) dev.write(none);
  std::printf("right arm: wall %llu writes (peak %.1f N), joint range %llu (peak %.2f N m), avoidance %llu; z %.3f of wall %.3f\n",
              static_cast<unsigned long long>(n.wall_writes[0]), n.peak_wall_n[0],
              static_cast<unsigned long long>(n.joint_limit_writes[0]), n.peak_joint_limit_nm[0],
              static_cast<unsigned long long>(n.collision_writes[0]),
              dev.simulation().output(hb::ArmSide::kRight).T_D_E.translation().z(), c.control[0].workspace_D.min_D.z());
  EXPECT_GT(n.collision_writes[0], 100u);
  EXPECT_GT(n.peak_collision_nm[0], 0.5);
  EXPECT_GT(dev.simulation().output(hb::ArmSide::kRight).T_D_E.translation().z(), c.control[0].workspace_D.min_D.z());
  EXPECT_EQ(n.wall_writes[1] + n.joint_limit_writes[1] + n.collision_writes[1], 0u);
  EXPECT_EQ(n.peak_wall_n[1] + n.peak_joint_limit_nm[1] + n.peak_collision_nm[1], 0.0);
}

TEST(SimulatedBimanualDevice, CountsTheWritesWithAnArmAtTheEndOfItsReach) {
  // The right hand pulled 0.4 m towards the operator (-x in D): the arm
  // straightens (joint 4 near 0) and the hand stops short, with no limit term
  // engaged - the counter is what says why.
  hb::SimulationConfig c;
  hb::BimanualSimulation probe(c);
  auto h = probe.resting_targets();
  auto pull = h[0];
  pull.position_D.x() -= 0.4;
  hb::SimulatedBimanualDevice dev(c, keyed_hands({{0.0, h[0]}, {0.5, h[0]}, {1.5, pull}}, {{0.0, h[1]}}));
  const hd::DeviceCommand none;
  for (int k = 0; k < 3000; ++k) dev.write(none);
  const hb::BimanualDeviceCounters& n = dev.counters();
  const double q4 = dev.simulation().reading(hb::ArmSide::kRight).q(3);
  const double reached = h[0].position_D.x() - dev.simulation().output(hb::ArmSide::kRight).T_D_E.translation().x();
  std::printf("pulled 0.40 m towards the operator: reached %.3f m, elbow %.3f rad, stretched in %llu of 3000 writes\n", reached,
              q4, static_cast<unsigned long long>(n.stretched_writes[0]));
  EXPECT_LT(reached, 0.3);
  EXPECT_LT(std::abs(q4), 0.1);
  EXPECT_GT(n.stretched_writes[0], 500u);
  EXPECT_EQ(n.stretched_writes[1], 0u);
}
