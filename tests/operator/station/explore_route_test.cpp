// The exploration routes of a scene file's header (operator/station/
// explore_route.h): a good header read back exactly, home.xml's routes (the
// key poses the 6-DoF table numbers were measured with), malformed lines
// refused with the file, line and reason and no change to the output, and
// keys out of the SIMULATED rigid hand's reach refused with the reason.
#include <gtest/gtest.h>

#include <iomanip>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "operator/device/haptic_device.h"
#include "operator/station/explore_route.h"
#include "operator/station/tool6_explorer.h"

namespace ho = hemm::op;

namespace {

const char* kGood = R"(<!--
  A scene. Prose may say explore6 anywhere but at a line's start
  with a colon; "explore-table" here is prose too.
    explore-start: 1.5 -2 0.25
    explore-region: 0 1 2 3 4 5
    explore6: a   0 0.8 0.1 0.9 0    -
    explore6: a   2 0.8 0.1 0.8 0.3  top
    explore6: b   0 0.7 0   0.9 0    -
    explore6: a   3 0.8 0.2 0.8 0    top
    explore6: a   4 0.8 0.2 0.9 0    -
    explore6: a   5 0.7 0.2 0.8 0    side
    explore6: b   1 0.7 0   0.8 0    floor
-->
<mujoco/>
)";

// The text with line `n` (1-based) replaced.
std::string with_line(const std::string& text, int n, const std::string& line) {
  std::vector<std::string> lines;
  std::size_t p = 0;
  while (p <= text.size()) {
    const std::size_t e = text.find('\n', p);
    lines.push_back(text.substr(p, e == std::string::npos ? std::string::npos : e - p));
    if (e == std::string::npos) break;
    p = e + 1;
  }
  lines.at(static_cast<std::size_t>(n - 1)) = line;
  std::string s;
  for (std::size_t i = 0; i < lines.size(); ++i) s += lines[i] + (i + 1 < lines.size() ? "\n" : "");
  return s;
}

// A sentinel output that an error must leave as it is.
ho::SceneExploration sentinel() {
  ho::SceneExploration s;
  s.start_W = {7, 8, 9};
  s.routes.push_back({"keep", {}});
  return s;
}

}  // namespace

TEST(ExploreRoute, AGoodHeaderIsReadExactly) {
  ho::SceneExploration x;
  ASSERT_EQ(ho::parse_scene_exploration(kGood, "s.xml", &x), std::nullopt);
  EXPECT_EQ(x.start_W.x, 1.5);
  EXPECT_EQ(x.start_W.y, -2.0);
  EXPECT_EQ(x.start_W.theta, 0.25);
  EXPECT_EQ(x.region_W.min(), Eigen::Vector3d(0, 1, 2));
  EXPECT_EQ(x.region_W.max(), Eigen::Vector3d(3, 4, 5));
  ASSERT_EQ(x.routes.size(), 2u);
  EXPECT_EQ(x.route_names(), "a, b");
  const ho::ExploreRoute* a = x.find("a");
  ASSERT_NE(a, nullptr);
  ASSERT_EQ(a->keys.size(), 5u);
  EXPECT_EQ(a->keys[1].t_s, 2.0);
  EXPECT_EQ(a->keys[1].tip_R, Eigen::Vector3d(0.8, 0.1, 0.8));
  EXPECT_EQ(a->keys[1].tilt_x_rad, 0.3);
  EXPECT_EQ(a->keys[1].feature, "top");
  EXPECT_EQ(a->keys[1].line, 7);
  EXPECT_EQ(a->keys[4].line, 11);
  EXPECT_EQ(x.find("nope"), nullptr);
  // Features span from their first key to their last, transits inside them.
  const std::vector<ho::RouteFeature> f = ho::route_features(*a);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[0].name, "top");
  EXPECT_EQ(f[0].t0_s, 2.0);
  EXPECT_EQ(f[0].t1_s, 3.0);
  EXPECT_EQ(f[1].name, "side");
  EXPECT_EQ(f[1].t0_s, 5.0);
  EXPECT_EQ(f[1].t1_s, 5.0);
  // The hand's path: the tip in H (R less H's origin), turned about x.
  const Eigen::Vector3d origin(0.85, 0, 0.95);
  const hemm::device::Trajectory t = ho::make_hand6_trajectory(*a, origin);
  ASSERT_EQ(t.samples.size(), 5u);
  EXPECT_TRUE(t.samples[1].ee[0].position_H.isApprox(Eigen::Vector3d(-0.05, 0.1, -0.15), 1e-15));
  EXPECT_NEAR(t.samples[1].ee[0].orientation_H.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))),
              0.0, 1e-12);

  // No header, or a header without directives: no routes.
  ho::SceneExploration none = sentinel();
  ASSERT_EQ(ho::parse_scene_exploration("<mujoco/>", "n.xml", &none), std::nullopt);
  EXPECT_TRUE(none.routes.empty());
  none = sentinel();
  ASSERT_EQ(ho::parse_scene_exploration("<?xml version=\"1.0\"?>\n<!-- prose only -->\n<mujoco/>", "n.xml", &none),
            std::nullopt);
  EXPECT_TRUE(none.routes.empty());
}

