// What the operator's live view draws (operator/view/operator_scene.h),
// checked against the geometry it stands for: each map piece a wall whose
// free-side face lies on the piece, the robot's footprint at the rendered
// pose, the proxy and device point, the force arrow along the force; and the
// text's banners for link down, e-stop and no robot state.
#include <gtest/gtest.h>
#include <numbers>

#include <cmath>

#include "common/haptics/vps/voxmap.h"
#include "common/mesh/primitives.h"
#include "operator/view/operator_scene.h"
#include "wire.pb.h"

namespace ho = hemm::op;
namespace hm = hemm::math;
namespace hv = hemm::view;
namespace hmap = hemm::mapping;

namespace {

bool same(hv::Rgba a, hv::Rgba b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

TEST(OperatorScene, AMapPieceIsAWallStandingBehindItsFace) {
  ho::ViewModel m;
  hmap::Segment2 s;  // the face x = 2 from y = -1 to 1, free side toward -x
  s.a = Eigen::Vector2d(2, -1);
  s.b = Eigen::Vector2d(2, 1);
  s.normal = Eigen::Vector2d(-1, 0);
  m.segments.push_back(s);
  s.kind = hmap::SensorKind::kSonar;
  m.segments.push_back(s);
  const ho::OperatorSceneStyle st;
  hv::PrimitiveList out;
  ho::build_operator_scene(m, nullptr, st, out);
  ASSERT_EQ(out.size(), 2u);  // no state, no tick: the map only
  const hv::Primitive& w = out.items()[0];
  EXPECT_EQ(w.shape, hv::Shape::kBox);
  EXPECT_TRUE(same(w.rgba, ho::view_colours::kMapLaser));
  EXPECT_TRUE(same(out.items()[1].rgba, ho::view_colours::kMapSonar));
  // The box's corners in W: its -x face on x = 2, spanning y in [-1, 1],
  // z in [0, wall_height], thickness behind the face.
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9, zmin = 1e9, zmax = -1e9;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c((i & 1) ? 1 : -1, (i & 2) ? 1 : -1, (i & 4) ? 1 : -1);
    const Eigen::Vector3d p = w.pos + w.R * c.cwiseProduct(w.size);
    xmin = std::min(xmin, p.x()), xmax = std::max(xmax, p.x());
    ymin = std::min(ymin, p.y()), ymax = std::max(ymax, p.y());
    zmin = std::min(zmin, p.z()), zmax = std::max(zmax, p.z());
  }
  EXPECT_NEAR(xmin, 2.0, 1e-12);
  EXPECT_NEAR(xmax, 2.0 + st.wall_thickness, 1e-12);
  EXPECT_NEAR(ymin, -1.0, 1e-12);
  EXPECT_NEAR(ymax, 1.0, 1e-12);
  EXPECT_NEAR(zmin, 0.0, 1e-12);
  EXPECT_NEAR(zmax, st.wall_height, 1e-12);
}

// The live voxmap (depth clouds) is drawn as its surface: every cube on the
// surface of the geometry it was built from, within the geom budget, in W.
TEST(OperatorScene, TheLiveVoxmapIsDrawnAsCubesOnItsSurface) {
  // A 0.6 x 0.4 x 0.1 m table-like slab, centred at (1.5, 0.2, 0.7) in W.
  const Eigen::Vector3d half(0.3, 0.2, 0.05), centre(1.5, 0.2, 0.7);
  hemm::mesh::TriangleMesh slab = hemm::mesh::make_box(half, 4);
  for (auto& v : slab.vertices) v += centre;
  hemm::vps::VoxmapParams vp;
  vp.voxel_size = 0.01;
  auto vm = std::make_shared<hemm::vps::Voxmap>();
  ASSERT_FALSE(hemm::vps::build_voxmap(slab, vp, vm.get(), nullptr));

  ho::ViewModel m;
  m.voxmap = vm;
  m.voxmap_builds = 7;
  const std::size_t budget = 400;
  ho::update_voxmap_cubes(m, budget);
  EXPECT_EQ(m.voxmap_cubes_of, 7u);
  EXPECT_GT(m.voxmap_cubes.surface_voxels, budget);  // merged: more voxels than cubes
  ASSERT_GT(m.voxmap_cubes.centres.size(), 30u);
  EXPECT_LE(m.voxmap_cubes.centres.size(), budget);
  for (const Eigen::Vector3d& c : m.voxmap_cubes.centres) {
    const Eigen::Vector3d q = (c - centre).cwiseAbs();
    const Eigen::Vector3d outside = (q - half).cwiseMax(0.0);
    const double to_surface = outside.norm() > 0 ? outside.norm() : (half - q).minCoeff();
    EXPECT_LE(to_surface, std::sqrt(3.0) * m.voxmap_cubes.half + 1e-9) << c.transpose();
  }

  const ho::OperatorSceneStyle st;
  hv::PrimitiveList out;
  ho::build_operator_scene(m, nullptr, st, out);
  std::size_t cubes = 0;
  for (const hv::Primitive& p : out.items()) {
    if (!same(p.rgba, ho::view_colours::kVoxmap)) continue;
    ++cubes;
    EXPECT_EQ(p.shape, hv::Shape::kBox);
    EXPECT_NEAR(p.size.x(), m.voxmap_cubes.half, 1e-12);
  }
  EXPECT_EQ(cubes, m.voxmap_cubes.centres.size());

  // Without a voxmap nothing of it is drawn.
  m.voxmap.reset();
  ho::update_voxmap_cubes(m, budget);
  EXPECT_TRUE(m.voxmap_cubes.centres.empty());
  ho::build_operator_scene(m, nullptr, st, out);
  EXPECT_EQ(out.size(), 0u);
}

TEST(OperatorScene, RobotProxyDevicePointAndForce) {
  ho::ViewModel m;
  m.have_state = true;
  m.state.T_W_R_odom = hm::Pose2{0.9, 2.0, std::numbers::pi / 2};
  ho::StationLogRecord t;
  t.robot[0] = 1.0;
  t.robot[1] = 2.0;
  t.robot[2] = std::numbers::pi / 2;  // heading +y
  t.proxy_W[0] = 1.0;
  t.proxy_W[1] = 3.0;
  t.goal_W[0] = 1.0;
  t.goal_W[1] = 3.1;
  t.force_W[0] = 0.0;
  t.force_W[1] = -2.0;
  const ho::OperatorSceneStyle st;
  hv::PrimitiveList out;
  ho::build_operator_scene(m, &t, st, out);
  int robots = 0, proxies = 0, devices = 0, forces = 0, outline = 0;
  for (const hv::Primitive& p : out.items()) {
    if (p.shape == hv::Shape::kBox && same(p.rgba, ho::view_colours::kRobot)) {
      ++robots;
      EXPECT_TRUE(p.pos.isApprox(Eigen::Vector3d(1.0, 2.0, st.robot_half.z())));
      // Turned by the heading: the footprint's long axis (x_R) along +y.
      EXPECT_TRUE((p.R * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
    }
    if (p.shape == hv::Shape::kSphere && same(p.rgba, ho::view_colours::kProxy)) {
      ++proxies;
      EXPECT_TRUE(p.pos.head<2>().isApprox(Eigen::Vector2d(1.0, 3.0)));
    }
    if (p.shape == hv::Shape::kSphere && same(p.rgba, ho::view_colours::kDevicePoint)) {
      ++devices;
      EXPECT_TRUE(p.pos.head<2>().isApprox(Eigen::Vector2d(1.0, 3.1)));
      EXPECT_LT(p.pos.z(), st.marker_z);  // under the proxy when they meet
    }
    if (p.shape == hv::Shape::kArrow && same(p.rgba, ho::view_colours::kForce)) {
      ++forces;
      EXPECT_TRUE(p.pos.head<2>().isApprox(Eigen::Vector2d(1.0, 3.0)));
      EXPECT_TRUE((p.to - p.pos).isApprox(Eigen::Vector3d(0, -2.0 * st.force_scale, 0)));
    }
    if (p.shape == hv::Shape::kLine && same(p.rgba, ho::view_colours::kRobotReceived)) {
      ++outline;
      // Corners of the received pose's footprint (heading +y: x extent = half y).
      for (const Eigen::Vector3d& q : {p.pos, p.to}) {
        if (std::abs(q.y() - 2.0) > st.robot_half.x() + 0.1 + 1e-9 || std::abs(q.x() - 0.9) > st.robot_half.y() + 1e-9)
          ADD_FAILURE() << q.transpose();
      }
    }
  }
  EXPECT_EQ(robots, 1);
  EXPECT_EQ(proxies, 1);
  EXPECT_EQ(devices, 1);
  EXPECT_EQ(forces, 1);
  EXPECT_EQ(outline, 5);  // four edges and the heading
}

TEST(OperatorOverlay, BannersForLinkDownEStopAndNoState) {
  ho::ViewModel m;
  hemm::net::LinkStatistics link;
  link.link_up = true;
  ho::OverlayInputs in;
  in.model = &m;
  in.link = &link;
  auto banners = [&] {
    std::string s;
    for (const auto& b : ho::make_operator_overlay(in).banners) s += b.text + ";";
    return s;
  };
  EXPECT_EQ(banners(), "NO ROBOT STATE;");
  m.have_state = true;
  EXPECT_EQ(banners(), "");
  link.link_up = false;
  m.state.safety = hemm::wire::SAFETY_ESTOP;
  EXPECT_EQ(banners(), "LINK DOWN;E-STOP;");
  m.state.safety = 0;
  in.estop_requested = true;
  EXPECT_EQ(banners(), "LINK DOWN;E-STOP REQUESTED;");
  ho::StationLogRecord t;
  t.mode = hemm::wire::MODE_NAVIGATION;
  t.scale = 25.0;
  in.tick = &t;
  const hv::Overlay o = ho::make_operator_overlay(in);
  EXPECT_NE(o.right.find("navigation"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("scale 25.0"), std::string::npos) << o.right;
  EXPECT_NE(o.right.find("DOWN"), std::string::npos) << o.right;
}

}  // namespace
