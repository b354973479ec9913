// SIMULATION ONLY truth of the 3-DoF point probe (robot_side/truth/
// probe3_truth.h): a probe pressed a known depth d into a box face of an MJCF
// scene, voxelised exactly as hemm-truth --probe3 does it, rests on the face
// with the contact law's force k d / scale along the face's normal (the
// proxy at the probe radius outside the face, the device point d deeper);
// the error against a live run that rendered exactly that law is near zero,
// and malformed world logs are refused with the file, line and reason.
#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

#include "common/haptics/vps/voxmap.h"
#include "robot_side/truth/probe3_truth.h"
#include "robot_side/truth/tool6_truth.h"
#include "tests/temp_dir.h"

namespace hr = hemm::robot;

namespace {

// A box on its own (not a scene anything was tuned on): centre (0.5, -0.2,
// 0.4), half extents (0.1, 0.08, 0.05): top z 0.45, the +x face at x 0.6.
constexpr const char* kProbe3BoxScene = R"(<mujoco model="probe3_box">
  <worldbody>
    <geom name="box" type="box" pos="0.5 -0.2 0.4" size="0.1 0.08 0.05"/>
  </worldbody>
</mujoco>
)";

std::string probe3_write(const std::string& dir, const std::string& name, const std::string& text) {
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// A live run along from -> to in 1 s, then held 1.5 s, whose force is the
// contact law against the plane through `face` with outward normal n
// (proxy at the probe radius outside it).
std::vector<hr::Probe3Tick> probe3_press(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                         const Eigen::Vector3d& face, const Eigen::Vector3d& n, double rho, double k,
                                         double scale) {
  std::vector<hr::Probe3Tick> ticks;
  for (int i = 0; i < 2500; ++i) {
    hr::Probe3Tick t;
    t.t_s = i * 1e-3;
    t.goal_W = from + std::min(1.0, i / 1000.0) * (to - from);
    const double pen = rho - n.dot(t.goal_W - face);
    t.contact = pen > 0;
    t.force_W = pen > 0 ? Eigen::Vector3d(k * pen / scale * n) : Eigen::Vector3d::Zero();
    ticks.push_back(t);
  }
  return ticks;
}

}  // namespace

TEST(Probe3Truth, AProbePressedIntoABoxFaceFeelsTheContactLaw) {
  const std::string dir = hemm::test::make_temp_dir("probe3-truth");
  const std::string scene = probe3_write(dir, "box.xml", kProbe3BoxScene);
  hemm::vps::Voxmap vm;
  std::vector<std::string> parts;
  std::string error;
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.3, -0.4, 0.25), Eigen::Vector3d(0.75, 0.0, 0.6));
  ASSERT_TRUE(hr::build_truth_voxmap(scene, region, 0.0025, &vm, &parts, &error)) << error;
  ASSERT_EQ(parts.size(), 1u);

  hemm::vps::PointProbeParams p;
  p.force.probe_radius = 0.01;
  p.force.period = 1e-3;
  const double scale = 7.5, rho = p.force.probe_radius, k = p.force.stiffness, d = 0.012;
  struct Face {
    const char* name;
    Eigen::Vector3d point, normal, start;
  };
  const Face faces[] = {
      {"top", {0.52, -0.18, 0.45}, {0, 0, 1}, {0.52, -0.18, 0.50}},
      {"+x side", {0.60, -0.23, 0.41}, {1, 0, 0}, {0.66, -0.23, 0.41}},
  };
  for (const Face& f : faces) {
    const Eigen::Vector3d to = f.point + (rho - d) * f.normal;  // d past where the probe's sphere touches
    const std::vector<hr::Probe3Tick> ticks = probe3_press(f.start, to, f.point, f.normal, rho, k, scale);
    const hr::Probe3Truth t = hr::evaluate_probe3(ticks, p, scale, vm);
    const Eigen::Vector3d want = k * d / scale * f.normal;  // 0.48 N
    const Eigen::Vector3d& got = t.force_W.back();
    // The proxy within 0.25 mm of the plane at rho: 0.01 N of the law.
    EXPECT_NEAR((got - want).norm(), 0.0, 0.01) << f.name << ": " << got.transpose();
    EXPECT_NEAR((t.proxy_W.back() - (f.point + rho * f.normal)).dot(f.normal), 0.0, 2.5e-4) << f.name;
    EXPECT_EQ(t.contact.back(), 1) << f.name;
    EXPECT_EQ(t.contact.front(), 0) << f.name;  // 5-6 cm off the face
    EXPECT_NEAR(t.true_force_peak, want.norm(), 0.02) << f.name;
    // The live run rendered the law itself: the error is the truth's
    // discretisation and the damping while moving, small beside 0.48 N.
    EXPECT_GT(t.contact_ticks, 1000u) << f.name;
    EXPECT_LT(t.force_rms, 0.02) << f.name;
  }
}

