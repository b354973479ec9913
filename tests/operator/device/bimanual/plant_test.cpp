// The SIMULATED bimanual plant: it holds still under exact gravity
// compensation, the wrist sensor reads the hand's push plus the handle's
// weight (against the force the plant applied), brakes stop the arm, and a
// step allocates nothing.
#include "operator/device/bimanual/plant.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "common/kinematics/arm7.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

namespace {

hb::PlantConfig ideal_config() {
  hb::PlantConfig c;
  c.actuators = hb::ideal_actuators(c.rig.arm);
  c.model_error = hb::ModelError{0, 0, 0, 1};
  return c;
}

// Torques from the plant's TRUE model: exact gravity compensation plus a
// joint PD to a posture with natural frequency w (rad/s) per joint, scaled
// by the mass matrix's diagonal (the wrist's inertia is tiny).
std::array<hb::ArmActuation, hb::kArms> hold(const hb::BimanualPlant& p, const std::array<hk::Arm7Vector, 2>& q0,
                                             double w) {
  std::array<hb::ArmActuation, hb::kArms> out;
  for (hb::ArmSide s : {hb::ArmSide::kRight, hb::ArmSide::kLeft}) {
    const auto a = static_cast<size_t>(hb::index(s));
    const hk::Arm7Model m = hk::with_payload(p.true_arm(s), p.true_handle(s).inertia_J7);
    const hb::ArmReading& r = p.reading(s);
    hk::Arm7Frames f;
    hk::forward_kinematics(m, r.q, f);
    const hk::Arm7Vector Mii = hk::mass_matrix(m, f).diagonal();
    out[a].tau = hk::gravity_torque(m, f, p.config().rig.gravity_A(s)) +
                 (w * w * Mii).cwiseProduct(q0[a] - r.q) - (1.4 * w * Mii).cwiseProduct(r.qd);
  }
  return out;
}

std::array<hb::HumanTarget, 2> stay(const hb::BimanualPlant& p) {
  std::array<hb::HumanTarget, 2> h;
  for (int a = 0; a < 2; ++a) {
    h[static_cast<size_t>(a)].position_D = p.truth().hands[static_cast<size_t>(a)].position_D;
    h[static_cast<size_t>(a)].orientation_D = p.truth().hands[static_cast<size_t>(a)].orientation_D;
  }
  return h;
}

}  // namespace

TEST(BimanualPlant, HoldsStillUnderExactGravityCompensation) {
  hb::BimanualPlant p(ideal_config());
  const auto human = stay(p);
  const std::array<hk::Arm7Vector, 2> q0{p.reading(hb::ArmSide::kRight).q, p.reading(hb::ArmSide::kLeft).q};
  for (int k = 0; k < 1000; ++k) p.step(hold(p, q0, 0.0), human);
  for (hb::ArmSide s : {hb::ArmSide::kRight, hb::ArmSide::kLeft}) {
    const auto a = static_cast<size_t>(hb::index(s));
    const double dq = (p.reading(s).q - q0[a]).cwiseAbs().maxCoeff();
    std::printf("%s arm after 1 s of pure gravity compensation: |dq|max %.2e rad, |qd|max %.2e rad/s\n",
                hb::to_string(s), dq, p.reading(s).qd.cwiseAbs().maxCoeff());
    EXPECT_LT(dq, 2e-3);
    EXPECT_TRUE(p.reading(s).powered);
    EXPECT_FALSE(p.reading(s).brakes_engaged);
  }
  EXPECT_NEAR(p.time_s(), 1.0, 1e-9);
  EXPECT_EQ(p.truth().arm_arm_contact_steps, 0u);
  EXPECT_EQ(p.truth().arm_table_contact_steps, 0u);
}

