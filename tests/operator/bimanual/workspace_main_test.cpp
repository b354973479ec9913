// hemm-bimanual-workspace through the real binary: --help, bad arguments are
// usage errors (exit 2), and on a coarse grid every point an arm reaches
// lies within that arm's reach of its shoulder (upper arm + forearm +
// flange, from the arm model's joint offsets, not from the IK), points out
// of reach of both get index 0, and each arm reaches a good part of the
// orientations somewhere.
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "common/kinematics/arm7.h"
#include "operator/device/bimanual/rig.h"
#include "tests/integration/link/child_process.h"

namespace hb = hemm::device::bimanual;
namespace hk = hemm::kinematics;

namespace {

const std::string kTool = std::string(HEMM_BINARY_DIR) + "/bin/hemm-bimanual-workspace";

hemm::test::ProcessResult run(const std::string& dir, std::vector<std::string> args) {
  args.insert(args.begin(), kTool);
  return hemm::test::run_to_completion(std::move(args), dir, std::chrono::seconds(60));
}

}  // namespace

TEST(BimanualWorkspace, HelpAndBadArguments) {
  const std::string d = hemm::test::make_temp_dir();
  EXPECT_EQ(run(d, {"--help"}).rc, 0);
  EXPECT_EQ(run(d, {}).rc, 2);  // --out is required
  EXPECT_EQ(run(d, {"-o", d + "/w.csv", "--step", "0"}).rc, 2);
  EXPECT_EQ(run(d, {"-o", d + "/w.csv", "--orientations", "nan"}).rc, 2);
  const auto r = run(d, {"-o", d + "/w.csv", "--x", "0.5"});
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--x"), std::string::npos) << r.err;
}

TEST(BimanualWorkspace, ReachedPointsLieWithinTheArmsReach) {
  const std::string d = hemm::test::make_temp_dir();
  const auto r = run(d, {"-o", d + "/w.csv", "--step", "0.4", "--orientations", "5"});
  ASSERT_EQ(r.rc, 0) << r.err;
  const hb::RigGeometry rig = hb::default_rig();
  hk::Arm7Frames f;
  hk::forward_kinematics(rig.arm, hk::Arm7Vector::Zero(), f);
  // Shoulder (J2, on joint 1's axis: independent of q) to flange (J7), stretched.
  double reach = 0.0;
  for (int i = 3; i <= 7; ++i) reach += rig.arm.offset[static_cast<std::size_t>(i - 1)].norm();
  std::istringstream in(hemm::test::read_file(d + "/w.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "section,x,y,z,right,left");
  int rows = 0, sections = 0;
  double best[2] = {0, 0};
  std::string last;
  while (std::getline(in, line)) {
    std::istringstream l(line);
    std::string section, cell;
    std::getline(l, section, ',');
    double v[5];
    for (double& x : v) {
      std::getline(l, cell, ',');
      x = std::stod(cell);
    }
    if (section != last) ++sections, last = section;
    ++rows;
    const Eigen::Vector3d p(v[0], v[1], v[2]);
    EXPECT_GT(p.z(), 0.0);  // nothing inside the table
    for (int a = 0; a < 2; ++a) {
      const double idx = v[3 + a];
      ASSERT_GE(idx, 0.0);
      ASSERT_LE(idx, 1.0);
      best[a] = std::max(best[a], idx);
      const Eigen::Vector3d shoulder_D = rig.T_D_A[static_cast<std::size_t>(a)] * f.origin(2);
      if (idx > 0.0) {
        EXPECT_LE((p - shoulder_D).norm(), reach + 1e-6) << line;
      }
    }
  }
  EXPECT_EQ(sections, 2);
  EXPECT_GT(rows, 20);
  EXPECT_GT(best[0], 0.5);
  EXPECT_GT(best[1], 0.5);
}