TEST(Probe3Truth, ATickWithoutAModelOrOutsideExplorationFeelsNothing) {
  const std::string dir = hemm::test::make_temp_dir("probe3-truth");
  hemm::vps::Voxmap vm;
  std::vector<std::string> parts;
  std::string error;
  const Eigen::AlignedBox3d region(Eigen::Vector3d(0.3, -0.4, 0.25), Eigen::Vector3d(0.75, 0.0, 0.6));
  ASSERT_TRUE(hr::build_truth_voxmap(probe3_write(dir, "box.xml", kProbe3BoxScene), region, 0.0025, &vm, &parts, &error));
  hemm::vps::PointProbeParams p;
  p.force.probe_radius = 0.01;
  std::vector<hr::Probe3Tick> ticks(3);
  for (hr::Probe3Tick& t : ticks) t.goal_W = Eigen::Vector3d(0.5, -0.2, 0.452);  // inside the probe's reach of the top
  ticks[0].model = false;
  ticks[1].exploring = false;
  const hr::Probe3Truth t = hr::evaluate_probe3(ticks, p, 7.5, vm);
  EXPECT_EQ(t.force_W[0].norm(), 0.0);
  EXPECT_EQ(t.force_W[1].norm(), 0.0);
  EXPECT_GT(t.force_W[2].z(), 0.0);  // the model back, exploring: pushed up
}

TEST(Probe3Truth, MalformedWorldLogsAreRefusedWithTheLineAndChangeNothing) {
  const std::string dir = hemm::test::make_temp_dir("probe3-log");
  const std::string head =
      "t_ns,mode,goal_x,goal_y,goal_z,fw_x,fw_y,fw_z,proxy3_x,proxy3_y,proxy3_z,force_gain,probe3_contact,model_version\n";
  const std::string row1 = "1000000,4,0.5,-0.2,0.46,0,0,0.1,0.5,-0.2,0.46,1,1,3\n";
  const std::string row2 = "2000000,2,0.5,-0.2,0.47,0,0,0,0.5,-0.2,0.47,0.5,0,0\n";
  std::vector<hr::Probe3Tick> out(1);
  out[0].t_s = 42;
  std::string error;
  // Good, with a cut-off last line (a killed writer) dropped.
  ASSERT_TRUE(hr::read_probe3_world_log(probe3_write(dir, "good.csv", head + row1 + row2 + "3000000,4,0.5"), &out,
                                        &error))
      << error;
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].t_s, 0.0);
  EXPECT_NEAR(out[1].t_s, 1e-3, 1e-12);
  EXPECT_EQ(out[0].goal_W, Eigen::Vector3d(0.5, -0.2, 0.46));
  EXPECT_EQ(out[0].force_W, Eigen::Vector3d(0, 0, 0.1));
  EXPECT_TRUE(out[0].exploring && out[0].contact && out[0].model);
  EXPECT_FALSE(out[1].exploring || out[1].contact || out[1].model);
  EXPECT_EQ(out[1].gain, 0.5);

  struct Case {
    std::string name, text, error;
  };
  const std::vector<Case> cases = {
      {"nocol.csv", "t_ns,mode,goal_x\n1,4,0\n", "nocol.csv: no column goal_y"},
      {"short.csv", head + row1 + "2000000,4,0.5\n" + row2, "short.csv:3: 3 fields, expected 14"},
      {"nan.csv", head + "1000000,4,0.5,-0.2,x,0,0,0.1,0.5,-0.2,0.46,1,1,3\n", "nan.csv:2: field 5 'x' is not a finite number"},
      {"inf.csv", head + row1 + "1000000,4,0.5,-0.2,inf,0,0,0.1,0.5,-0.2,0.46,1,1,3\n",
       "inf.csv:3: field 5 'inf' is not a finite number"},
  };
  for (const Case& c : cases) {
    std::vector<hr::Probe3Tick> keep(1);
    keep[0].t_s = 42;
    const std::string path = probe3_write(dir, c.name, c.text);
    EXPECT_FALSE(hr::read_probe3_world_log(path, &keep, &error)) << c.name;
    EXPECT_NE(error.find(c.error), std::string::npos) << error;
    ASSERT_EQ(keep.size(), 1u);
    EXPECT_EQ(keep[0].t_s, 42.0);
  }
  EXPECT_FALSE(hr::read_probe3_world_log(dir + "/none.csv", &out, &error));
  EXPECT_EQ(error, "cannot read " + dir + "/none.csv");
}
