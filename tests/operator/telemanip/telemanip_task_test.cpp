// The telemanipulation servo task with both hands: the remote G follows the
// hand through the mapping, each gripper's pointshell pressed into a bench
// voxmap pushes its own hand back with the series-spring closed form of the
// coupling and the pads' contact (K * pad area), the hand in free space
// feels nothing, a gripper that holds something feels its palm alone, a
// released dead-man stops pressing and displays nothing, an object held by
// both grippers couples the hands and weighs on them,
// and the tick allocates nothing with both hands rendering.
#include "operator/telemanip/telemanip_task.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numbers>
#include <vector>

#include "common/clock/steady_clock.h"
#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"
#include "operator/telemanip/telemanip_replay.h"
#include "tests/operator/servo/alloc_counter.h"
#include "tests/operator/telemanip/arms_state_wire.h"
#include "tests/sanitizer_build.h"

namespace tele = hemm::op::telemanip;
namespace hd = hemm::device;

namespace {

// A bench of its own (not workbench.xml's, on which nothing was tuned):
// top at z = 0.72, x 0.4..1.0, y -0.6..0.6 (A = W).
constexpr double kTaskTestTopZ = 0.72;

hemm::vps::Voxmap task_test_bench(double voxel) {
  hemm::mesh::TriangleMesh m;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.7, 0.0, kTaskTestTopZ - 0.05);
  hemm::mesh::append_mesh(&m, hemm::mesh::make_box({0.3, 0.6, 0.05}, 6), T);
  hemm::vps::VoxmapParams vp;
  vp.voxel_size = voxel;
  vp.layers_in = vp.layers_out = 4;
  hemm::vps::Voxmap vm;
  auto e = hemm::vps::build_voxmap(m, vp, &vm, nullptr);
  EXPECT_FALSE(e.has_value()) << (e ? e->message : "");
  return vm;
}

// The robot faces the operator: D's x is A's -x (z shared).
tele::TelemanipTaskParams task_test_params() {
  tele::TelemanipTaskParams p;
  for (auto& m : p.mapping) {
    m.R_A_D = Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    m.opening_open_m = 0.08;
  }
  const hd::DeviceLimits l = hd::rigid_hand_limits(2);
  p.limits = {l.ee[0], l.ee[1]};
  p.tick_budget_ns = 0;  // the force test: every level, whatever the machine's load
  p.budget = hemm::vps::kUnlimitedWork;
  // The sanitizer pass builds the gripper's shells every 8 cm, not every 2:
  // 4 shells, not 12 (building them was 50 s of each test there, 30 times
  // its release cost); the openings these tests use, 0 and 8 cm, are among them.
  if (hemm::test::kSanitizerBuild) p.gripper.opening_step_m = 0.08;
  return p;
}

// G pointing down (its z along A's -z), fingers along A's y.
Eigen::Quaterniond task_test_down() { return Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX())); }

tele::RemoteArmsState task_test_remote(const Eigen::Vector3d& right, const Eigen::Vector3d& left) {
  tele::RemoteArmsState r;
  r.valid = true;
  r.arm[0].p_A = right;
  r.arm[0].q_A = task_test_down();
  r.arm[1].p_A = left;
  r.arm[1].q_A = task_test_down();
  r.gripper[0].opening_m = r.gripper[1].opening_m = 0.08;
  return r;
}

hd::DeviceSample task_test_sample(const Eigen::Vector3d& right_D, const Eigen::Vector3d& left_D, bool deadman) {
  hd::DeviceSample s;
  s.end_effectors = 2;
  const std::array<Eigen::Vector3d, 2> p{right_D, left_D};
  for (int k = 0; k < 2; ++k) {
    hd::EndEffectorSample& e = s.ee[static_cast<std::size_t>(k)];
    e.position_H = p[static_cast<std::size_t>(k)];
    e.handle.has_deadman = true;
    e.handle.deadman = deadman;
  }
  return s;
}

