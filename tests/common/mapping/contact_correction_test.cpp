// The contact correction against planar surfaces of known offset: the
// remote fingertip (a sphere on the gripper) presses on the true plane, the
// voxmap's plane is off by d along its normal; the applied offset converges to
// d (also tilted, also beyond the voxmap's stored distances), the model that
// penetrates where the robot is free moves back, the rendered force never
// changes by more than K slew dt per tick, and wrench noise without contact
// leaves the model exactly alone.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "common/mapping/contact_correction.h"
#include "common/mesh/primitives.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::mapping {
namespace {

constexpr double kFingertipR = 0.015;
constexpr double kFingerLength = 0.10;  // fingertip centre 10 cm along G's -z
constexpr std::int64_t kSampleNs = 4'000'000;  // ArmsState at 250 Hz

// The bench top: a box whose +z face is the surface (voxmap frame V).
const vps::Voxmap& correction_bench() {
  static const vps::Voxmap vm = [] {
    vps::VoxmapParams p;
    p.voxel_size = 0.004;
    vps::Voxmap out;
    EXPECT_FALSE(vps::build_voxmap(mesh::make_box({0.2, 0.2, 0.03}, 4), p, &out, nullptr).has_value());
    return out;
  }();
  return vm;
}

// The gripper: one fingertip sphere, in G.
const vps::PointShell& correction_gripper() {
  static const vps::PointShell ps = [] {
    mesh::TriangleMesh m;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0, 0, -kFingerLength);
    mesh::append_mesh(&m, mesh::make_icosphere(kFingertipR, 4), T);
    vps::PointShellParams p;
    p.voxel_size = 0.002;
    vps::PointShell out;
    EXPECT_FALSE(vps::build_pointshell(m, p, Eigen::Vector3d::Zero(), &out).has_value());
    return out;
  }();
  return ps;
}

Eigen::Matrix3d correction_frame(const Eigen::Vector3d& n) {
  return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), n).toRotationMatrix();
}

// The voxmap pose whose top face (z = 0.03 in V) is the plane through s0 with normal n.
Eigen::Isometry3d correction_plane_pose(const Eigen::Vector3d& s0, const Eigen::Vector3d& n) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = correction_frame(n);
  T.translation() = s0 - 0.03 * n;
  return T;
}

// The remote grasp frame with the fingertip's lowest point at `contact` (G's z along n).
Eigen::Isometry3d correction_grasp(const Eigen::Vector3d& contact, const Eigen::Vector3d& n) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = correction_frame(n);
  T.translation() = contact + (kFingertipR + kFingerLength) * n;
  return T;
}

struct CorrectionRun {
  Eigen::Vector3d applied = Eigen::Vector3d::Zero();
  double max_force_step = 0.0;
  double force_change = 0.0;
};

// Runs `seconds`: a sample every 4 ms (the fingertip at `contact` + lift
// along n, pressing with `press_n` when lift <= 0), the slew every 1 ms, and
// a rendered point contact (stiffness k) at probe_A.
CorrectionRun correction_run(const ContactCorrectionParams& p, const CorrectedVoxmap& model, const Eigen::Vector3d& s0,
                             const Eigen::Vector3d& n, double lift, double press_n, double seconds,
                             ContactCorrection* c, unsigned seed, const Eigen::Vector3d& probe_A, double k) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> nf(0, 0.3), nt(0, 0.01);
  std::uniform_real_distribution<double> slide(-0.03, 0.03);
  const Eigen::Matrix3d F = correction_frame(n);
  CorrectionRun run;
  double force_prev = k * std::max(0.0, -corrected_sdf(model, run.applied, probe_A));
  const double force_start = force_prev;
  const int ticks = static_cast<int>(seconds * 1000);
  Eigen::Vector3d contact = s0;
  for (int i = 0; i < ticks; ++i) {
    if (i % 4 == 0) {
      if (i % 400 == 0) contact = s0 + F * Eigen::Vector3d(slide(rng), slide(rng), 0);  // a new spot on the plane
      ContactSample s;
      s.stamp_ns = static_cast<std::int64_t>(i / 4 + 1) * kSampleNs;
      s.T_A_G = correction_grasp(contact + lift * n, n);
      const Eigen::Vector3d noise_f(nf(rng), nf(rng), nf(rng)), noise_t(nt(rng), nt(rng), nt(rng));
      s.force_A = (lift <= 0 ? press_n : 0.0) * n + noise_f;
      s.torque_A = (contact - s.T_A_G.translation()).cross(s.force_A - noise_f) + noise_t;
      observe_contact(p, model, correction_gripper(), s, c);
    }
    slew_surface_offset(p, c->offset_A, 1e-3, &run.applied);
    const double f = k * std::max(0.0, -corrected_sdf(model, run.applied, probe_A));
    run.max_force_step = std::max(run.max_force_step, std::abs(f - force_prev));
    force_prev = f;
  }
  run.force_change = force_prev - force_start;
  return run;
}

