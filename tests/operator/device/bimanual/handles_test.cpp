// The three handles on the SIMULATED device: the magnetic clutch comes off
// above its attaching force (not below), its dead-man opens, the brakes
// engage and the arm stops (time and travel measured); releasing the
// joystick handle's dead-man does the same and pressing it again resumes;
// the grip lever reads the forefinger and renders force against it; inputs a
// handle does not have are not reported and asking for them is an error.
#include "operator/device/bimanual/handles.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "operator/device/bimanual/simulation.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;
using Eigen::Vector3d;

TEST(Handles, InputsPerHandleAndClearErrors) {
  using K = hb::HandleKind;
  using I = hb::HandleInput;
  EXPECT_TRUE(hb::has_input(K::kMagneticClutch, I::kClutch));
  EXPECT_TRUE(hb::has_input(K::kMagneticClutch, I::kDeadman));
  EXPECT_FALSE(hb::has_input(K::kMagneticClutch, I::kGrip));
  EXPECT_TRUE(hb::has_input(K::kGripForce, I::kGrip));
  EXPECT_FALSE(hb::has_input(K::kGripForce, I::kDeadman));
  for (I i : {I::kJoystickAxes, I::kSwitch, I::kButtons, I::kDeadman}) EXPECT_TRUE(hb::has_input(K::kJoystick, i));
  EXPECT_FALSE(hb::has_input(K::kJoystick, I::kClutch));
  EXPECT_EQ(hb::require_input(K::kJoystick, I::kGrip).value_or(""), "the joystick handle has no grip");
  EXPECT_FALSE(hb::require_input(K::kGripForce, I::kGrip));
  EXPECT_EQ(hb::handle_from_string("grip_force"), K::kGripForce);
  EXPECT_FALSE(hb::handle_from_string("gripforce"));
  for (K k : {K::kMagneticClutch, K::kGripForce, K::kJoystick}) {
    EXPECT_FALSE(hb::validate(hb::handle_spec(k))) << hb::to_string(k);
    EXPECT_EQ(hb::handle_from_string(hb::to_string(k)), k);
  }
  hb::HandleSpec bad = hb::handle_spec(K::kMagneticClutch);
  bad.clutch_force_limit = 0;
  EXPECT_TRUE(hb::validate(bad));
}

namespace {

struct Stop {
  double t_event = -1;       // s since the run started
  double t_brakes = -1;      // brakes engaged, s after the event
  double t_stopped = -1;     // every joint below 1e-3 rad/s, s after the event
  double travel_m = 0;       // end-effector travel from the event to the end
  double joint_travel = 0;   // largest joint travel [rad]
  int joint = 0;             // of joint (1..7)
};

// Steps until `done` and 0.3 s beyond; the event is the first tick the arm
// runs unpowered.
template <class Human>
Stop run_until_stopped(hb::BimanualSimulation& s, Human human, double t_max) {
  Stop r;
  Eigen::Vector3d p_event = Eigen::Vector3d::Zero();
  hk::Arm7Vector q_event = hk::Arm7Vector::Zero();
  while (s.time_s() < t_max) {
    s.step(human(s.time_s() + 0.001));
    const hb::ArmReading& rd = s.reading(hb::ArmSide::kRight);
    const double t = s.time_s();
    if (r.t_event < 0 && !rd.powered) {
      r.t_event = t;
      p_event = s.output(hb::ArmSide::kRight).T_D_E.translation();
      q_event = rd.q;
    }
    if (r.t_event < 0) continue;
    if (r.t_brakes < 0 && rd.brakes_engaged) r.t_brakes = t - r.t_event;
    if (r.t_stopped < 0 && rd.brakes_engaged && rd.qd.cwiseAbs().maxCoeff() < 1e-3) r.t_stopped = t - r.t_event;
    hk::Arm7Frames f;
    hk::forward_kinematics(s.controller().nominal(hb::ArmSide::kRight), rd.q, f);
    const Vector3d p = s.config().plant.rig.T_D_A[0] * (f.joint(7) * s.controller().handle(hb::ArmSide::kRight).T_J7_E).translation();
    r.travel_m = std::max(r.travel_m, (p - p_event).norm());
    int j = 0;
    const double jt = (rd.q - q_event).cwiseAbs().maxCoeff(&j);
    if (jt > r.joint_travel) {
      r.joint_travel = jt;
      r.joint = j + 1;
    }
    if (r.t_stopped >= 0 && t - r.t_event > r.t_stopped + 0.3) break;
  }
  return r;
}

}  // namespace