struct TaskTestRun {
  tele::TelemanipTask task;
  hemm::servo::ModelSnapshot empty;
  hemm::servo::TickOutput out;
  std::uint64_t tick = 0;
  explicit TaskTestRun(const tele::TelemanipTaskParams& p) : task(p) {}
  void step(const hd::DeviceSample& s) {
    hemm::servo::prepare_tick_output(s, ++tick, out);
    task.tick(s, empty, out);
  }
};

// The direct mode: no model rendered, the device's peak force as the hands' bound.
tele::TelemanipTaskParams task_test_direct_params() {
  tele::TelemanipTaskParams p = task_test_params();
  p.mode = tele::FeedbackMode::kDirect;
  p.render = false;
  for (int k = 0; k < 2; ++k) {
    p.direct[static_cast<std::size_t>(k)].R_A_D = p.mapping[static_cast<std::size_t>(k)].R_A_D;
    p.direct[static_cast<std::size_t>(k)].peak_force_n = p.limits[static_cast<std::size_t>(k)].peak_force;
  }
  return p;
}

const Eigen::Vector3d kTaskTestRightA(0.65, -0.25, 0.85), kTaskTestLeftA(0.7, 0.25, 0.9);
const Eigen::Vector3d kTaskTestRightD(0.3, -0.2, 0.3), kTaskTestLeftD(0.3, 0.2, 0.3);

// Counts this thread's allocations from now on; false if the counter does
// not see an allocation made on purpose.
bool task_test_start_counting() {
  hemm::test::count_allocations_on_this_thread(true);
  const std::uint64_t probe = hemm::test::counted_allocations();
  auto* q = new std::array<double, 16>{};
  asm volatile("" : : "g"(q) : "memory");
  delete q;
  return hemm::test::counted_allocations() > probe;
}

}  // namespace