TEST(ContactCorrection, APlaneOffsetInTheModelConvergesToTheTrueOffset) {
  const ContactCorrectionParams p;
  ASSERT_FALSE(validate(p).has_value());
  struct Case {
    const char* name;
    Eigen::Vector3d n;
    double d;  // the model's plane lies d below the true one (along -n)
  };
  const Case cases[] = {
      {"level, model 6 mm low", {0, 0, 1}, 0.006},
      {"level, model 5 mm high", {0, 0, 1}, -0.005},
      {"tilted 25 deg, model 9 mm low", Eigen::Vector3d(std::sin(0.44), 0, std::cos(0.44)), 0.009},
      {"tilted, model 30 mm low (beyond the stored layers)", Eigen::Vector3d(0.2, -0.3, 1).normalized(), 0.030},
  };
  unsigned seed = 1;
  for (const Case& k : cases) {
    const Eigen::Vector3d s0(0.6, 0.1, 0.8);
    CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0 - k.d * k.n, k.n)};
    ContactCorrection c = make_contact_correction(p);
    // Slew 5 mm/s: 30 mm take 6 s.
    const CorrectionRun run =
        correction_run(p, model, s0, k.n, 0.0, 8.0, 2.0 + std::abs(k.d) / p.slew_m_per_s, &c, seed++, s0, 2000);
    const double along = run.applied.dot(k.n);
    const double across = (run.applied - along * k.n).norm();
    std::printf("%s: applied %.3f mm along n (truth %.1f), %.3f mm across; %lu contacts located, %lu skipped\n",
                k.name, 1e3 * along, 1e3 * k.d, 1e3 * across, static_cast<unsigned long>(c.robot_contacts),
                static_cast<unsigned long>(c.skipped));
    EXPECT_NEAR(along, k.d, 0.0008) << k.name;
    EXPECT_LT(across, 0.001) << k.name;
    EXPECT_GT(c.robot_contacts, 100u);
  }
}

TEST(ContactCorrection, AModelThatPenetratesWhereTheRobotIsFreeMovesBack) {
  const ContactCorrectionParams p;
  const Eigen::Vector3d n = Eigen::Vector3d(-0.1, 0.25, 1).normalized();
  const Eigen::Vector3d s0(0.5, -0.2, 0.8);
  // The fingertip hovers 3 mm above the true plane; the model's plane is 12 mm
  // above the truth, so it has the fingertip 9 mm deep.
  CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0 + 0.012 * n, n)};
  ContactCorrection c = make_contact_correction(p);
  const CorrectionRun run = correction_run(p, model, s0, n, 0.003, 0.0, 4.0, &c, 17, s0, 2000);
  // Moved back until the fingertip just touches: -9 mm along n (at least
  // deep_penetration_m is left unresolved by design: the model stops being "deep").
  const double along = run.applied.dot(n);
  std::printf("model 12 mm high, fingertip 3 mm up: applied %.3f mm along n (%lu too-deep observations)\n",
              1e3 * along, static_cast<unsigned long>(c.model_too_deep));
  EXPECT_LT(along, -0.009 + p.deep_penetration_m);
  EXPECT_GT(along, -0.009 - 0.001);
  EXPECT_GT(c.model_too_deep, 0u);
}

