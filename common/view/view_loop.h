// The frame loop both live views run on their own thread: window events and
// keys, a frame every 1/fps while a window is open, a PNG every interval
// (rendered then, also without a window), sleeping in between; at the end a
// last picture (view_last.png) of the final state. Runs on the caller's
// thread (the view's); owns nothing but its pacing.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "common/clock/steady_clock.h"
#include "common/view/mujoco_window.h"
#include "common/view/png_sequence.h"
#include "common/view/view_options.h"

namespace hemm::view {

struct ViewLoopHooks {
  std::function<void(MujocoWindow&)> on_start;                                 // the window is up
  std::function<void(const std::string& error)> on_png_error;                   // the first failure only
  std::function<void(MujocoWindow&, int key)> on_key;                          // keys of take_keys
  std::function<void(MujocoWindow&, std::int64_t now_ns, Image* capture)> draw;  // one frame (capture may be null)
  std::function<TextChunks(MujocoWindow&, std::int64_t now_ns)> text;          // a PNG's text chunks
};

// The stations' usual on_start / on_png_error: log the view's start (window,
// PNG directory, OpenGL renderer) and the first PNG failure.
void set_logging_hooks(const ViewOptions& o, ViewLoopHooks& hooks);

struct ViewLoopCounters {
  std::atomic<std::uint64_t> frames{0}, pngs{0}, png_errors{0};
};

// A live view from start to end on the calling thread: opens the window over
// (m, d) (hidden when o asks only for PNGs), the PNG sequence, points the
// camera (o.top, else default_camera), then the loop until `stop` (or the
// window is closed and no PNGs are asked for). Throws std::runtime_error if
// the window or the PNG directory cannot be opened.
void run_live_view(mjModel_* m, mjData_* d, const ViewOptions& o, const std::string& title,
                   const CameraSpec& default_camera, const std::atomic<bool>& stop, const ViewLoopHooks& hooks,
                   ViewLoopCounters& counters);

// The views' cameras: following a target (the robot) from the user's angle
// and distance, free (only the mouse moves it), or straight down over it.
enum class CameraMode { kFollow, kFree, kTop };
CameraMode initial_camera_mode(const ViewOptions& o);  // free with --view-top, else follow
CameraMode next_camera_mode(CameraMode m);             // the c key
void aim_camera(MujocoWindow& win, CameraMode m, const Eigen::Vector3d& target);

using hemm::steady_now_ns;

// How often a station's simulation thread hands its view a frame (robot
// time): at the window's rate, or a few per PNG interval without a window.
std::int64_t station_feed_interval_ns(const ViewOptions& o);

// The thread a station's live view runs on (operator/view, robot_side/view
// start and stop it; this library starts none by itself). The body runs at
// a lowered priority (nice 10); what it throws ends the view: error() keeps
// the message and on_error hears it (on the view's thread).
class ViewThread {
 public:
  ViewThread() = default;
  ~ViewThread() { stop(); }
  ViewThread(const ViewThread&) = delete;
  ViewThread& operator=(const ViewThread&) = delete;

  // Throws std::logic_error if running.
  void start(std::function<void(const std::atomic<bool>& stop)> body,
             std::function<void(const std::string& error)> on_error);
  void stop();  // asks the body to stop and joins; idempotent
  std::string error() const;
  // start() with the stations' error report (logged as event=view_failed).
  void start_logged(std::function<void(const std::atomic<bool>& stop)> body);

 private:
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;
  std::string error_;
  std::thread thread_;
};

}  // namespace hemm::view