TEST(TelemanipTask, GripperPressedIntoTheBenchPushesItsOwnHandBack) {
  const tele::TelemanipTaskParams p = task_test_params();
  const hemm::vps::Voxmap bench = task_test_bench(0.01);
  TaskTestRun run(p);
  run.task.set_voxmap_override(&bench, 1);
  run.task.remote().publish(task_test_remote(kTaskTestRightA, kTaskTestLeftA));
  // The right hand goes down 12 cm over 0.4 s: G to 0.73, the finger tips
  // (2.5 cm beyond G along G's z, here A's -z) to 0.705, 15 mm into the bench top.
  const double down = 0.12;
  const int ramp = 400, hold = 1500;
  for (int i = 0; i <= ramp + hold; ++i) {
    const double f = std::min(1.0, static_cast<double>(i) / ramp);
    run.step(task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, down * f), kTaskTestLeftD, true));
  }
  // The remote G was told where the hand went (z is shared by A and D).
  const Eigen::Isometry3d G = run.task.command(0).T_A_G;
  EXPECT_LT((G.translation() - (kTaskTestRightA - Eigen::Vector3d(0, 0, down))).norm(), 1e-9);
  EXPECT_TRUE(run.task.command(0).pressed);
  // Finger tips: 2.5 cm beyond G along its z (here A's -z).
  const double tips_z = G.translation().z() - 0.025;
  const double commanded_depth = kTaskTestTopZ - tips_z;
  ASSERT_NEAR(commanded_depth, 0.015, 1e-9);
  // Closed form: the coupling's spring in series with the pads' contact
  // stiffness K * A (two 36 x 12 mm pads).
  const double k_c = run.task.tool_params(0).coupling.k_lin;
  const double k_s = p.contact_stiffness * 2.0 * 0.036 * 0.012;
  const double f_expected = k_c * k_s / (k_c + k_s) * commanded_depth;
  const Eigen::Vector3d F = run.out.command.ee[0].force_H;
  std::printf("k_c %.0f N/m, k_s %.0f N/m: F_D (%.3f, %.3f, %.3f) N, closed form %.3f N\n", k_c, k_s, F.x(), F.y(),
              F.z(), f_expected);
  EXPECT_NEAR(F.z(), f_expected, 0.2 * f_expected);
  EXPECT_LT(F.head<2>().norm(), 0.05 * F.z());  // symmetric pads: straight up
  EXPECT_LT(run.out.command.ee[0].torque_H.norm(), 0.05 * F.z() * 0.1);
  // The left hand, in free space above the bench, feels nothing.
  EXPECT_LT(run.out.command.ee[1].force_H.norm(), 1e-6);
  EXPECT_GT(run.task.render_stats(0).contact_ticks, 1000u);
  EXPECT_EQ(run.task.render_stats(1).contact_ticks, 0u);
  // The setpoint for the link carries both arms, the right one pressed down there.
  const tele::TelemanipSetpoint* sp = run.task.setpoints().take();
  ASSERT_NE(sp, nullptr);
  EXPECT_TRUE(sp->arm[0].active && sp->arm[0].pressed && sp->arm[1].active);
  EXPECT_NEAR(sp->arm[0].p_A.z(), 0.73, 1e-9);
  // The remote gripper says it holds something: its fingers are on the held
  // object, whose own voxels the live voxmap keeps, so the palm's shell alone
  // is rendered - here 7.5 cm and more above G, off the bench: nothing felt.
  tele::RemoteArmsState holding = task_test_remote(kTaskTestRightA, kTaskTestLeftA);
  holding.gripper[0].holding = true;
  run.task.remote().publish(holding);
  const std::uint64_t contacts = run.task.render_stats(0).contact_ticks;
  for (int i = 0; i < 300; ++i)
    run.step(task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, down), kTaskTestLeftD, true));
  EXPECT_LT(run.out.command.ee[0].force_H.norm(), 0.02 * f_expected);
  EXPECT_LE(run.task.render_stats(0).contact_ticks - contacts, 10u);
  // Let go (not holding, the lever open): still the grasp phase - the
  // fingers are around what they let go of - until the hand has left by
  // kGraspClear_m: 10 cm up and back down into the bench, the fingers are
  // felt again.
  run.task.remote().publish(task_test_remote(kTaskTestRightA, kTaskTestLeftA));
  hd::DeviceSample pressed_in = task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, down), kTaskTestLeftD, true);
  pressed_in.ee[0].handle.has_grip = true;
  pressed_in.ee[0].handle.grip_position = 0.0;  // open: the commanded opening is the open one, 0.08
  for (int i = 0; i < 300; ++i) run.step(pressed_in);
  EXPECT_NEAR(run.task.command(0).opening_m, 0.08, 1e-9);
  EXPECT_LT(run.out.command.ee[0].force_H.norm(), 0.02 * f_expected);
  const double s = p.mapping[0].translation_scale, up = 0.10;
  ASSERT_GT(up, tele::TelemanipTask::kGraspClear_m);
  for (int i = 0; i <= 2000; ++i) {
    hd::DeviceSample m = pressed_in;
    m.ee[0].position_H.z() += up / s * std::sin(std::numbers::pi * std::min(1.0, i / 1000.0));  // up and back
    run.step(m);
  }
  EXPECT_NEAR(run.out.command.ee[0].force_H.z(), f_expected, 0.2 * f_expected);
  // The lever closes the fingers below the remote opening (0.08): the grasp
  // phase again, the palm's shell alone.
  pressed_in.ee[0].handle.grip_position = 0.5 * p.mapping[0].grip_travel_m;
  for (int i = 0; i < 300; ++i) run.step(pressed_in);
  EXPECT_LT(run.task.command(0).opening_m, 0.08 - tele::TelemanipTask::kClosingTol_m);
  EXPECT_LT(run.out.command.ee[0].force_H.norm(), 0.02 * f_expected);
  // So too from the start when the remote gripper keeps up with the lever:
  // the opening below the widest commanded tells the closing then. (A fresh
  // hand: the one above left its grasp phase by moving off, not by opening.)
  {
    TaskTestRun fresh(p);
    fresh.task.set_voxmap_override(&bench, 1);
    tele::RemoteArmsState following = task_test_remote(kTaskTestRightA, kTaskTestLeftA);
    fresh.task.remote().publish(following);
    hd::DeviceSample m = pressed_in;
    m.ee[0].handle.grip_position = 0.0;
    for (int i = 0; i <= ramp + hold; ++i) {
      const double f = std::min(1.0, static_cast<double>(i) / ramp);
      m.ee[0].position_H = kTaskTestRightD - Eigen::Vector3d(0, 0, down * f);
      fresh.step(m);
    }
    EXPECT_NEAR(fresh.out.command.ee[0].force_H.z(), f_expected, 0.2 * f_expected);
    // The lever closes a little past kLeverClosing_m (the remote with it):
    // already the grasp phase, before the pads could meet anything.
    const double span = p.mapping[0].opening_open_m - p.mapping[0].opening_closed_m;
    m.ee[0].handle.grip_position = (tele::TelemanipTask::kLeverClosing_m + 0.001) / span * p.mapping[0].grip_travel_m;
    for (int i = 0; i < 100; ++i) {
      fresh.step(m);
      following.gripper[0].opening_m = fresh.task.command(0).opening_m;
      fresh.task.remote().publish(following);
    }
    EXPECT_LT(fresh.task.command(0).opening_m, p.mapping[0].opening_open_m - tele::TelemanipTask::kLeverClosing_m);
    EXPECT_GT(fresh.task.command(0).opening_m, p.mapping[0].opening_open_m - 0.005);
    EXPECT_LT(fresh.out.command.ee[0].force_H.norm(), 0.02 * f_expected);
    m.ee[0].handle.grip_position = 0.5 * p.mapping[0].grip_travel_m;
    for (int i = 0; i < 300; ++i) {
      fresh.step(m);
      following.gripper[0].opening_m = fresh.task.command(0).opening_m;  // at once, as the lever asks
      fresh.task.remote().publish(following);
    }
    EXPECT_LT(fresh.task.command(0).opening_m, 0.08 - tele::TelemanipTask::kClosingTol_m);
    EXPECT_LT(fresh.out.command.ee[0].force_H.norm(), 0.02 * f_expected);
    // It closed on nothing (never held): the lever open again ends the
    // grasp phase where the hand is; the fingers are felt again.
    m.ee[0].handle.grip_position = 0.0;
    for (int i = 0; i < 500; ++i) {
      fresh.step(m);
      following.gripper[0].opening_m = fresh.task.command(0).opening_m;
      fresh.task.remote().publish(following);
    }
    EXPECT_NEAR(fresh.out.command.ee[0].force_H.z(), f_expected, 0.2 * f_expected);
  }
  // Dead-man released: nothing pressed, nothing displayed, the command holds.
  run.step(task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, down + 0.05), kTaskTestLeftD, false));
  EXPECT_FALSE(run.task.command(0).pressed);
  EXPECT_LT(run.out.command.ee[0].force_H.norm(), 1e-12);
  EXPECT_TRUE(run.task.command(0).T_A_G.isApprox(G, 1e-12));
}