TEST(ContactCorrection, TheRenderedForceNeverStepsMoreThanTheSlewLimit) {
  ContactCorrectionParams p;
  for (double slew : {0.005, 0.002}) {
    p.slew_m_per_s = slew;
    const Eigen::Vector3d n(0, 0, 1), s0(0.6, 0.0, 0.8);
    CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0 - 0.008 * n, n)};
    ContactCorrection c = make_contact_correction(p);
    // The operator's probe sits 1 mm below the true surface: in the model it
    // starts 7 mm above the (low) plane, free, and ends 1 mm in.
    const double k = 3000;
    const Eigen::Vector3d probe = s0 + Eigen::Vector3d(0.05, 0.05, -0.001);
    const CorrectionRun run = correction_run(p, model, s0, n, 0.0, 8.0, 4.0 + 0.008 / slew, &c, 23, probe, k);
    const double limit = k * slew * 1e-3;
    std::printf("slew %.1f mm/s: largest rendered force step %.5f N per tick (limit K slew dt = %.5f N), force "
                "changed by %.3f N\n",
                1e3 * slew, run.max_force_step, limit, run.force_change);
    // The field is a plane's: its gradient has unit length up to the
    // interpolant's error.
    EXPECT_LE(run.max_force_step, 1.02 * limit);
    EXPECT_NEAR(run.force_change, k * 0.001, 0.0008 * k);  // the correction did change the force
  }
}

TEST(ContactCorrection, WrenchNoiseWithoutContactLeavesTheModelAlone) {
  const ContactCorrectionParams p;
  const Eigen::Vector3d n(0, 0, 1), s0(0.6, 0.0, 0.8);
  CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0, n)};
  ContactCorrection c = make_contact_correction(p);
  std::mt19937 rng(4);
  std::normal_distribution<double> nf(0, 0.5), nt(0, 0.03);
  std::bernoulli_distribution spike(0.02);
  const Eigen::Vector3d bias(0.4, -0.3, 0.2);
  int outcomes[8] = {};
  for (int i = 1; i <= 2500; ++i) {  // 10 s at 250 Hz, the fingertip 3 cm above the surface
    ContactSample s;
    s.stamp_ns = i * kSampleNs;
    s.T_A_G = correction_grasp(s0 + 0.03 * n + Eigen::Vector3d(0.001 * (i % 50), 0, 0), n);
    s.force_A = bias + Eigen::Vector3d(nf(rng), nf(rng), nf(rng));
    if (spike(rng)) s.force_A += Eigen::Vector3d(0, 6.0, 0);  // a knock: one sample
    s.torque_A = Eigen::Vector3d(nt(rng), nt(rng), nt(rng));
    ++outcomes[static_cast<int>(observe_contact(p, model, correction_gripper(), s, &c))];
  }
  // A steady push whose line of action misses the gripper (cable drag 10 cm off).
  for (int i = 2501; i <= 2600; ++i) {
    ContactSample s;
    s.stamp_ns = i * kSampleNs;
    s.T_A_G = correction_grasp(s0 + 0.03 * n, n);
    s.force_A = Eigen::Vector3d(5.0, 0, 0);
    s.torque_A = Eigen::Vector3d(0, 0.1, 0.5).cross(s.force_A);
    ++outcomes[static_cast<int>(observe_contact(p, model, correction_gripper(), s, &c))];
  }
  std::printf("noise: %d none, %d located, %d too deep, %d no single contact\n", outcomes[0], outcomes[1],
              outcomes[2], outcomes[3]);
  EXPECT_EQ(c.offset_A, Eigen::Vector3d::Zero());
  EXPECT_EQ(c.robot_contacts, 0u);
  EXPECT_EQ(c.model_too_deep, 0u);
  EXPECT_EQ(outcomes[static_cast<int>(ContactObservation::kNoSingleContact)], 100 - p.persistence + 1);
}