TEST(ExploreRoute, HomeHasTheTableAndBlockRoutesItsNumbersWereMeasuredWith) {
  ho::SceneExploration x;
  ASSERT_EQ(ho::load_scene_exploration(HEMM_SOURCE_DIR "/deploy/scenes/home.xml", &x), std::nullopt);
  EXPECT_EQ(x.route_names(), "explore-table, explore-block");
  const ho::ExploreRoute* t = x.find("explore-table");
  const ho::ExploreRoute* b = x.find("explore-block");
  ASSERT_TRUE(t && b);
  EXPECT_EQ(t->keys.size(), 53u);
  EXPECT_EQ(b->keys.size(), 20u);
  EXPECT_EQ(t->keys.back().t_s, 58.5);
  EXPECT_EQ(b->keys.back().t_s, 23.0);
  // The tilted press on the block's top and the mug's front side as they were.
  EXPECT_EQ(t->keys[8].t_s, 13.0);
  EXPECT_EQ(t->keys[8].tip_R, Eigen::Vector3d(0.85, -0.25, 0.865));
  EXPECT_EQ(t->keys[8].tilt_x_rad, 0.35);
  EXPECT_EQ(t->keys[49].tip_R, Eigen::Vector3d(1.145, -0.10, 0.80));
  // The per-feature table's phases (deploy/explore3d.sh had them in Python).
  const std::vector<ho::RouteFeature> f = ho::route_features(*t);
  const std::vector<std::tuple<std::string, double, double>> want = {
      {"block-top", 6, 15},    {"block-front", 16, 22}, {"block-left", 23, 30}, {"book-top", 32, 40.5},
      {"book-front", 41.5, 46.5}, {"mug-top", 48.5, 52.5}, {"mug-front", 53.5, 58.5}};
  ASSERT_EQ(f.size(), want.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    EXPECT_EQ(f[i].name, std::get<0>(want[i]));
    EXPECT_EQ(f[i].t0_s, std::get<1>(want[i]));
    EXPECT_EQ(f[i].t1_s, std::get<2>(want[i]));
  }
  // explore-block is explore-table's first 19 keys, then a lift.
  for (std::size_t i = 0; i < 19; ++i) {
    EXPECT_EQ(b->keys[i].t_s, t->keys[i].t_s);
    EXPECT_EQ(b->keys[i].tip_R, t->keys[i].tip_R);
  }
  EXPECT_EQ(x.start_W.x, 1.5);
  EXPECT_EQ(x.start_W.y, 1.0);
}

