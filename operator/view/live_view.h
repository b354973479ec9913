// The operator station's live view (hemm-operator --view / --view-png): its
// own thread renders operator_scene.h's picture with MuJoCo in a GLFW window
// at --view-fps, or offscreen every --view-interval for PNGs, from the
// ViewFeed the station fills (view_feed.h: it never delays the servo thread).
// The thread runs at a lowered CPU priority. Keys: m switches the mode (a
// button-1 press), e requests the e-stop, c cycles the camera (follow the
// robot / free / top-down over the robot); the mouse moves the camera as in
// MuJoCo's viewer.
//
// If the view cannot start (no display, no OpenGL) it logs why and ends;
// the station runs on without it.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include <asio.hpp>

#include "common/net/link_stats.h"
#include "common/view/view_loop.h"
#include "common/view/view_options.h"
#include "operator/station/operator_station.h"
#include "operator/view/view_feed.h"

namespace hemm::op {

struct LiveViewLinks {
  std::function<net::LinkStatistics()> link_stats;  // any thread (OperatorClient::statistics)
  std::function<void()> estop;                      // the e-stop key; called on the view thread
};

// The links of a running hemm-operator: statistics from the client; the
// e-stop key engages the robot's e-stop through the station
// (OperatorStation::request_estop on the network thread, io's: an EStop with
// a request id whose Ack is logged). The robot engages it for any
// authenticated session.
LiveViewLinks station_view_links(OperatorClient& client, OperatorStation& station, asio::io_context& io);

struct LiveViewStats {
  std::uint64_t frames = 0;
  std::uint64_t pngs = 0;
  std::uint64_t model_copies = 0;
  std::uint64_t dropped_geoms = 0;
  std::string error;  // why the view stopped early, if it did
};

// What both operator views share about their thread: started with an error
// log for what ends it, and its counters as LiveViewStats.
void start_view_thread(view::ViewThread& thread, std::function<void(const std::atomic<bool>& stop)> body);
LiveViewStats live_view_stats(const view::ViewLoopCounters& c, std::uint64_t dropped_geoms,
                              const view::ViewThread& thread);

class OperatorLiveView {
 public:
  // Attaches the view's feed to the station: call before station.start().
  OperatorLiveView(const view::ViewOptions& o, OperatorStation& station, LiveViewLinks links);
  // Without a station (a replayed session): the caller fills feed(); no
  // servo loop's health is shown, and ages are taken at the newest tick's time.
  OperatorLiveView(const view::ViewOptions& o, LiveViewLinks links);
  ~OperatorLiveView();
  OperatorLiveView(const OperatorLiveView&) = delete;
  OperatorLiveView& operator=(const OperatorLiveView&) = delete;

  void start();
  // Joins the thread, after a last picture (view_last.png) when writing PNGs.
  void stop();
  LiveViewStats stats() const;
  ViewFeed& feed() noexcept { return feed_; }

 private:
  void run(const std::atomic<bool>& stop);

  view::ViewOptions o_;
  const servo::TimingStats* servo_stats_ = nullptr;  // the station's servo loop, if any
  LiveViewLinks links_;
  ViewFeed feed_;
  view::ViewLoopCounters counters_;
  std::atomic<std::uint64_t> dropped_{0};
  view::ViewThread thread_;  // last: joined first
};

}  // namespace hemm::op
