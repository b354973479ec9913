// SIMULATION ONLY. The robot station's live view (hemm-robot --view /
// --view-png): the simulation's own MuJoCo scene posed from the state the
// simulation thread hands over (sim_view_feed.h), with the range sensors'
// rays from their true pose at acquisition (laser red where it hit, sonar
// beams green), the true contacts (points, force arrows: robot against the
// world red, the wheels on the floor grey), and text (simulation time, true
// and odometry pose, safety flags, link). Its own thread, lowered priority,
// loads its own copy of the scene; the simulation thread only copies.
// Keys: c cycles the camera (follow the robot / free / top-down); mouse as in
// MuJoCo's viewer.
#pragma once

#include <atomic>
#include <memory>
#include <string>

#include "common/view/view_loop.h"
#include "common/view/view_options.h"
#include "robot_side/view/sim_view_feed.h"

namespace hemm::robot {

class RobotLiveView {
 public:
  // scene_path: the MJCF the simulation loaded. Makes the feed (attach it to
  // the station with RobotStation::attach_view before start()).
  RobotLiveView(const view::ViewOptions& o, std::string scene_path);
  ~RobotLiveView();
  RobotLiveView(const RobotLiveView&) = delete;
  RobotLiveView& operator=(const RobotLiveView&) = delete;

  std::shared_ptr<SimViewFeed> feed() const { return feed_; }
  void start();
  void stop();  // joins, after a last picture when writing PNGs
  std::uint64_t frames() const { return counters_.frames.load(); }
  std::uint64_t pngs() const { return counters_.pngs.load(); }
  std::string error() const { return thread_.error(); }

 private:
  void run(const std::atomic<bool>& stop);

  view::ViewOptions o_;
  std::string scene_path_;
  std::shared_ptr<SimViewFeed> feed_;
  view::ViewLoopCounters counters_;
  view::ViewThread thread_;  // last: joined first
};

}  // namespace hemm::robot