TEST(ExploreRoute, MalformedLinesAreRefusedWithTheLineAndReasonAndChangeNothing) {
  struct Case {
    int line;
    std::string text, error;
  };
  const std::vector<Case> cases = {
      {6, "    explore6: a 0 0.8 0.1 0.9 0", "s.xml:6: explore6: expected ROUTE T X Y Z TILT_X FEATURE (7 fields), got 6"},
      {7, "    explore6: a 2 0.8 x 0.8 0.3 top", "s.xml:7: explore6: 'x' is not a finite number"},
      {7, "    explore6: a 2 0.8 nan 0.8 0.3 top", "s.xml:7: explore6: 'nan' is not a finite number"},
      {7, "    explore6: a 2 0.8 0.1 0.8 0.3 Top", "s.xml:7: explore6: feature 'Top': lower-case"},
      {7, "    explore6: A 2 0.8 0.1 0.8 0.3 top", "s.xml:7: explore6: route name 'A'"},
      {7, "    explore6: a 0 0.8 0.1 0.8 0.3 top", "s.xml:7: explore6: t = 0 s is not after the previous key's 0 s (line 6)"},
      {7, "    explore6: a 2 0.8 0.1 0.8 2 top", "s.xml:7: explore6: |TILT_X| must be at most pi/2"},
      {7, "    explore6: a 2 9 0.1 0.8 0 top", "s.xml:7: explore6: the tip must be within 5 m of R's origin"},
      {7, "    explore6: a -1 0.8 0.1 0.8 0 top", "s.xml:7: explore6: T must be within [0, 3600] s"},
      {8, "    explore6: b 1 0.7 0 0.9 0 -", "s.xml:8: explore6: route b's first key must be at t = 0"},
      {12, "    explore6: a 6 0.7 0.2 0.8 0 top", "s.xml:12: explore6: feature 'top' of route a resumes after 'side'"},
      {4, "    explore-start: 1.5 -2", "s.xml:4: explore-start: expected X Y THETA (3 numbers), got 2"},
      {4, "    explore-start: 1.5 -2 inf", "s.xml:4: explore-start: 'inf' is not a finite number"},
      {5, "    explore-region: 0 1 2 3 0.5 5", "s.xml:5: explore-region: each minimum must be below its maximum"},
      {5, "    explore-start: 1 2 3", "s.xml:5: explore-start: given twice (first on line 4)"},
      {5, "    explore4: a 0 0.8 0.1 0.9 -",
       "s.xml:5: unknown directive 'explore4:' (explore-start:, explore-region:, explore6:, explore3:)"},
      {4, "    prose", "s.xml: a scene with explore6 or explore3 routes needs explore-start: X Y THETA"},
      {5, "    prose", "s.xml: a scene with explore6 or explore3 routes needs explore-region: (6 numbers)"},
      {13, "", "s.xml:1: unterminated header comment"},  // the closing line gone
  };
  for (const Case& c : cases) {
    ho::SceneExploration x = sentinel();
    const auto e = ho::parse_scene_exploration(with_line(kGood, c.line, c.text), "s.xml", &x);
    ASSERT_TRUE(e.has_value()) << c.text;
    EXPECT_EQ(e->rfind(c.error, 0), 0u) << *e;
    EXPECT_EQ(x.start_W.x, 7.0) << c.text;  // untouched
    ASSERT_EQ(x.routes.size(), 1u);
    EXPECT_EQ(x.routes[0].name, "keep");
  }
  // A route of one key, and one naming no feature.
  const std::string one = "<!--\n explore-start: 0 0 0\n explore-region: 0 0 0 1 1 1\n explore6: a 0 1 0 1 0 x\n-->";
  ho::SceneExploration x = sentinel();
  EXPECT_EQ(ho::parse_scene_exploration(one, "o.xml", &x), "o.xml: explore6 route a needs at least two keys");
  const std::string transit =
      "<!--\n explore-start: 0 0 0\n explore-region: 0 0 0 1 1 1\n explore6: a 0 1 0 1 0 -\n explore6: a 1 1 0 1 0 -\n-->";
  EXPECT_EQ(ho::parse_scene_exploration(transit, "o.xml", &x), "o.xml: explore6 route a names no feature (every key is '-')");
  EXPECT_EQ(x.routes[0].name, "keep");
  EXPECT_EQ(ho::load_scene_exploration("/nonexistent/scene.xml", &x), "/nonexistent/scene.xml: cannot read");
}

TEST(ExploreRoute, KeysOutOfTheHandsReachAreRefusedWithTheReason) {
  const hemm::device::EndEffectorLimits hand = hemm::device::rigid_hand_limits(1).ee[0];  // +-1 m box, 1.5 m/s
  ho::SceneExploration x;
  ASSERT_EQ(ho::parse_scene_exploration(kGood, "s.xml", &x), std::nullopt);
  const Eigen::Vector3d origin(0.85, 0, 0.95);
  EXPECT_EQ(ho::check_route_reach(*x.find("a"), origin, hand, "s.xml"), std::nullopt);
  // H's origin 1.2 m higher: the keys 1.1-1.35 m below it, out of the box.
  const auto low = ho::check_route_reach(*x.find("a"), origin + Eigen::Vector3d(0, 0, 1.2), hand, "s.xml");
  ASSERT_TRUE(low);
  EXPECT_EQ(low->rfind("s.xml:6: explore6 a at t = 0 s: the tip (0.800 0.100 0.900) in R is out of the device's "
                       "reach: (-0.050 0.100 -1.250) in H, outside its workspace box (-1.000 -1.000 -1.000) to "
                       "(1.000 1.000 1.000)",
                       0),
            0u)
      << *low;
  // A key 1.6 m away 1 s after the last: faster than the hand moves.
  const std::string fast = with_line(kGood, 10, "    explore6: a 4 0.8 0.2 2.4 0 -");
  ASSERT_EQ(ho::parse_scene_exploration(fast, "s.xml", &x), std::nullopt);
  const auto f = ho::check_route_reach(*x.find("a"), Eigen::Vector3d(0.85, 0, 1.6), hand, "s.xml");
  ASSERT_TRUE(f);
  EXPECT_EQ(f->rfind("s.xml:10: explore6 a at t = 4 s: the tip moves at 1.60 m/s from the previous key, above the "
                     "device's 1.50 m/s",
                     0),
            0u)
      << *f;
  // load_hand6_route names the field and refuses an unknown route.
  try {
    (void)ho::load_hand6_route(HEMM_SOURCE_DIR "/deploy/scenes/home.xml", "explore-moon", origin, hand);
    ADD_FAILURE() << "an unknown route was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("probe_3d.tool_hand_script: no route 'explore-moon' in ", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("(its explore6 routes: explore-table, explore-block)"), std::string::npos);
  }
}

