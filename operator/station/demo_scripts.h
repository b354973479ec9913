// Built-in SIMULATED operator hand scripts for the demo (hemm-operator
// --script NAME) and the tests. Positions are in the device frame H (x right,
// y up, z towards the user; forward = -z). They assume the task's default maps
// (exploration_range 4 m, navigation look-ahead 2 m: 50 and 25 world metres
// per device metre) and the robot at deploy/scenes/home.xml's robot_start
// (0, 0, heading 0).
//  - "idle": the hand holds the stylus at the centre; exploration mode.
//  - "nav-to-wall" (HEMM Fig. 8): navigation mode; the hand steers like
//    nav-to-goal for a point behind the wall wall_mid_n (nav_to_wall_target:
//    (4.5, 1.6); the path turns ~20 deg left and meets the wall's west face,
//    x = 2.95, near y = 1.05, 0.55 m from its doorway end) and keeps pushing
//    the stylus forward: the navigation proxy meets the wall, the force rises
//    and the command falls into the dead band, so the robot stops short of
//    the wall while the hand still pushes.
//  - "probe-cylinder": exploration mode, robot still; the probe goes to
//    (1.42, -0.8) in W and sweeps along x = 1.42 to y = -1.6 and back,
//    through the bin at (1.5, -1.2), r = 0.15, 8 cm off its centre line: the
//    proxy meets the bin's near (seen) face and slides round it.
// Where a script drives the robot (nav-to-wall, nav-to-goal) the hand presses
// the stylus's dead-man; "idle" and "probe-cylinder" (exploration) do not.
//  - "nav-to-goal": navigation mode, CLOSED LOOP: the hand watches the robot
//    pose the station shows (OperatorView) and steers the stylus so the
//    robot drives along a route of goals in W and stops at the last one
//    (NavGoalHand below). Default route: via (2.2, 0) to (2.45, -1.6): the
//    straight line from the start to (2.45, -1.6) passes 0.18 m from the bin's
//    centre, too close for the 0.50 x 0.49 m base; the via point keeps its
//    west side >= 0.4 m from the bin. At the goal the base's east side is
//    ~0.25 m from wall_mid_s (west face x = 2.95).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/math/workspace_maps.h"
#include "operator/device/hand_script.h"
#include "operator/station/explore_route.h"
#include "operator/station/operator_task.h"

namespace hemm::op {

// ------------------------------------------------------------ nav-to-goal
// How the simulated operator drives (a person with a learned feel for the
// navigation map, not a bang-bang controller): the speed wanted is
// proportional to the distance left (between v_min and v_cruise), cut while
// the heading error is large (turn first); the turn rate wanted is
// proportional to the heading error (capped). Wanted (v, omega) become stylus
// offsets through the inverse of the map's dead band / saturation
// (NavigationMap): forward = v, lateral = omega. Inside stop_distance of the
// last goal the stylus goes back to the centre (inside the dead band: the
// robot stops), aiming at half the tolerance so the robot still coasting on
// commands in flight (the link's delay) ends inside it; only beyond
// `tolerance` does the hand drive again (hysteresis: it corrects a drift but
// does not chatter). A last goal close behind the robot (< reverse_range) is
// reached backing up rather than turning round.
struct NavGoalParams {
  math::NavigationMap nav = math::make_navigation_map(math::DeviceWorkspace{}, 2.0);
  double stop_distance = 0.05;    // m: arrived (stylus centred) inside this
  double tolerance = 0.10;        // m: once arrived, drive again only beyond this
  double pass_radius = 0.30;      // m: an intermediate goal is passed inside this
  double k_distance = 0.5;        // 1/s: wanted speed per metre left
  double v_min = 0.05;            // m/s: no creeping on the last centimetres
  double v_cruise = 0.35;         // m/s
  double k_heading = 0.8;         // 1/s: wanted turn rate per radian of heading error
  double omega_cruise = 0.6;      // rad/s
  double turn_in_place = 1.0;     // rad: no forward push at a larger heading error
  double reverse_range = 0.5;     // m
  double max_offset = 0.030;      // m of stylus travel per axis (the Omni's box: +-35 mm deep)
  double hand_speed = 0.05;       // m/s: how fast the hand moves the stylus (rate limit)
  double rearm_release_s = 0.2;   // s the dead-man is let go to re-arm the robot
  double rearm_retry_s = 1.0;     // s between two such re-arms
};
// Empty if usable, else what is wrong.
std::string validate(const NavGoalParams& p);

struct NavHandTarget {
  Eigen::Vector3d position_H = Eigen::Vector3d::Zero();  // where the hand wants the stylus
  bool arrived = false;          // at the (last) goal: stylus centred
  double distance = -1.0;        // m, robot to goal; -1: nothing to go by (view invalid, non-finite input)
  double heading_error = 0.0;    // rad, of the driving direction (the back when reversing)
};

// The simulated operator's decision for one glance at the display: where to
// hold the stylus so the robot drives to goal_W. final_goal: stop there
// (else just drive through); was_arrived: the previous decision's `arrived`
// (hysteresis). Invalid view, a view not in navigation mode, or non-finite
// input: centre. Pure, allocation-free; the result stays within
// +-max_offset on the two horizontal axes (y_H = 0).
NavHandTarget hand_target_for_goal(const OperatorView& view, const Eigen::Vector2d& goal_W,
                                   const NavGoalParams& p, bool final_goal = true,
                                   bool was_arrived = false) noexcept;

// The closed-loop hand: at(t) takes the task's OperatorView, moves along the
// route (intermediate goals are passed inside pass_radius; never while the
// view is invalid, e.g. the model is stale) and rate-limits the stylus
// target to hand_speed. When the robot restarted (view.resyncs changed) the
// route starts again from its first goal. The hand holds the dead-man
// pressed; when the display shows the robot waiting to be re-armed
// (SAFETY_REARM: after an e-stop, a lost link, an expired watchdog) it lets
// go for rearm_release_s and presses again, at most once per rearm_retry_s,
// as a person would. at() keeps its state in mutable members: it is
// called only on the thread the SIMULATED Omni's hardware runs on (the servo
// thread in lock-step, right after the tick that wrote the view; its own
// thread when threaded, where the station hands it the newest view through a
// mailbox: operator_station.cpp), and once by SimulatedOmni's constructor
// before either starts. The accessors are for that thread or after it
// stopped. Throws std::invalid_argument on an empty route, a non-finite goal,
// bad params or a null view.
class NavGoalHand final : public device::HandScript {
 public:
  NavGoalHand(std::shared_ptr<const OperatorView> view, std::vector<Eigen::Vector2d> route_W,
              const NavGoalParams& p = {});
  device::HandTarget at(double t_s) const noexcept override;

