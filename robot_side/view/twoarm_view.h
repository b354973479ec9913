// SIMULATION ONLY. The two-arm station's live view (hemm-robot kind twoarm
// --view / --view-png): the workbench's own MuJoCo scene posed from the
// control thread's frames (twoarm_view_feed.h; the arms, grippers and the
// task objects where the simulation has them), with twoarm_scene.h's
// targets, wrist wrenches, contacts and text. Its own thread, lowered
// priority, its own copy of the scene (the arms' geoms, in geom group 3 for
// the depth camera's sake, moved to group 0 there so MuJoCo draws them).
// Keys: c cycles the camera (follow the grasp frames' midpoint / free / top).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "common/view/view_loop.h"
#include "common/view/view_options.h"
#include "robot_side/view/twoarm_view_feed.h"

namespace hemm::robot {

class TwoArmLiveView {
 public:
  // scene_path: the MJCF the station loaded. Throws std::invalid_argument if
  // o asks for neither a window nor PNGs.
  TwoArmLiveView(const view::ViewOptions& o, std::string scene_path);
  ~TwoArmLiveView();
  TwoArmLiveView(const TwoArmLiveView&) = delete;
  TwoArmLiveView& operator=(const TwoArmLiveView&) = delete;

  // Attach to the station (TwoArmStation::attach_view) before its start().
  std::shared_ptr<TwoArmViewFeed> feed() const { return feed_; }
  void start();
  void stop();  // joins, after a last picture when writing PNGs
  std::uint64_t frames() const { return counters_.frames.load(); }
  std::uint64_t pngs() const { return counters_.pngs.load(); }
  std::string error() const { return thread_.error(); }

 private:
  void run(const std::atomic<bool>& stop);

  view::ViewOptions o_;
  std::string scene_path_;
  std::shared_ptr<TwoArmViewFeed> feed_;
  view::ViewLoopCounters counters_;
  view::ViewThread thread_;  // last: joined first
};

}  // namespace hemm::robot