// In a grasp phase the palm's shell is rendered only when configured
// (telemanip.held.palm_contact): held, the hand goes down until the palm
// (7.5 cm and more above G) would be 1.5 cm into the bench; off (the
// default), nothing is felt and the ticks count as grasp ticks; on, the
// bench pushes the hand up.
TEST(TelemanipTask, InAGraspPhaseThePalmIsFeltOnlyWhenConfigured) {
  const hemm::vps::Voxmap bench = task_test_bench(0.01);
  for (const bool palm : {false, true}) {
    tele::TelemanipTaskParams p = task_test_params();
    p.grasp_palm_contact = palm;
    TaskTestRun run(p);
    run.task.set_voxmap_override(&bench, 1);
    tele::RemoteArmsState held = task_test_remote(kTaskTestRightA, kTaskTestLeftA);
    held.gripper[0].holding = true;
    run.task.remote().publish(held);
    const double down = kTaskTestRightA.z() - (kTaskTestTopZ - 0.075 - 0.015);
    for (int i = 0; i <= 1500; ++i) {
      const double f = std::min(1.0, i / 1000.0);
      run.step(task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, down * f), kTaskTestLeftD, true));
    }
    const Eigen::Vector3d F = run.out.command.ee[0].force_H;
    if (palm) {
      EXPECT_GT(F.z(), 5.0);
      EXPECT_GT(run.task.render_stats(0).contact_ticks, 100u);
      EXPECT_EQ(run.task.render_stats(0).grasp_ticks, 0u);
    } else {
      EXPECT_LT(F.norm(), 1e-9);
      EXPECT_EQ(run.task.render_stats(0).contact_ticks, 0u);
      EXPECT_GT(run.task.render_stats(0).grasp_ticks, 1400u);
    }
  }
}

