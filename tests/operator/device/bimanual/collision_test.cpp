// Collision avoidance: closest points against brute-force sampling, the
// controller's arm-arm distance against MuJoCo's own collision detection on
// the same postures, and (closed loop, SIMULATED) scripted hands that drive
// the arms into each other and into the table: the gap stays above the
// margin and MuJoCo reports no arm-arm or arm-table contact.
#include "operator/device/bimanual/collision.h"

#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "operator/device/bimanual/simulation.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;
using Eigen::Vector3d;

namespace {

Vector3d rand_vec(std::mt19937_64& rng, double s) {
  std::uniform_real_distribution<double> u(-s, s);
  return {u(rng), u(rng), u(rng)};
}

}  // namespace

TEST(Collision, SegmentSegmentIsTheSampledMinimum) {
  std::mt19937_64 rng(31);
  for (int k = 0; k < 300; ++k) {
    const Vector3d a0 = rand_vec(rng, 1), a1 = k % 10 == 0 ? a0 : rand_vec(rng, 1);  // some degenerate
    Vector3d b0 = rand_vec(rng, 1), b1 = rand_vec(rng, 1);
    if (k % 7 == 0) b1 = b0 + 0.5 * (a1 - a0);  // parallel
    const hb::ClosestPoints c = hb::segment_segment(a0, a1, b0, b1);
    double best = 1e9;
    for (int i = 0; i <= 200; ++i)
      for (int j = 0; j <= 200; ++j)
        best = std::min(best, ((a0 + (a1 - a0) * (i / 200.0)) - (b0 + (b1 - b0) * (j / 200.0))).norm());
    ASSERT_LE(c.distance, best + 1e-12);
    ASSERT_GT(c.distance, best - 0.02);  // the grid's resolution
    ASSERT_NEAR((c.p - c.q).norm(), c.distance, 1e-12);
  }
}

TEST(Collision, SegmentBoxIsTheSampledMinimum) {
  std::mt19937_64 rng(32);
  hb::Box box;
  box.min_D << -0.3, -0.2, -0.1;
  box.max_D << 0.2, 0.4, 0.05;
  for (int k = 0; k < 300; ++k) {
    const Vector3d a0 = rand_vec(rng, 1), a1 = rand_vec(rng, 1);
    const hb::ClosestPoints c = hb::segment_box(a0, a1, box);
    double best = 1e9;
    for (int i = 0; i <= 2000; ++i) {
      const Vector3d p = a0 + (a1 - a0) * (i / 2000.0);
      best = std::min(best, (p - p.cwiseMax(box.min_D).cwiseMin(box.max_D)).norm());
    }
    ASSERT_NEAR(c.distance, best, 1e-3) << k;
    ASSERT_TRUE((c.q.array() >= box.min_D.array() - 1e-12).all() && (c.q.array() <= box.max_D.array() + 1e-12).all());
  }
}

TEST(Collision, ControllerDistancesMatchMujocoOnThePlant) {
  // Random postures near the arms' meeting zone: the controller's capsule
  // gap against MuJoCo's reported distance (same capsules, its own code).
  hb::SimulationConfig c;
  c.plant.actuators = hb::ideal_actuators(c.plant.rig.arm);
  hb::BimanualSimulation s(c);
  std::mt19937_64 rng(33);
  std::normal_distribution<double> n(0.0, 0.35);
  int compared = 0;
  for (int k = 0; k < 200 && compared < 40; ++k) {
    hk::Arm7Vector qr = c.plant.rig.home(hb::ArmSide::kRight), ql = c.plant.rig.home(hb::ArmSide::kLeft);
    for (int i = 0; i < 7; ++i) {
      qr(i) += n(rng);
      ql(i) += n(rng);
    }
    qr = hk::clamp_to_limits(c.plant.rig.arm, qr);
    ql = hk::clamp_to_limits(c.plant.rig.arm, ql);
    s.plant().reset({qr, ql});
    // One step with the arms braked-free but at rest, so MuJoCo's collision pass runs.
    std::array<hb::ArmActuation, 2> act;
    act[0].power = act[1].power = false;
    s.plant().step(act, s.resting_targets());
    std::array<hk::Arm7Frames, 2> f;
    std::array<hb::ArmCapsules, 2> caps;
    for (int a = 0; a < 2; ++a) {
      const auto side = static_cast<hb::ArmSide>(a);
      hk::forward_kinematics(c.plant.rig.arm, s.reading(side).q, f[static_cast<size_t>(a)]);
      caps[static_cast<size_t>(a)] = hb::arm_capsules(c.plant.rig, side, s.controller().handle(side), f[static_cast<size_t>(a)]);
    }
    hb::CollisionResult r;
    hb::collision_avoidance(c.plant.rig, hb::CollisionParams{}, caps, f, {hk::Arm7Vector::Zero(), hk::Arm7Vector::Zero()}, r);
    const double mj = s.truth().min_arm_arm_m;
    if (!std::isfinite(mj) || mj < 0.0) continue;  // beyond MuJoCo's reporting margin, or already penetrating
    ++compared;
    EXPECT_NEAR(r.min_arm_arm_m, mj, 2e-4) << "posture " << k;
  }
  std::printf("compared the arm-arm gap with MuJoCo's at %d postures\n", compared);
  EXPECT_GE(compared, 10);
}

