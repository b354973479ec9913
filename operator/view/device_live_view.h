// The live view of hemm-operator's device-only runs (a `vps` block: the VPS
// scene with the rigid scripted hands, the Omni or the SIMULATED bimanual
// device; or the SIMULATED bimanual device against its local planes): its own
// thread, at a lowered CPU priority, renders device_scene.h's picture with
// MuJoCo in a GLFW window at --view-fps, or offscreen every --view-interval
// for PNGs, from the servo task's per-tick record (device_view_record.h: one
// copy and one atomic exchange per tick on the servo thread) and the servo
// loop's timing atomics. Key c puts the camera back where it started; the
// mouse moves it as in MuJoCo's viewer.
//
// If the view cannot start (no display, no OpenGL) it logs why and ends;
// the run goes on without it.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "common/view/view_loop.h"
#include "common/view/view_options.h"
#include "operator/servo/timing_stats.h"
#include "operator/view/device_scene.h"
#include "operator/view/device_view_record.h"
#include "operator/view/live_view.h"

namespace hemm::op {

class DeviceLiveView {
 public:
  // Throws std::invalid_argument if o asks for neither a window nor PNGs.
  DeviceLiveView(const view::ViewOptions& o, DeviceSceneSetup setup);
  ~DeviceLiveView();
  DeviceLiveView(const DeviceLiveView&) = delete;
  DeviceLiveView& operator=(const DeviceLiveView&) = delete;

  // The servo task publishes here (set_view of the VPS or bimanual task).
  DeviceViewMailbox& ticks() noexcept { return ticks_; }
  // Starts the thread; `servo` (may be null) must outlive stop().
  void start(const servo::TimingStats* servo);
  // Joins the thread, after a last picture (view_last.png) when writing PNGs.
  void stop();
  LiveViewStats stats() const;

 private:
  void run(const std::atomic<bool>& stop);

  view::ViewOptions o_;
  DeviceSceneSetup setup_;
  const servo::TimingStats* servo_ = nullptr;
  DeviceViewMailbox ticks_;
  view::ViewLoopCounters counters_;
  std::atomic<std::uint64_t> dropped_{0};
  view::ViewThread thread_;  // last: joined first
};

}  // namespace hemm::op