// Both remote grippers report holding one object, each wrist 9.81 N of its
// weight: each hand feels that weight (times the translation scale), and,
// when the right hand moves 5 mm (1 cm in A), the coupling pulls it back
// with the spring's force (held_object.h), equal and opposite on the left.
TEST(TelemanipTask, AnObjectHeldByBothGrippersCouplesTheHandsAndWeighsOnThem) {
  tele::TelemanipTaskParams p = task_test_params();
  for (auto& m : p.mapping) m.translation_scale = 2.0;
  TaskTestRun run(p);  // no voxmap: the held object's wrench alone
  tele::RemoteArmsState rs = task_test_remote(kTaskTestRightA, kTaskTestLeftA);
  for (int k = 0; k < 2; ++k) {
    rs.gripper[static_cast<std::size_t>(k)].holding = true;
    rs.arm[static_cast<std::size_t>(k)].force_A = Eigen::Vector3d(0, 0, -9.81);
  }
  run.task.remote().publish(rs);
  for (int i = 0; i < 3000; ++i) run.step(task_test_sample(kTaskTestRightD, kTaskTestLeftD, true));
  EXPECT_EQ(run.task.held().holds, 1u);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d F = run.out.command.ee[static_cast<std::size_t>(k)].force_H;
    EXPECT_NEAR(F.z(), -2.0 * 9.81, 1e-3) << k;  // F_D = s F_A, z shared by A and D
    EXPECT_NEAR(F.head<2>().norm(), 0.0, 1e-9) << k;
  }
  // The right hand 5 mm along D's y (A's -y: away from the left hand) over
  // 100 ticks, then held: stretched by 1 cm in A.
  for (int i = 1; i <= 600; ++i) {
    const double f = std::min(1.0, i / 100.0);
    run.step(task_test_sample(kTaskTestRightD + Eigen::Vector3d(0, 0.005 * f, 0), kTaskTestLeftD, true));
  }
  ASSERT_NEAR(run.task.command(0).T_A_G.translation().y(), kTaskTestRightA.y() - 0.01, 1e-9);
  const double spring_A = p.held.stiffness_n_per_m * 0.01;
  const Eigen::Vector3d F0 = run.out.command.ee[0].force_H, F1 = run.out.command.ee[1].force_H;
  EXPECT_NEAR(F0.y(), -2.0 * spring_A, 1e-6);  // back towards where it took hold (D's -y)
  EXPECT_NEAR(F1.y(), 2.0 * spring_A, 1e-6);   // the left pulled towards the right
  EXPECT_NEAR(F0.x(), 0.0, 1e-9);
  EXPECT_NEAR(F0.z(), -2.0 * 9.81, 1e-3);
  // Its largest: the spring and the damper at the ramp's end (0.1 m/s in A).
  EXPECT_GT(run.task.held().peak_squeeze_n, spring_A - 1e-6);
  EXPECT_LT(run.task.held().peak_squeeze_n, spring_A + p.held.damping_ns_per_m * 0.1 + 1e-6);
  // The dead-man released: the coupling and the weight's pull end (the weight fades at its rate).
  run.step(task_test_sample(kTaskTestRightD, kTaskTestLeftD, false));
  EXPECT_FALSE(run.task.held().both_held);
}

TEST(TelemanipTask, WithoutARobotStateNothingIsCommanded) {
  TaskTestRun run(task_test_params());
  for (int i = 0; i < 50; ++i) run.step(task_test_sample(kTaskTestRightD, kTaskTestLeftD, true));
  const tele::TelemanipSetpoint* sp = run.task.setpoints().take();
  ASSERT_NE(sp, nullptr);
  EXPECT_FALSE(sp->arm[0].active);
  EXPECT_FALSE(sp->arm[1].active);
  EXPECT_FALSE(run.task.command(0).pressed);
}