TEST(Collision, ScriptedHandsCannotDriveTheArmsIntoEachOtherOrTheTable) {
  // Joystick handles (no clutch to come off) with the dead-man held; each
  // hand is driven 0.40 m across the midline towards the other, then down
  // 0.35 m into the table, with the human's default arm stiffness (300 N/m):
  // pushes of up to ~100 N.
  hb::SimulationConfig c;
  c.plant.handles = {hb::HandleKind::kJoystick, hb::HandleKind::kJoystick};
  hb::BimanualSimulation s(c);
  const auto h0 = s.resting_targets();
  auto script = [&](int a, double dir) {
    const Vector3d p = h0[static_cast<size_t>(a)].position_D;
    auto key = [&](double t, const Vector3d& d) {
      hb::HumanTarget g = h0[static_cast<size_t>(a)];
      g.position_D = p + d;
      return hb::HumanKey{t, g};
    };
    return hb::HumanKeyScript({key(0.0, Vector3d::Zero()), key(1.5, Vector3d(0, 0.40 * dir, 0)),
                               key(2.0, Vector3d(0, 0.40 * dir, 0)), key(3.5, Vector3d(0, 0.15 * dir, -0.35)),
                               key(4.0, Vector3d(0, 0.15 * dir, -0.35))});
  };
  const hb::HumanKeyScript sr = script(0, +1.0), sl = script(1, -1.0);
  const double margin = 0.03;  // what the test asserts: never closer than 3 cm
  double min_aa = 1e9, min_at = 1e9, max_push = 0.0;
  for (int k = 0; k < 4000; ++k) {
    const double t = s.time_s() + 0.001;
    s.step({sr.at(t), sl.at(t)});
    min_aa = std::min(min_aa, std::min(s.truth().min_arm_arm_m, s.controller().collisions().min_arm_arm_m));
    min_at = std::min(min_at, std::min(s.truth().min_arm_table_m, s.controller().collisions().min_arm_table_m));
    max_push = std::max(max_push, s.truth().hands[0].grasp_force_D.norm());
    ASSERT_TRUE(s.enabled(hb::ArmSide::kRight) && s.enabled(hb::ArmSide::kLeft)) << "t " << t;
  }
  std::printf("hands pushing (grasp force up to %.0f N): min gap arm-arm %.3f m, arm-table/column %.3f m "
              "(activation %.2f m, margin %.2f m); MuJoCo contacts: arm-arm %lu, arm-table %lu substeps\n",
              max_push, min_aa, min_at, hb::CollisionParams{}.activation_m, margin,
              static_cast<unsigned long>(s.truth().arm_arm_contact_steps),
              static_cast<unsigned long>(s.truth().arm_table_contact_steps));
  EXPECT_GT(max_push, 40.0);  // the hands really push
  EXPECT_GT(min_aa, margin);
  EXPECT_GT(min_at, margin);
  EXPECT_LT(min_aa, hb::CollisionParams{}.activation_m);  // the avoidance was engaged
  EXPECT_LT(min_at, hb::CollisionParams{}.activation_m);
  EXPECT_EQ(s.truth().arm_arm_contact_steps, 0u);
  EXPECT_EQ(s.truth().arm_table_contact_steps, 0u);
}
