// The SIMULATED humans of telemanipulation in the SIMULATED bimanual device
// (MuJoCo, lock-step), closed loop through the task's mapping: the demo
// route asks the right G 10 cm towards the bench and back and the right
// gripper closed and opened; the remote G is taken to follow its command
// (a perfect robot: this test is about the hands, not the robot). The
// commanded G must do what the route asks of it in A (the humans' arm
// springs track it within millimetres: nothing is rendered without a
// voxmap), the left arm stays, and the lever closes the gripper.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <numbers>

#include "config_operator.pb.h"
#include "wire.pb.h"
#include "operator/bimanual/bimanual_config.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "operator/telemanip/telemanip_config.h"
#include "operator/telemanip/telemanip_human.h"
#include "operator/telemanip/telemanip_task.h"

namespace tele = hemm::op::telemanip;
namespace hb = hemm::device::bimanual;

TEST(TelemanipHuman, DemoRouteDrivesTheRightArmThroughTheMappingAndWorksItsGripper) {
  hemm::config::BimanualDeviceConfig bc;
  bc.set_script("idle");
  bc.mutable_right()->set_handle("grip_force");
  bc.mutable_left()->set_handle("magnetic_clutch");
  hemm::op::BimanualSetup setup = hemm::op::bimanual_setup(bc);
  setup.sim.plant.control_period_s = 1e-3;
  hemm::config::TelemanipConfig tc;
  tc.set_enabled(true);
  tc.set_yaw_a_d_deg(30.0);  // not the shipped alignment: the route is in A whatever D is
  tc.mutable_right()->set_deadman_ee(1);
  tc.mutable_left()->set_deadman_ee(1);
  tele::TelemanipTaskParams tp;
  tele::TelemanipLinkParams lp;
  ASSERT_EQ(tele::telemanip_params(tc, 1e-3, hb::bimanual_limits(setup.sim), &tp, &lp), "");
  tp.render = false;  // no voxmap here: the hands feel nothing either way
  tele::TelemanipTask task(tp);
  const auto rest = hb::BimanualSimulation(setup.sim).resting_targets();
  const double travel = hb::handle_spec(hb::HandleKind::kGripForce).grip_travel;
  ASSERT_GT(travel, 0.0);
  auto right = std::make_shared<const tele::MappedHumanScript>(rest[0], tp.mapping[0], tele::demo_right_route(travel),
                                                               &task.anchors(0));
  auto left = std::make_shared<const tele::MappedHumanScript>(rest[1], tp.mapping[1], std::vector<tele::GRouteKey>{},
                                                              &task.anchors(1));
  hb::SimulatedBimanualDevice dev(setup.sim, {right, left});
  // The robot's G at the start (A), pointing down.
  tele::RemoteArmsState remote;
  remote.valid = true;
  remote.arm[0].p_A = Eigen::Vector3d(0.65, -0.25, 0.95);
  remote.arm[1].p_A = Eigen::Vector3d(0.65, 0.25, 0.95);
  for (auto& a : remote.arm) a.q_A = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX()));
  remote.gripper[0].opening_m = remote.gripper[1].opening_m = 0.12;
  task.remote().publish(remote);
  hemm::servo::ModelSnapshot empty;
  hemm::servo::TickOutput out;
  hemm::device::DeviceSample s;
  double max_fwd = 0.0, max_left_dev = 0.0, min_opening = 1.0;
  double back_at_end = 1.0, opening_at_end = 0.0;
  const int ticks = 11000;
  for (int i = 0; i < ticks; ++i) {
    dev.read(s);
    s.t_ns = static_cast<std::int64_t>(i) * 1'000'000;
    hemm::servo::prepare_tick_output(s, static_cast<std::uint64_t>(i), out);
    task.tick(s, empty, out);
    dev.write(out.command);
    if (!task.command(0).pressed) continue;
    const Eigen::Vector3d d0 = task.command(0).T_A_G.translation() - remote.arm[0].p_A;
    const Eigen::Vector3d d1 = task.command(1).T_A_G.translation() - remote.arm[1].p_A;
    max_fwd = std::max(max_fwd, d0.x());
    max_left_dev = std::max(max_left_dev, d1.norm());
    if (task.command(0).has_gripper) min_opening = std::min(min_opening, task.command(0).opening_m);
    back_at_end = d0.norm();
    opening_at_end = task.command(0).opening_m;
  }
  std::printf("right G: furthest %.4f m towards the bench, %.4f m from its start at the end; left G moved %.4f m; "
              "opening closed to %.4f m, %.4f at the end; presses %llu\n",
              max_fwd, back_at_end, max_left_dev, min_opening, opening_at_end,
              static_cast<unsigned long long>(task.mapping(0).presses));
  EXPECT_EQ(task.mapping(0).presses, 1u);  // held the whole route
  EXPECT_NEAR(max_fwd, 0.10, 0.01);
  EXPECT_LT(back_at_end, 0.01);
  EXPECT_LT(max_left_dev, 0.01);
  EXPECT_LT(min_opening, 0.02);              // the lever closed (0.0 at full travel)
  EXPECT_NEAR(opening_at_end, 0.12, 0.01);   // and opened again
}

// The human watching the robot's status: the dead-man released until the
// robot has reported for a reaction time, then pressed; when the robot asks
// to be re-armed (SAFETY_REARM) for a reaction time, released for one and
// pressed again, so the robot sees a neutral command and then a pressed one.
TEST(TelemanipHuman, PressesTheDeadManWhenTheRobotReportsAndAgainWhenItAsksToBeReArmed) {
  hemm::NewestMailbox<tele::MappingAnchor> anchors;
  std::atomic<std::uint32_t> safety{tele::kNoRobotState};
  hb::HumanTarget rest;
  rest.deadman = true;
  const tele::MappedHumanScript human(rest, tele::ArmMappingParams{}, {}, &anchors, 0.5, &safety);
  constexpr double r = tele::MappedHumanScript::kReaction_s;
  double t = 0.0;
  const auto run_until = [&](double t_end) {  // the dead-man over [t, t_end) at 1 kHz: pressed all along, or not
    int pressed = 0, n = 0;
    for (; t < t_end; t += 1e-3, ++n) pressed += human.at(t).deadman ? 1 : 0;
    return n == 0 ? -1 : (pressed == n ? 1 : (pressed == 0 ? 0 : 2));
  };
  EXPECT_EQ(run_until(2.0), 0) << "no robot status: never pressed";
  safety = 0;
  EXPECT_EQ(run_until(2.0 + r - 0.01), 0) << "the reaction time";
  EXPECT_EQ(run_until(2.0 + r + 0.01), 2);
  EXPECT_EQ(run_until(5.0), 1) << "pressed while the robot follows";
  safety = hemm::wire::SAFETY_REARM | hemm::wire::SAFETY_LINK_LOST;
  EXPECT_EQ(run_until(5.0 + r - 0.01), 1) << "still pressed within the reaction time";
  EXPECT_EQ(run_until(5.0 + r + 0.01), 2) << "let go";
  EXPECT_EQ(run_until(5.0 + 2 * r - 0.01), 0) << "released for a reaction time: a neutral command";
  EXPECT_EQ(run_until(5.0 + 2 * r + 0.02), 2) << "pressed again";
  safety = 0;  // the robot armed
  EXPECT_EQ(run_until(8.0), 1);
  // Without the robot's status the rest's dead-man holds throughout.
  const tele::MappedHumanScript blind(rest, tele::ArmMappingParams{}, {}, &anchors, 0.5, nullptr);
  EXPECT_TRUE(blind.at(0.0).deadman);
}
