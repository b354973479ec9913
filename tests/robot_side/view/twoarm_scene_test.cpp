// SIMULATION ONLY. The two-arm station's view as primitives and text
// (twoarm_scene.h), checked against a frame built by hand with a turned and
// moved torso: each target where T_W_A puts it, the spring's line from G to
// it, the wrist force as an arrow from G of 5 mm per N (red while the arm
// yields), each contact with its force; the text and the banners say what
// the frame holds.
#include <gtest/gtest.h>

#include <cmath>

#include "robot_side/view/twoarm_scene.h"
#include "wire.pb.h"

namespace hr = hemm::robot;
namespace hv = hemm::view;

namespace {

bool same_colour(const hv::Rgba& a, const hv::Rgba& b) { return a.r == b.r && a.g == b.g && a.b == b.b && a.a == b.a; }

const hv::Primitive* find(const hv::PrimitiveList& l, hv::Shape s, const Eigen::Vector3d& pos, double tol = 1e-9) {
  for (const hv::Primitive& p : l.items())
    if (p.shape == s && (p.pos - pos).norm() < tol) return &p;
  return nullptr;
}

struct SceneTestFrame {
  hr::TwoArmViewFrame f;
  Eigen::Isometry3d T_W_A = Eigen::Isometry3d::Identity();
  SceneTestFrame() {
    T_W_A.translation() = Eigen::Vector3d(0.3, -0.2, 0.1);
    T_W_A.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    for (std::size_t a = 0; a < 2; ++a) {
      const double s = a == 0 ? -1.0 : 1.0;
      f.snapshot.targets.T_A_G[a].translation() = Eigen::Vector3d(0.6, 0.25 * s, 0.9);
      f.snapshot.control.arm[a].T_A_G.translation() = Eigen::Vector3d(0.58, 0.25 * s, 0.88);
      f.snapshot.control.gripper[a].opening_m = 0.042;
      f.snapshot.control.gripper[a].grip_force_N = 12.5;
    }
    f.snapshot.control.wrench_ext_A[0].head<3>() = Eigen::Vector3d(0.0, 3.0, -4.0);  // 5 N
    f.snapshot.control.wrench_ext_A[1].head<3>() = Eigen::Vector3d(40.0, 0.0, 0.0);
    f.snapshot.control.arm[1].force_limited = true;
    f.ncontacts = 1;
    f.contacts_seen = 3;
    f.contacts[0].pos_W = Eigen::Vector3d(0.4, 0.1, 0.75);
    f.contacts[0].force_W = Eigen::Vector3d(0.0, 0.0, 10.0);
    f.t_ns = 2'500'000'000;
    f.link_up = true;
    f.in_control = true;
  }
};

TEST(TwoArmScene, TargetsSpringsWrenchesAndContactsWhereTheFrameHasThem) {
  SceneTestFrame t;
  hv::PrimitiveList prims;
  const hr::TwoArmSceneStyle style;
  hr::build_twoarm_scene(t.f, t.T_W_A, style, prims);
  for (std::size_t a = 0; a < 2; ++a) {
    const Eigen::Vector3d target_W = t.T_W_A * t.f.snapshot.targets.T_A_G[a].translation();
    const Eigen::Vector3d G_W = t.T_W_A * t.f.snapshot.control.arm[a].T_A_G.translation();
    const hv::Primitive* s = find(prims, hv::Shape::kSphere, target_W);
    ASSERT_NE(s, nullptr) << "arm " << a;
    EXPECT_TRUE(same_colour(s->rgba, hr::twoarm_view_colours::kArm[a]));
    const hv::Primitive* spring = find(prims, hv::Shape::kLine, G_W);
    ASSERT_NE(spring, nullptr);
    EXPECT_LT((spring->to - target_W).norm(), 1e-9);
    const hv::Primitive* arrow = find(prims, hv::Shape::kArrow, G_W);
    ASSERT_NE(arrow, nullptr);
    const Eigen::Vector3d f_W = t.T_W_A.linear() * t.f.snapshot.control.wrench_ext_A[a].head<3>();
    EXPECT_LT((arrow->to - (G_W + 0.005 * f_W)).norm(), 1e-9);
    EXPECT_TRUE(same_colour(arrow->rgba, a == 1 ? hr::twoarm_view_colours::kYielding : hr::twoarm_view_colours::kWrench));
  }
  // The target's x axis, turned with A.
  const Eigen::Vector3d target0_W = t.T_W_A * t.f.snapshot.targets.T_A_G[0].translation();
  bool x_axis = false;
  for (const hv::Primitive& p : prims.items())
    if (p.shape == hv::Shape::kLine && (p.pos - target0_W).norm() < 1e-9 &&
        (p.to - (target0_W + style.axis_length * t.T_W_A.linear().col(0))).norm() < 1e-9)
      x_axis = true;
  EXPECT_TRUE(x_axis);
  const hv::Primitive* c = find(prims, hv::Shape::kSphere, t.f.contacts[0].pos_W);
  ASSERT_NE(c, nullptr);
  const hv::Primitive* ca = find(prims, hv::Shape::kArrow, t.f.contacts[0].pos_W);
  ASSERT_NE(ca, nullptr);
  EXPECT_NEAR(ca->to.z(), 0.75 + 0.05, 1e-9);
  // A zero wrench draws no arrow.
  t.f.snapshot.control.wrench_ext_A[0].setZero();
  hr::build_twoarm_scene(t.f, t.T_W_A, style, prims);
  EXPECT_EQ(find(prims, hv::Shape::kArrow, t.T_W_A * t.f.snapshot.control.arm[0].T_A_G.translation()), nullptr);
}

TEST(TwoArmScene, TextAndBannersSayWhatTheFrameHolds) {
  SceneTestFrame t;
  hv::Overlay o = hr::twoarm_overlay(t.f, 500'000'000);
  EXPECT_NE(o.right.find("t 2.00 s"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("wrist 5.0 N, gripper 42 mm, squeeze 12.5 N"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("wrist 40.0 N (yielding)"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("up, operator in control (3 contacts, some not drawn)"), std::string::npos) << o.right;
  ASSERT_EQ(o.banners.size(), 1u);
  EXPECT_EQ(o.banners[0].text, "WRIST FORCE LIMIT");
  t.f.snapshot.control.arm[1].force_limited = false;
  t.f.snapshot.safety = hemm::wire::SAFETY_ESTOP | hemm::wire::SAFETY_LINK_LOST;
  t.f.link_up = false;
  t.f.has_task = true;
  t.f.lifted = true;
  t.f.dropped = true;
  t.f.task.tilt_rad = 0.31;
  o = hr::twoarm_overlay(t.f, 0);
  EXPECT_NE(o.right.find("E-STOP link-lost"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("lifted, DROPPED, tilt 0.31 rad"), std::string::npos) << o.right;
  ASSERT_EQ(o.banners.size(), 3u);
  EXPECT_EQ(o.banners[0].text, "E-STOP");
  EXPECT_EQ(o.banners[1].text, "NO OPERATOR LINK");
  EXPECT_EQ(o.banners[2].text, "DROPPED");
  EXPECT_EQ(hr::safety_text(0), "ok");
  EXPECT_EQ(hr::safety_text(hemm::wire::SAFETY_WATCHDOG | hemm::wire::SAFETY_REARM), "watchdog re-arm");
}

}  // namespace
