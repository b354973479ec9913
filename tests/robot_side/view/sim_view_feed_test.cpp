// SIMULATION ONLY. The robot station's live view reads the simulation
// through SimulatedRobot::view_frame_sim and a SimViewFeed: the frame's state
// poses MuJoCo's own copy of the scene exactly (body positions agree), its
// contacts carry the true forces (standing still, the floor holds the robot's
// weight: sum of vertical contact forces = total mass * g), and the feed hands
// over the newest frame with the newest scan of each sensor, pacing frames.
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "common/sim/mujoco_owner.h"

#include <cmath>

#include "config_robot.pb.h"
#include "robot_side/sim/simulated_robot.h"
#include "robot_side/view/sim_view_feed.h"

namespace hr = hemm::robot;

namespace {

const std::string kScene = std::string(HEMM_SOURCE_DIR) + "/deploy/scenes/home.xml";

TEST(SimViewFrame, PosesTheSceneAndCarriesTheWeightInItsContacts) {
  hr::SimulatedRobot robot;
  ASSERT_FALSE(robot.load(hemm::config::RobotConfig(), kScene));
  robot.set_base_pose_sim(hr::Pose2{0.5, -0.3, 0.7});
  robot.step(1500);  // settle on the wheels, arm held
  hr::SimViewFrame f;
  robot.view_frame_sim(&f);
  EXPECT_EQ(f.t_ns, robot.time_ns());

  // MuJoCo's own copy of the scene, posed from the frame.
  const hemm::sim::MujocoOwner mj = hemm::sim::MujocoOwner::from_file(kScene);
  mjModel* m = mj.m();
  mjData* d = mj.d();
  ASSERT_EQ(f.qpos.size(), static_cast<std::size_t>(m->nq));
  std::copy(f.qpos.begin(), f.qpos.end(), d->qpos);
  mj_kinematics(m, d);
  const int base = mj_name2id(m, mjOBJ_BODY, "base_link");
  ASSERT_GE(base, 0);
  const hr::RobotStateSim st = robot.state();
  EXPECT_NEAR(d->xpos[3 * base], st.T_W_R_truth.x, 1e-9);
  EXPECT_NEAR(d->xpos[3 * base + 1], st.T_W_R_truth.y, 1e-9);

  // Standing still: the vertical contact forces on the robot sum to its weight.
  double fz = 0.0;
  int floor_contacts = 0;
  for (const hr::SimContact& c : f.contacts) {
    const bool floor1 = m->geom_type[c.geom1] == mjGEOM_PLANE, floor2 = m->geom_type[c.geom2] == mjGEOM_PLANE;
    ASSERT_TRUE(floor1 || floor2) << "a contact off the floor in free space";
    ++floor_contacts;
    fz += floor1 ? c.force_W.z() : -c.force_W.z();  // force_W acts on geom2
    EXPECT_NEAR(c.pos_W.z(), 0.0, 0.01);
  }
  const double weight = m->body_subtreemass[base] * -m->opt.gravity[2];
  EXPECT_GE(floor_contacts, 4);
  EXPECT_NEAR(fz, weight, 0.02 * weight) << "mass " << m->body_subtreemass[base];
}

hr::RangeScanData scan(const char* name, std::int64_t stamp) {
  hr::RangeScanData s;
  s.sensor_name = name;
  s.stamp_ns = stamp;
  s.ranges = {1.0f};
  s.valid = {1};
  return s;
}

TEST(SimViewFeed, NewestFrameWithNewestScansAndPacing) {
  hr::SimViewFeed feed(100);
  hr::SimViewFrame f, out;
  EXPECT_TRUE(feed.due(0));
  EXPECT_FALSE(feed.take(out));
  f.t_ns = 1000;
  f.qpos = {1, 2, 3};
  ASSERT_TRUE(feed.publish(f));
  EXPECT_FALSE(feed.due(1099));  // the next one an interval later
  EXPECT_TRUE(feed.due(1100));
  f.t_ns = 1100;
  f.qpos = {4, 5, 6};
  ASSERT_TRUE(feed.publish(f));
  feed.publish_scans({scan("laser", 10), scan("sonar", 20)});
  feed.publish_scans({scan("laser", 30)});
  feed.publish_scans({scan("sonar", 5)});  // older than the one kept
  ASSERT_TRUE(feed.take(out));
  EXPECT_EQ(out.t_ns, 1100);
  EXPECT_EQ(out.qpos, (std::vector<double>{4, 5, 6}));
  ASSERT_EQ(out.scans.size(), 2u);
  EXPECT_EQ(out.scans[0].stamp_ns, 30);
  EXPECT_EQ(out.scans[1].stamp_ns, 20);
  EXPECT_FALSE(feed.take(out));
  EXPECT_EQ(feed.frames(), 2u);
}

}  // namespace