TEST(Handles, MagneticClutchComesOffAboveItsLimitAndTheArmStops) {
  hb::SimulationConfig c;  // LWR-like actuators, model error; clutches on both arms
  const double limit = hb::handle_spec(hb::HandleKind::kMagneticClutch).clutch_force_limit;
  // A steady pull of 45 N (below the limit) does not detach.
  {
    hb::BimanualSimulation s(c);
    auto h = s.resting_targets();
    h[0].push_force_D = Vector3d(-45.0, 0.0, 0.0);  // towards the operator
    for (int k = 0; k < 1500; ++k) s.step(h);
    EXPECT_TRUE(s.reading(hb::ArmSide::kRight).attached);
    EXPECT_TRUE(s.reading(hb::ArmSide::kRight).powered);
  }
  // A pull growing at 200 N/s does, once the grasp carries more than the limit.
  hb::BimanualSimulation s(c);
  const auto h0 = s.resting_targets();
  double pull_at_detach = 0.0;
  auto human = [&](double t) {
    auto h = h0;
    h[0].push_force_D = Vector3d(-200.0 * t, 0.0, 0.0);
    if (s.reading(hb::ArmSide::kRight).attached) pull_at_detach = s.truth().hands[0].grasp_force_D.norm();
    return h;
  };
  const Stop r = run_until_stopped(s, human, 3.0);
  std::printf("magnetic clutch (limit %.0f N): came off at t = %.3f s with %.1f N in the grasp; brakes after %.0f ms; "
              "arm stopped %.0f ms after the clutch came off, end-effector travel %.1f mm, largest joint travel %.3f rad "
              "(joint %d)\n",
              limit, r.t_event, pull_at_detach, 1e3 * r.t_brakes, 1e3 * r.t_stopped, 1e3 * r.travel_m, r.joint_travel,
              r.joint);
  ASSERT_GT(r.t_event, 0.0);
  EXPECT_FALSE(s.reading(hb::ArmSide::kRight).attached);
  EXPECT_FALSE(s.reading(hb::ArmSide::kRight).deadman_closed);
  EXPECT_TRUE(s.reading(hb::ArmSide::kRight).brakes_engaged);
  EXPECT_GT(pull_at_detach, limit - 10.0);  // it held until near its limit
  EXPECT_NEAR(r.t_brakes, c.plant.actuators.brake_delay_s, 0.0011);
  ASSERT_GT(r.t_stopped, 0.0);
  EXPECT_LT(r.t_stopped, 0.060);   // measured ~20 ms: bound with margin
  EXPECT_LT(r.travel_m, 0.010);    // measured ~1 mm
  // The other arm keeps running.
  EXPECT_TRUE(s.reading(hb::ArmSide::kLeft).powered);
}