// Both hands pressing their grippers into the bench, with the time budget as
// shipped: no heap allocation in 2000 ticks; the compute is printed.
TEST(TelemanipTask, TickAllocatesNothingWithBothHandsRendering) {
  tele::TelemanipTaskParams p = task_test_params();
  p.tick_budget_ns = 100'000;
  p.budget = 4000;
  const hemm::vps::Voxmap bench = task_test_bench(0.01);
  TaskTestRun run(p);
  run.task.set_voxmap_override(&bench, 1);
  run.task.set_trace(true);  // the hand trace's sample too (--hand-trace)
  run.task.remote().publish(task_test_remote(kTaskTestRightA, kTaskTestLeftA));
  // Both down to 1 cm into the bench first (and the grippers' shells chosen).
  for (int i = 0; i < 600; ++i) {
    const double f = std::min(1.0, i / 400.0);
    run.step(task_test_sample(kTaskTestRightD - Eigen::Vector3d(0, 0, 0.12 * f),
                              kTaskTestLeftD - Eigen::Vector3d(0, 0, 0.165 * f), true));
  }
  ASSERT_TRUE(task_test_start_counting());
  std::vector<std::int64_t> ns(2000);
  std::vector<double> cpu(2000);  // the thread's own CPU time: the loaded machine's preemption left out
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int i = 0; i < 2000; ++i) {
    // Slide both grippers along the bench (y), 2 cm and back.
    const double y = 0.02 * std::sin(2.0 * std::numbers::pi * i / 2000.0);
    const hd::DeviceSample s = task_test_sample(kTaskTestRightD + Eigen::Vector3d(0, y, -0.12),
                                                kTaskTestLeftD + Eigen::Vector3d(0, y, -0.165), true);
    const std::int64_t t0 = hemm::steady_now_ns();
    const double c0 = hemm::thread_cpu_s();
    hemm::servo::prepare_tick_output(s, ++run.tick, run.out);
    run.out.deadline_ns = t0 + 1'000'000;
    run.task.tick(s, run.empty, run.out);
    ns[static_cast<std::size_t>(i)] = hemm::steady_now_ns() - t0;
    cpu[static_cast<std::size_t>(i)] = hemm::thread_cpu_s() - c0;
  }
  const std::uint64_t after = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_GT(run.task.render_stats(0).contact_ticks, 2000u);
  EXPECT_GT(run.task.render_stats(1).contact_ticks, 2000u);
  // The trace's newest sample is the last tick's: its felt force, as in A, the force sent.
  const tele::HandTraceSample* t = run.task.trace().take();
  ASSERT_NE(t, nullptr);
  const tele::ArmMappingParams& m0 = p.mapping[0];
  EXPECT_LT((t->arm[0].felt_A - m0.R_A_D * run.out.command.ee[0].force_H / m0.translation_scale).norm(), 1e-12);
  EXPECT_GT(t->arm[0].felt_A.norm(), 0.1);
  std::sort(ns.begin(), ns.end());
  std::sort(cpu.begin(), cpu.end());
  std::printf("tick compute, both hands in contact (beside other builds): wall median %.1f us, p99 %.1f us, max %.1f us; "
              "thread CPU median %.1f us, p99 %.1f us, max %.1f us\n",
              ns[1000] * 1e-3, ns[1980] * 1e-3, ns.back() * 1e-3, cpu[1000] * 1e6, cpu[1980] * 1e6, cpu.back() * 1e6);
}