// ------------------------------------------------------------ explore3
namespace {

// Beside an explore6 route of the same name (the two kinds do not mix).
// The start turned by exactly pi/2 (printed to the last digit, so the
// mapping's closed forms below hold to 1e-12).
std::string good3_header() {
  std::ostringstream start;
  start << std::setprecision(17) << "    explore-start: 2 1 " << std::numbers::pi / 2 << "\n";
  return "<!--\n" + start.str() + R"(    explore-region: 0 1 2 3 4 5
    explore6: a 0 0.8 0.1 0.9 0 -
    explore6: a 1 0.8 0.1 0.8 0 top
    explore3: a 0   2.1 1.9 0.95 -
    explore3: a 1.5 2.1 1.9 0.85 top
    explore3: p 0   2.0 1.8 0.9  -
    explore3: a 2   2.0 1.9 0.85 top
    explore3: a 3   2.0 1.8 0.8  side
    explore3: p 1   2.0 1.8 0.85 floor
-->
<mujoco/>
)";
}
const std::string kGood3 = good3_header();

}  // namespace

TEST(ExploreRoute3, AGoodHeaderIsReadExactlyBesideTheExplore6Routes) {
  ho::SceneExploration x;
  ASSERT_EQ(ho::parse_scene_exploration(kGood3, "s3.xml", &x), std::nullopt);
  EXPECT_EQ(x.route_names(), "a");
  EXPECT_EQ(x.route3_names(), "a, p");
  ASSERT_EQ(x.find("a")->keys.size(), 2u);  // the explore6 route keeps its own keys
  const ho::ExploreRoute3* a = x.find3("a");
  ASSERT_NE(a, nullptr);
  ASSERT_EQ(a->keys.size(), 4u);
  EXPECT_EQ(a->keys[1].t_s, 1.5);
  EXPECT_EQ(a->keys[1].p_W, Eigen::Vector3d(2.1, 1.9, 0.85));
  EXPECT_EQ(a->keys[1].feature, "top");
  EXPECT_EQ(a->keys[1].line, 7);
  EXPECT_EQ(x.find3("nope"), nullptr);
  const std::vector<ho::RouteFeature> f = ho::route_features(*a);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_EQ(f[0].name, "top");
  EXPECT_EQ(f[0].t0_s, 1.5);
  EXPECT_EQ(f[0].t1_s, 2.0);
  EXPECT_EQ(f[1].name, "side");
  // W -> H by hand: the robot at (2, 1) facing +y, so R x = W y - 1, R y = 2 - W x;
  // W (2.1, 1.9, 0.85) is R (0.9, -0.1, 0.85). The map (scale 7.5, origin R (0.9, 0, 0.85))
  // gives B (0, -0.1 / 7.5, 0), and H = (-y_B, z_B, -x_B) = (0.1 / 7.5, 0, 0).
  const hemm::math::ScaledMap m{7.5, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.9, 0, 0.85)};
  EXPECT_TRUE(ho::route3_point_H(a->keys[1].p_W, x.start_W, m).isApprox(Eigen::Vector3d(0.1 / 7.5, 0, 0), 1e-12))
      << ho::route3_point_H(a->keys[1].p_W, x.start_W, m).transpose();
}