TEST(Handles, JoystickDeadmanReleaseBrakesAndPressingResumes) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kJoystick, hb::HandleKind::kJoystick};
  hb::BimanualSimulation s(c);
  const auto h0 = s.resting_targets();
  // The hand moves sideways at 0.3 m/s and lets go of the dead-man at 0.5 s.
  auto human = [&](double t) {
    auto h = h0;
    h[0].position_D += Vector3d(0.0, 0.3 * std::min(t, 0.8), 0.0);
    h[0].deadman = t < 0.5;
    return h;
  };
  const Stop r = run_until_stopped(s, human, 2.0);
  std::printf("joystick dead-man released at t = %.3f s: brakes after %.0f ms; arm stopped %.0f ms after release, "
              "end-effector travel %.1f mm, largest joint travel %.3f rad (joint %d)\n",
              r.t_event, 1e3 * r.t_brakes, 1e3 * r.t_stopped, 1e3 * r.travel_m, r.joint_travel, r.joint);
  EXPECT_NEAR(r.t_event, 0.5, 0.0011);
  EXPECT_NEAR(r.t_brakes, c.plant.actuators.brake_delay_s, 0.0011);
  ASSERT_GT(r.t_stopped, 0.0);
  EXPECT_LT(r.t_stopped, 0.060);
  EXPECT_LT(r.travel_m, 0.010);
  EXPECT_FALSE(s.reading(hb::ArmSide::kRight).deadman_closed);
  // Pressing it again: power back, brakes off, the arm follows the hand.
  const Vector3d p_stop = s.output(hb::ArmSide::kRight).T_D_E.translation();
  for (int k = 0; k < 1000; ++k) {
    auto h = h0;
    h[0].position_D += Vector3d(0.0, 0.3 * 0.8, 0.0);
    s.step(h);
  }
  EXPECT_TRUE(s.reading(hb::ArmSide::kRight).powered);
  EXPECT_FALSE(s.reading(hb::ArmSide::kRight).brakes_engaged);
  EXPECT_GT((s.output(hb::ArmSide::kRight).T_D_E.translation() - p_stop).norm(), 0.02);
}

TEST(Handles, GripLeverReadsTheFingerAndPushesBack) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kGripForce, hb::HandleKind::kJoystick};
  hb::BimanualSimulation s(c);
  auto h = s.resting_targets();
  h[0].finger_position = 0.015;
  for (int k = 0; k < 500; ++k) s.step(h);
  const double x_free = s.reading(hb::ArmSide::kRight).grip_position;
  EXPECT_NEAR(x_free, 0.015, 5e-4);
  // 4 N against the finger (stiffness 400 N/m): 1 cm back.
  for (int k = 0; k < 500; ++k) s.step({hk::Wrench6::Zero(), hk::Wrench6::Zero()}, {4.0, 0.0}, h);
  const double k_f = c.plant.humans[0].finger_stiffness;
  EXPECT_NEAR(s.reading(hb::ArmSide::kRight).grip_position, 0.015 - 4.0 / k_f, 5e-4);
  // Beyond the handle's maximum force the lever is pushed open (clamped to 10 N: 2.5 cm > the 1.5 cm target).
  for (int k = 0; k < 500; ++k) s.step({hk::Wrench6::Zero(), hk::Wrench6::Zero()}, {50.0, 0.0}, h);
  EXPECT_NEAR(s.reading(hb::ArmSide::kRight).grip_position, 0.0, 1e-3);  // at the open stop
  // The joystick handle on the left has no lever.
  EXPECT_EQ(s.reading(hb::ArmSide::kLeft).grip_position, 0.0);
}

TEST(Handles, JoystickInputsPassThroughAndOtherHandlesReportNone) {
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kJoystick, hb::HandleKind::kMagneticClutch};
  hb::BimanualSimulation s(c);
  auto h = s.resting_targets();
  for (auto& t : h) {
    t.buttons = 0b101;
    t.joystick = Eigen::Vector2d(0.4, -2.0);
    t.switch_on = true;
  }
  s.step(h);
  const hb::ArmReading& j = s.reading(hb::ArmSide::kRight);
  EXPECT_EQ(j.buttons, 0b101u);
  EXPECT_EQ(j.joystick, Eigen::Vector2d(0.4, -1.0));  // axes clamped to [-1, 1]
  EXPECT_TRUE(j.switch_on);
  const hb::ArmReading& m = s.reading(hb::ArmSide::kLeft);
  EXPECT_EQ(m.buttons, 0u);
  EXPECT_TRUE(m.joystick.isZero(0.0));
  EXPECT_FALSE(m.switch_on);
}