TEST(ContactCorrection, BadSamplesAreRefusedAndChangeNothing) {
  const ContactCorrectionParams p;
  const Eigen::Vector3d n(0, 0, 1), s0(0.6, 0.0, 0.8);
  CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0 - 0.005 * n, n)};
  ContactCorrection c = make_contact_correction(p);
  correction_run(p, model, s0, n, 0.0, 8.0, 0.2, &c, 2, s0, 1000);
  const ContactCorrection before = c;
  auto same = [&] {
    return c.offset_A == before.offset_A && c.P == before.P && c.contact_run == before.contact_run &&
           c.free_run == before.free_run && c.last_stamp_ns == before.last_stamp_ns;
  };
  ContactSample s;
  s.stamp_ns = before.last_stamp_ns + kSampleNs;
  s.T_A_G = correction_grasp(s0, n);
  s.force_A = 8.0 * n;
  ContactSample bad = s;
  bad.force_A.x() = std::nan("");
  EXPECT_EQ(observe_contact(p, model, correction_gripper(), bad, &c), ContactObservation::kNonFinite);
  EXPECT_TRUE(same());
  bad = s;
  bad.T_A_G.translation().y() = std::numeric_limits<double>::infinity();
  EXPECT_EQ(observe_contact(p, model, correction_gripper(), bad, &c), ContactObservation::kNonFinite);
  bad = s;
  bad.T_A_G.linear() *= 0.5;
  EXPECT_EQ(observe_contact(p, model, correction_gripper(), bad, &c), ContactObservation::kNotRotation);
  bad = s;
  bad.stamp_ns = before.last_stamp_ns;
  EXPECT_EQ(observe_contact(p, model, correction_gripper(), bad, &c), ContactObservation::kNotMonotonic);
  EXPECT_TRUE(same());
  EXPECT_EQ(c.refused, before.refused + 4);
  // The slew ignores a non-finite target and a bad dt.
  Eigen::Vector3d applied(0.001, 0, 0);
  slew_surface_offset(p, Eigen::Vector3d(std::nan(""), 0, 0), 1e-3, &applied);
  slew_surface_offset(p, Eigen::Vector3d(0.01, 0, 0), -1.0, &applied);
  EXPECT_EQ(applied, Eigen::Vector3d(0.001, 0, 0));

  ContactCorrectionParams q = p;
  q.free_force_n = q.contact_force_n;
  EXPECT_TRUE(validate(q).has_value());
  q = p;
  q.slew_m_per_s = 0;
  EXPECT_TRUE(validate(q).has_value());
  q = p;
  q.persistence = 0;
  EXPECT_TRUE(validate(q).has_value());
}

TEST(ContactCorrection, ObservingAndSlewingAllocateNothing) {
  const ContactCorrectionParams p;
  const Eigen::Vector3d n(0, 0, 1), s0(0.6, 0.0, 0.8);
  CorrectedVoxmap model{&correction_bench(), correction_plane_pose(s0 - 0.005 * n, n)};
  ContactCorrection c = make_contact_correction(p);
  Eigen::Vector3d applied = Eigen::Vector3d::Zero();
  const vps::PointShell& gripper = correction_gripper();  // built before counting
  test::count_allocations_on_this_thread(true);
  const auto before = test::counted_allocations();
  for (int i = 1; i <= 200; ++i) {
    ContactSample s;
    s.stamp_ns = i * kSampleNs;
    s.T_A_G = correction_grasp(s0 + (i > 100 ? 0.01 : 0.0) * n, n);
    s.force_A = (i > 100 ? 0.0 : 8.0) * n;
    observe_contact(p, model, gripper, s, &c);
    slew_surface_offset(p, c.offset_A, 4e-3, &applied);
  }
  const auto after = test::counted_allocations();
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(after - before, 0u);
  EXPECT_GT(c.robot_contacts, 0u);
}

}  // namespace
}  // namespace hemm::mapping