TEST(ExploreRoute3, MalformedLinesAreRefusedWithTheLineAndReasonAndChangeNothing) {
  struct Case {
    int line;
    std::string text, error;
  };
  const std::vector<Case> cases = {
      {7, "    explore3: a 1.5 2.1 1.9 0.85", "s.xml:7: explore3: expected ROUTE T X Y Z FEATURE (6 fields), got 5"},
      {7, "    explore3: a 1.5 2.1 1.9 0.85 0 top", "s.xml:7: explore3: expected ROUTE T X Y Z FEATURE (6 fields), got 7"},
      {7, "    explore3: a 1.5 2.1 y 0.85 top", "s.xml:7: explore3: 'y' is not a finite number"},
      {7, "    explore3: a 1.5 2.1 1.9 inf top", "s.xml:7: explore3: 'inf' is not a finite number"},
      {7, "    explore3: a 1.5 2.1 1.9 0.85 Top", "s.xml:7: explore3: feature 'Top': lower-case"},
      {7, "    explore3: a_b 1.5 2.1 1.9 0.85 top", "s.xml:7: explore3: route name 'a_b'"},
      {7, "    explore3: a 0 2.1 1.9 0.85 top", "s.xml:7: explore3: t = 0 s is not after the previous key's 0 s (line 6)"},
      {7, "    explore3: a 1.5 200 1.9 0.85 top", "s.xml:7: explore3: the point must be within 100 m"},
      {7, "    explore3: a 4000 2.1 1.9 0.85 top", "s.xml:7: explore3: T must be within [0, 3600] s"},
      {8, "    explore3: p 0.5 2.0 1.8 0.9 -", "s.xml:8: explore3: route p's first key must be at t = 0"},
      {11, "    explore3: a 4 2.0 1.8 0.8 top", "s.xml:11: explore3: feature 'top' of route a resumes after 'side'"},
      {2, "    prose", "s.xml: a scene with explore6 or explore3 routes needs explore-start: X Y THETA"},
  };
  for (const Case& c : cases) {
    ho::SceneExploration x = sentinel();
    const auto e = ho::parse_scene_exploration(with_line(kGood3, c.line, c.text), "s.xml", &x);
    ASSERT_TRUE(e.has_value()) << c.text;
    EXPECT_EQ(e->rfind(c.error, 0), 0u) << *e;
    EXPECT_EQ(x.start_W.x, 7.0) << c.text;  // untouched
    ASSERT_EQ(x.routes.size(), 1u);
    EXPECT_EQ(x.routes[0].name, "keep");
    EXPECT_TRUE(x.routes3.empty());
  }
  const std::string one = "<!--\n explore-start: 0 0 0\n explore-region: 0 0 0 1 1 1\n explore3: a 0 1 0 1 x\n-->";
  ho::SceneExploration x = sentinel();
  EXPECT_EQ(ho::parse_scene_exploration(one, "o.xml", &x), "o.xml: explore3 route a needs at least two keys");
  const std::string transit =
      "<!--\n explore-start: 0 0 0\n explore-region: 0 0 0 1 1 1\n explore3: a 0 1 0 1 -\n explore3: a 1 1 0 1 -\n-->";
  EXPECT_EQ(ho::parse_scene_exploration(transit, "o.xml", &x), "o.xml: explore3 route a names no feature (every key is '-')");
  EXPECT_EQ(x.routes[0].name, "keep");
}

TEST(ExploreRoute3, PointsOutOfTheOmnisReachAreRefusedWithTheReason) {
  const hemm::device::EndEffectorLimits omni = hemm::device::phantom_omni_limits().ee[0];  // +-80, 60, 35 mm
  ho::SceneExploration x;
  ASSERT_EQ(ho::parse_scene_exploration(kGood3, "s.xml", &x), std::nullopt);
  const hemm::math::ScaledMap m{7.5, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.9, 0, 0.85)};
  EXPECT_EQ(ho::check_route3_reach(*x.find3("a"), x.start_W, m, omni, "s.xml"), std::nullopt);
  // Depth: z_H = -x_B spans +-35 mm, +-0.2625 m of R x at scale 7.5. A key at R x 1.2
  // (W y 2.2) is 0.3 m ahead of the origin: z_H = -0.04, out of the box.
  const std::string far = with_line(kGood3, 9, "    explore3: a 2 2.05 2.2 0.85 top");
  ASSERT_EQ(ho::parse_scene_exploration(far, "s.xml", &x), std::nullopt);
  const auto e = ho::check_route3_reach(*x.find3("a"), x.start_W, m, omni, "s.xml");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->rfind("s.xml:9: explore3 a at t = 2 s: the point (2.050 2.200 0.850) in W is out of the Omni's reach: "
                     "(0.007 0.000 -0.040) in H, outside its workspace box (-0.080 -0.060 -0.035) to (0.080 0.060 "
                     "0.035) (probe_3d: 7.500 W m per device m, origin (0.900 0.000 0.850) in R)",
                     0),
            0u)
      << *e;
  // The same route with the origin 10 cm further out: reached.
  const hemm::math::ScaledMap m2{7.5, Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0, 0.85)};
  EXPECT_EQ(ho::check_route3_reach(*x.find3("a"), x.start_W, m2, omni, "s.xml"), std::nullopt);
}