// The direct mode (issue 25 part 5): each hand's twist in A goes into the
// setpoint with its port, the robot's wrench comes back on the hand through
// the passivity controller, the robot's newest energy taken each tick; no
// heap allocation in 2000 ticks with both hands moving against a remote
// wrench.
TEST(TelemanipTask, DirectModeTickSendsTheTwistAndAllocatesNothing) {
  TaskTestRun run(task_test_direct_params());
  tele::RemoteArmsState rs = task_test_remote(kTaskTestRightA, kTaskTestLeftA);
  rs.frame_epoch = 4;
  for (tele::RemoteArm& a : rs.arm) {
    a.direct.has_port = true;
    a.direct.has_wrench = true;
    a.direct.wrench_A << 0.0, 0.0, 5.0, 0.0, 0.0, 0.0;  // the bench pushing up on the gripper
  }
  std::uint64_t seq = 0;
  const auto publish = [&](double energy) {
    rs.seq = ++seq;
    for (tele::RemoteArm& a : rs.arm) {
      a.direct.seq = rs.seq;
      a.direct.energy_in_J.setConstant(energy);
    }
    run.task.remote().publish(rs);
  };
  auto sample = [](double vz, bool deadman) {
    hd::DeviceSample s = task_test_sample(kTaskTestRightD, kTaskTestLeftD, deadman);
    for (int k = 0; k < 2; ++k) s.ee[static_cast<std::size_t>(k)].velocity_H = Eigen::Vector3d(0.02, 0.0, vz);
    return s;
  };
  publish(0.0);
  for (int i = 0; i < 400; ++i) run.step(sample(0.0, true));  // pressed; the fade comes in
  const tele::TelemanipSetpoint* sp = run.task.setpoints().take();
  ASSERT_NE(sp, nullptr);
  for (int k = 0; k < 2; ++k) {
    EXPECT_TRUE(sp->arm[static_cast<std::size_t>(k)].direct);
    // D's x is A's -x: the hand's 2 cm/s along D x is -2 cm/s in A.
    EXPECT_NEAR(sp->arm[static_cast<std::size_t>(k)].twist_A.v.x(), -0.02, 1e-12);
  }
  // Moving down into the remote's 5 N: the hand does the work, nothing cut,
  // the whole 5 N shown (on D's z, shared with A).
  for (int i = 0; i < 200; ++i) {
    publish(0.0);
    run.step(sample(-0.05, true));
  }
  EXPECT_NEAR(run.out.command.ee[0].force_H.z(), 5.0, 1e-9);
  EXPECT_GT(run.task.direct_hand(0).side.in_J[2], 0.0);
  // Moving up, pushed by it: only what the robot's budget allows (none here).
  for (int i = 0; i < 50; ++i) {
    publish(0.0);
    run.step(sample(0.05, true));
  }
  EXPECT_NEAR(run.out.command.ee[0].force_H.z(), 0.0, 1e-12);
  EXPECT_GT(run.task.direct_hand(0).side.dissipated_J.sum(), 0.0);
  ASSERT_TRUE(task_test_start_counting());
  const std::uint64_t before = hemm::test::counted_allocations();
  for (int i = 0; i < 2000; ++i) {
    publish(1e-3 * i);
    const double vz = 0.05 * std::sin(2.0 * std::numbers::pi * i / 500.0);
    run.step(sample(vz, i < 1500));  // released for the last 500: the fade out
  }
  const std::uint64_t after = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_GE(run.task.direct_hand(0).stats.peer_accepted, 2200u);
  // Released 0.5 s (the 0.2 s fade long done): nothing shown, zero twist.
  EXPECT_DOUBLE_EQ(run.out.command.ee[0].force_H.norm(), 0.0);
  EXPECT_DOUBLE_EQ(run.task.direct_hand(0).sent_A.v.norm(), 0.0);
  // The robot's energy is never less than the hand's output.
  for (int k = 0; k < 2; ++k) {
    const auto& side = run.task.direct_hand(k).side;
    EXPECT_TRUE(((side.peer_in_J - side.out_J).array() >= -1e-12).all());
  }
}