TEST(BimanualPlant, WristSensorReadsTheHandsPushPlusTheHandleWeight) {
  hb::BimanualPlant p(ideal_config());
  auto human = stay(p);
  human[0].push_force_D = Eigen::Vector3d(8.0, -3.0, 5.0);
  human[1].push_torque_D = Eigen::Vector3d(0.0, 0.4, 0.0);
  const std::array<hk::Arm7Vector, 2> q0{p.reading(hb::ArmSide::kRight).q, p.reading(hb::ArmSide::kLeft).q};
  for (int k = 0; k < 2000; ++k) p.step(hold(p, q0, 30.0), human);
  for (hb::ArmSide s : {hb::ArmSide::kRight, hb::ArmSide::kLeft}) {
    const auto a = static_cast<size_t>(hb::index(s));
    const hb::ArmReading& r = p.reading(s);
    const hb::HandTruth& h = p.truth().hands[a];
    hk::Arm7Frames f;
    hk::forward_kinematics(p.true_arm(s), r.q, f);
    const Eigen::Isometry3d T_D_J7 = p.config().rig.T_D_A[a] * f.joint(7);
    const Eigen::Vector3d F_D = T_D_J7.linear() * r.ft_J7.head<3>();
    const Eigen::Vector3d T_D = T_D_J7.linear() * r.ft_J7.tail<3>();
    // At rest the handle passes on what the hand applies (minus the grasp
    // force the plant put on the hand) plus its own weight.
    const hb::HandleSpec& hs = p.true_handle(s);
    const Eigen::Vector3d weight = hs.inertia_J7.mass * p.config().rig.gravity_D;
    const Eigen::Vector3d expect_F = -h.grasp_force_D + weight;
    const Eigen::Vector3d p_E = T_D_J7 * hs.T_J7_E.translation();
    const Eigen::Vector3d c = T_D_J7 * hs.inertia_J7.com;
    const Eigen::Vector3d expect_T =
        -h.grasp_torque_D + (p_E - T_D_J7.translation()).cross(-h.grasp_force_D) + (c - T_D_J7.translation()).cross(weight);
    std::printf("%s wrist F/T in D: F (%.3f %.3f %.3f) expected (%.3f %.3f %.3f); T (%.4f %.4f %.4f) expected (%.4f %.4f %.4f)\n",
                hb::to_string(s), F_D.x(), F_D.y(), F_D.z(), expect_F.x(), expect_F.y(), expect_F.z(), T_D.x(), T_D.y(),
                T_D.z(), expect_T.x(), expect_T.y(), expect_T.z());
    EXPECT_LT((F_D - expect_F).norm(), 0.02);
    EXPECT_LT((T_D - expect_T).norm(), 0.002);
  }
  // The right hand is at rest: the grasp balances the push and the human
  // arm's spring (it carries its own weight).
  const hb::HandTruth& h = p.truth().hands[0];
  const double k = p.config().humans[0].arm_stiffness;
  EXPECT_LT((h.grasp_force_D + k * (human[0].position_D - h.position_D) + human[0].push_force_D).norm(), 0.01);
  EXPECT_GT(h.grasp_force_D.norm(), 5.0);
}

TEST(BimanualPlant, PowerOffEngagesTheBrakesAndTheArmStops) {
  hb::PlantConfig c;  // LWR-like actuators, model error
  hb::BimanualPlant p(c);
  auto human = stay(p);
  human[0].push_force_D = Eigen::Vector3d(0.0, -30.0, 0.0);
  const std::array<hk::Arm7Vector, 2> q0{p.reading(hb::ArmSide::kRight).q, p.reading(hb::ArmSide::kLeft).q};
  // Gravity compensation only: the push moves the right arm.
  for (int k = 0; k < 200; ++k) p.step(hold(p, q0, 0.0), human);
  const double speed0 = p.reading(hb::ArmSide::kRight).qd.norm();
  ASSERT_GT(speed0, 0.05);
  auto act = hold(p, q0, 0.0);
  act[0].power = false;
  int stopped_at = -1, braked_at = -1;
  for (int k = 0; k < 500; ++k) {
    p.step(act, human);
    const hb::ArmReading& r = p.reading(hb::ArmSide::kRight);
    EXPECT_FALSE(r.powered);
    if (braked_at < 0 && r.brakes_engaged) braked_at = k + 1;
    if (stopped_at < 0 && r.brakes_engaged && r.qd.norm() < 1e-3) stopped_at = k + 1;
  }
  std::printf("power off at %.2f rad/s: brakes at %d ms, stopped (|qd| < 1e-3) at %d ms; still at 0.5 s: |qd| %.1e\n",
              speed0, braked_at, stopped_at, p.reading(hb::ArmSide::kRight).qd.norm());
  // Engaged 15 ms after the power went off (at the start of step 1).
  EXPECT_EQ(braked_at, 16);
  ASSERT_GT(stopped_at, 0);
  EXPECT_LT(stopped_at, 100);
  EXPECT_LT(p.reading(hb::ArmSide::kRight).qd.norm(), 1e-3);
  // The left arm was never switched off.
  EXPECT_TRUE(p.reading(hb::ArmSide::kLeft).powered);
}

TEST(BimanualPlant, StepAllocatesNothing) {
  hb::BimanualPlant p(hb::PlantConfig{});
  const auto human = stay(p);
  const std::array<hk::Arm7Vector, 2> q0{p.reading(hb::ArmSide::kRight).q, p.reading(hb::ArmSide::kLeft).q};
  const auto act = hold(p, q0, 30.0);
  p.step(act, human);
  const auto before = hemm::test::counted_allocations();
  hemm::test::count_allocations_on_this_thread(true);
  for (int k = 0; k < 200; ++k) p.step(act, human);
  hemm::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(hemm::test::counted_allocations() - before, 0u);
}

TEST(BimanualPlant, RejectsBadConfigs) {
  auto bad = [](auto mutate) {
    hb::PlantConfig c;
    mutate(c);
    try {
      hb::BimanualPlant p(c);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(bad([](hb::PlantConfig& c) { c.substeps = 0; }), "");
  EXPECT_NE(bad([](hb::PlantConfig& c) { c.humans[1].hand_mass = -1; }), "");
  EXPECT_NE(bad([](hb::PlantConfig& c) { c.actuators.coulomb_friction(2) = NAN; }), "");
  EXPECT_NE(bad([](hb::PlantConfig& c) { c.rig.link_radius(0) = 0; }), "");
  EXPECT_NE(bad([](hb::PlantConfig& c) { c.model_error.mass = 0.9; }), "");
  EXPECT_EQ(bad([](hb::PlantConfig&) {}), "");
}