  const std::vector<Eigen::Vector2d>& route() const { return route_; }
  const NavGoalParams& params() const { return p_; }
  std::size_t goal_index() const { return index_; }  // the goal driven to now
  bool arrived() const { return arrived_; }
  double first_arrival_s() const { return first_arrival_s_; }  // device time; -1: never
  std::uint64_t arrivals() const { return arrivals_; }          // > 1: it had to correct
  double last_distance() const { return last_.distance; }

 private:
  std::shared_ptr<const OperatorView> view_;
  std::vector<Eigen::Vector2d> route_;
  NavGoalParams p_;
  // Servo-thread state (see the class comment).
  mutable std::size_t index_ = 0;
  mutable bool arrived_ = false;
  mutable double first_arrival_s_ = -1.0;
  mutable std::uint64_t arrivals_ = 0;
  mutable double t_prev_ = 0.0;
  mutable bool started_ = false;
  mutable Eigen::Vector3d position_H_ = Eigen::Vector3d::Zero();
  mutable NavHandTarget last_;
  mutable std::uint64_t resyncs_seen_ = 0;
  mutable double release_until_s_ = -1.0, next_rearm_s_ = 0.0;
};

// The default route of "nav-to-goal" (see the file comment).
std::vector<Eigen::Vector2d> default_nav_goal_route();
// The point "nav-to-wall" steers for, behind the wall (see the file comment).
Eigen::Vector2d nav_to_wall_target();

// ------------------------------------------------------------ scripts
struct DemoScript {
  std::shared_ptr<const device::HandScript> hand;
  math::Mode mode = math::Mode::kExploration;
  double duration_s = 0.0;  // natural length of the script (0: none)
  // Closed-loop scripts only: the view the task must write (pass it to
  // OperatorServoTask) and the nav-to-goal hand (for its arrival state).
  std::shared_ptr<OperatorView> view;
  std::shared_ptr<const NavGoalHand> nav_goal;
};

// Targets from the scene's config or the command line (the defaults are
// home.xml's, see the file comment): other scenes name their own.
struct DemoScriptOptions {
  // nav-to-goal: the route (empty = default_nav_goal_route()); nav-to-wall:
  // one point behind the wall to steer for (empty = nav_to_wall_target()).
  std::vector<Eigen::Vector2d> route_W;
  // probe-cylinder: the line in W the probe sweeps out and back along (it
  // should pass a few cm off the object's centre, so the proxy meets its
  // seen face and slides round it). Empty = default_probe_line().
  std::vector<Eigen::Vector2d> probe_line_W;
};
// The default probe line of "probe-cylinder": (1.42, -0.8) -> (1.42, -1.6).
std::vector<Eigen::Vector2d> default_probe_line();

// Null hand if the name is unknown. Throws std::invalid_argument on a bad
// route (non-finite goal), a route for a script that takes none, or a probe
// line that is not two finite points within the exploration range (4 m) of
// the robot's start.
DemoScript make_demo_script(std::string_view name, const DemoScriptOptions& o = {});
std::vector<std::string> demo_script_names();

// ------------------------------------------------------------ hand3 routes
// The SIMULATED Omni's hand following an explore3 route of a scene file's
// header (explore_route.h; hemm-operator --hand3-route FILE --hand3-script
// NAME): the stylus target at each key is the key's device point in H
// through the task's 3-DoF probe map (probe3d_map_of: probe_3d's range and
// origin), linear between keys, exploration mode, no dead-man. The Omni's
// SIMULATED grip (simulated_omni.h) pulls the stylus towards the target and
// yields to the force, so the logged device point is the path the truth
// replays, not the route itself.
math::ScaledMap probe3d_map_of(const OperatorTaskParams& p);
std::shared_ptr<const device::WaypointScript> make_hand3_script(const ExploreRoute3& r, const math::Pose2& start_W,
                                                                const math::ScaledMap& m);
// Loads the route (errors "probe_3d.hand3_script: FILE:LINE: reason", the
// route missing, or out of the Omni's reach: std::invalid_argument); the
// task must run the 3-DoF point probe (probe_3d enabled, tool "point").
std::shared_ptr<const device::WaypointScript> load_hand3_route(const std::string& scene_path, const std::string& name,
                                                               const OperatorTaskParams& task);

}  // namespace hemm::op
