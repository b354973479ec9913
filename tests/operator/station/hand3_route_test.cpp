// The SIMULATED Omni's hand on an explore3 route (demo_scripts.h
// load_hand3_route), in simulated time: with no force on the stylus, the
// device point the task maps into W (R_B_H, the probe's map, the robot at
// explore-start) follows each table scene's route: within 1 mm of every held
// key at the hold's end, and within the grip's lag of the route's
// piecewise-linear path on the way; a route out of the Omni's reach, or one
// for a task without the point probe, is refused with the reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "operator/device/simulated_omni.h"
#include "operator/station/demo_scripts.h"
#include "operator/station/explore_route.h"
#include "operator/station/operator_task.h"

namespace ho = hemm::op;

namespace {

// The point probe as deploy/configs/operator_explore3d_omni.pbtxt sets it.
ho::OperatorTaskParams hand3_task(double origin_x) {
  ho::OperatorTaskParams p;
  p.probe_3d = true;
  p.probe3d_range = 0.6;
  p.probe3d_origin_R = Eigen::Vector3d(origin_x, 0.0, 0.85);
  return p;
}

// The route's point at t (linear between keys, held after the last).
Eigen::Vector3d hand3_route_at(const ho::ExploreRoute3& r, double t) {
  if (t >= r.keys.back().t_s) return r.keys.back().p_W;
  std::size_t i = 1;
  while (r.keys[i].t_s < t) ++i;
  const ho::Route3Key &a = r.keys[i - 1], &b = r.keys[i];
  return a.p_W + (t - a.t_s) / (b.t_s - a.t_s) * (b.p_W - a.p_W);
}

}  // namespace

TEST(Hand3Route, TheSimulatedOmniFollowsEachTableScenesRouteInSimulatedTime) {
  const ho::OperatorTaskParams task = hand3_task(0.95);
  const hemm::math::ScaledMap m = ho::probe3d_map_of(task);
  const Eigen::Matrix3d R = ho::R_B_H();
  for (const char* scene : {"home", "table_round", "table_mixed"}) {
    const std::string path = std::string(HEMM_SOURCE_DIR "/deploy/scenes/") + scene + ".xml";
    ho::SceneExploration x;
    ASSERT_EQ(ho::load_scene_exploration(path, &x), std::nullopt) << scene;
    const ho::ExploreRoute3* r = x.find3("explore-table");
    ASSERT_NE(r, nullptr) << scene;
    const auto hand = ho::load_hand3_route(path, "explore-table", task);
    hemm::device::SimulatedOmniModel om;
    hemm::device::SimulatedOmniData d;
    d.position_H = hand->at(0.0).position_H;
    double worst_lag = 0.0;
    std::size_t held = 0;
    const double end = r->keys.back().t_s;
    std::size_t next_key = 1;
    while (d.t_s < end + 1.0) {
      hemm::device::simulated_omni_step(om, d, hand->at(d.t_s), Eigen::Vector3d::Zero());
      const Eigen::Vector3d p_W = hemm::math::anchored_point_W(m, {}, x.start_W, R * d.position_H);
      worst_lag = std::max(worst_lag, (p_W - hand3_route_at(*r, d.t_s)).norm());
      // A held key (the next one at the same point, >= 0.5 s later): reached by the hold's end.
      while (next_key < r->keys.size() && r->keys[next_key].t_s <= d.t_s + 1e-9) {
        const ho::Route3Key &a = r->keys[next_key - 1], &b = r->keys[next_key];
        if (a.p_W == b.p_W && b.t_s - a.t_s >= 0.5) {
          EXPECT_LT((p_W - b.p_W).norm(), 1e-3) << scene << " key at t = " << b.t_s << " s (line " << b.line << ")";
          ++held;
        }
        ++next_key;
      }
    }
    EXPECT_EQ(next_key, r->keys.size()) << scene;
    EXPECT_GE(held, 3u) << scene;
    // The grip (a spring-damper on the stylus) trails a target moving at v by
    // (b_hand + b_device) / k_hand v once the ramp settles; the route's
    // fastest segment sets the bound, with half again for the start of each
    // ramp (the damped overshoot).
    double v_max = 0.0;
    for (std::size_t i = 1; i < r->keys.size(); ++i)
      v_max = std::max(v_max, (r->keys[i].p_W - r->keys[i - 1].p_W).norm() / (r->keys[i].t_s - r->keys[i - 1].t_s));
    const double ramp_lag = (om.hand_damping + om.device_damping) / om.hand_stiffness * v_max;
    EXPECT_GT(v_max, 0.05) << scene;
    EXPECT_LT(worst_lag, 1.5 * ramp_lag) << scene << ": fastest segment " << v_max << " m/s";
  }
}

TEST(Hand3Route, ARouteOutOfReachOrWithoutThePointProbeIsRefused) {
  const std::string home = HEMM_SOURCE_DIR "/deploy/scenes/home.xml";
  // probe_3d's default origin (R x 0.9): the mug's top at R x 1.20 is 0.30 m
  // ahead of it, beyond the Omni's 35 mm of depth at 7.5 W m per device m.
  try {
    (void)ho::load_hand3_route(home, "explore-table", hand3_task(0.9));
    ADD_FAILURE() << "a route out of reach was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("explore3 explore-table at t = 48.5 s: the point"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("out of the Omni's reach"), std::string::npos) << e.what();
  }
  ho::OperatorTaskParams no_probe = hand3_task(0.95);
  no_probe.probe_3d = false;
  EXPECT_THROW((void)ho::load_hand3_route(home, "explore-table", no_probe), std::invalid_argument);
  try {
    (void)ho::load_hand3_route(home, "explore-moon", hand3_task(0.95));
    ADD_FAILURE() << "an unknown route was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("(its explore3 routes: explore-table)"), std::string::npos) << e.what();
  }
}