// A direct-mode session recorded as hemm-operator --record does (the task's
// tick tap, each ArmsState with its datagram sequence), replayed on a fresh
// task by replay_telemanip: every tick's wrench equal, the operator end's
// passivity controller acting in it. The same recording with one state's
// wrench changed differs from that state on; a tick whose state is missing
// stops the replay there and says why.
TEST(TelemanipReplay, DirectSessionReplaysTickForTick) {
  const tele::TelemanipTaskParams p = task_test_direct_params();
  hemm::op::Recording rec;
  rec.header.set_end_effectors(2);
  rec.header.set_servo_period_ns(1'000'000);
  rec.header.set_telemanip_mode("direct");
  const auto no_send = [](const hemm::wire::StreamMessage&) { return true; };
  const auto clock0 = [] { return std::int64_t{0}; };
  constexpr int kTicks = 3000;
  double peak_shown = 0.0;
  {
    TaskTestRun live(p);
    hemm::op::ServoTickTap tap(8);
    live.task.set_tick_tap(&tap);
    asio::io_context io;
    tele::TelemanipLink link(io, live.task.setpoints(), live.task.remote(), no_send, clock0, tele::TelemanipLinkParams{});
    std::uint64_t seq = 0;
    for (int i = 0; i < kTicks; ++i) {
      const std::int64_t t = 1'000'000LL * i;
      if (i % 4 == 0) {  // a state every 4 ms, its remote pushing 2-8 N up, its budget growing
        hemm::wire::StreamMessage m;
        hemm::wire::ArmsState& s = *m.mutable_arms_state();
        s = hemm::test::telemanip_test_state(0.65);
        for (std::uint32_t k = 0; k < 2; ++k) {
          hemm::wire::PassivityPort* port = s.add_passivity();
          port->set_index(k);
          for (int a = 0; a < 6; ++a) port->add_energy_in_j(2e-4 * i);
          hemm::wire::DirectWrench* w = s.add_direct_wrench();
          w->set_index(k);
          for (int a = 0; a < 6; ++a) w->add_wrench_a(a == 2 ? static_cast<float>(5.0 + 3.0 * std::sin(i / 200.0)) : 0.0f);
        }
        link.on_arms_state(++seq, t, s);
        hemm::rec::StreamEvent& e = rec.streams.emplace_back();
        e.set_t_ns(t);
        e.set_seq(seq);
        *e.mutable_message() = m;
      }
      hd::DeviceSample s = task_test_sample(kTaskTestRightD, kTaskTestLeftD, i < 2500);
      for (int k = 0; k < 2; ++k)
        s.ee[static_cast<std::size_t>(k)].velocity_H = Eigen::Vector3d(0.01, 0.0, 0.06 * std::sin(i / 150.0 + k));
      s.t_ns = t;
      live.step(s);
      peak_shown = std::max(peak_shown, live.out.command.ee[0].force_H.norm());
      hemm::op::ServoTickRecord r;
      ASSERT_TRUE(tap.ring.try_pop(r));
      hemm::op::to_proto(r, &rec.ticks.emplace_back());
    }
    EXPECT_GT(live.task.direct_hand(0).side.dissipated_J.sum(), 0.0);  // the controller acted
  }
  EXPECT_GT(peak_shown, 2.0);
  const auto replay = [&](const hemm::op::Recording& r) {
    tele::TelemanipTask task(p);
    asio::io_context io;
    tele::TelemanipLink link(io, task.setpoints(), task.remote(), no_send, clock0, tele::TelemanipLinkParams{});
    return tele::replay_telemanip(r, task, link);
  };
  const hemm::op::SessionReplayResult same = replay(rec);
  EXPECT_EQ(same.stopped, "");
  EXPECT_EQ(same.ticks, static_cast<std::uint64_t>(kTicks));
  EXPECT_EQ(same.remote_states, static_cast<std::uint64_t>(kTicks / 4));
  EXPECT_EQ(same.ticks_not_compared, 0u);
  EXPECT_EQ(same.force_mismatches, 0u) << "largest " << same.max_force_error_N << " N at tick " << same.max_error_tick;
  EXPECT_EQ(same.mode_mismatches, 0u);

  hemm::op::Recording bent = rec;
  bent.streams[400].mutable_message()->mutable_arms_state()->mutable_direct_wrench(0)->set_wrench_a(2, 20.0f);
  const hemm::op::SessionReplayResult differs = replay(bent);
  EXPECT_GT(differs.force_mismatches, 0u);
  EXPECT_GE(differs.max_error_tick, 1600u);  // not before the state changed (tick 1600)

  hemm::op::Recording cut = rec;
  cut.streams.erase(cut.streams.begin() + 600);
  const hemm::op::SessionReplayResult stops = replay(cut);
  EXPECT_NE(stops.stopped.find("which the recording does not have"), std::string::npos) << stops.stopped;
  EXPECT_LT(stops.ticks, static_cast<std::uint64_t>(kTicks));
}
