#include "common/view/view_loop.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <thread>

#include <spdlog/spdlog.h>

#include "common/clock/steady_clock.h"

namespace hemm::view {


namespace {

void run_view_loop(MujocoWindow& win, const ViewOptions& o, std::optional<PngSequence>& pngs,
                   const std::atomic<bool>& stop, const ViewLoopHooks& hooks, ViewLoopCounters& counters) {
  Image image;
  const auto frame_ns = static_cast<std::int64_t>(1e9 / o.fps);
  std::int64_t next_frame = steady_now_ns();
  bool window_open = o.window;
  auto write = [&](bool last, std::int64_t now) {
    const auto e =
        last ? pngs->write_last(image, hooks.text(win, now)) : pngs->write(image, hooks.text(win, now), now);
    if (e) {
      // The first failure is enough to report: a full disk fails every time.
      if (counters.png_errors.fetch_add(1) == 0 && hooks.on_png_error) hooks.on_png_error(*e);
    } else {
      counters.pngs.fetch_add(1, std::memory_order_relaxed);
    }
  };
  while (!stop.load(std::memory_order_relaxed)) {
    const std::int64_t now = steady_now_ns();
    if (window_open) {
      win.poll();
      for (int key : win.take_keys())
        if (hooks.on_key) hooks.on_key(win, key);
      if (win.close_requested()) {
        window_open = false;
        if (!pngs) break;
      }
    }
    const bool png_due = pngs && pngs->due(now);
    if ((window_open && now >= next_frame) || png_due) {
      hooks.draw(win, now, png_due ? &image : nullptr);
      counters.frames.fetch_add(1, std::memory_order_relaxed);
      if (png_due) write(false, now);
      next_frame += frame_ns;
      if (next_frame <= now) next_frame = now + frame_ns;
    }
    // Wake for the next frame or picture, at least every 50 ms (stop, keys).
    std::int64_t wake = now + 50'000'000;
    if (window_open) wake = std::min(wake, next_frame);
    if (pngs) wake = std::min(wake, pngs->next_due_ns());
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(wake)));
  }
  if (pngs) {
    const std::int64_t now = steady_now_ns();
    hooks.draw(win, now, &image);
    counters.frames.fetch_add(1, std::memory_order_relaxed);
    write(true, now);
  }
}

}  // namespace

void set_logging_hooks(const ViewOptions& o, ViewLoopHooks& hooks) {
  hooks.on_start = [window = o.window, dir = o.png_dir](MujocoWindow& win) {
    spdlog::info("event=view_started window={} png_dir=\"{}\" renderer=\"{}\"", window, dir, win.gl_renderer());
  };
  hooks.on_png_error = [](const std::string& e) { spdlog::warn("event=view_png_failed error=\"{}\"", e); };
}

void run_live_view(mjModel_* m, mjData_* d, const ViewOptions& o, const std::string& title,
                   const CameraSpec& default_camera, const std::atomic<bool>& stop, const ViewLoopHooks& hooks,
                   ViewLoopCounters& counters) {
  WindowOptions wo;
  wo.visible = o.window;
  wo.width = o.width;
  wo.height = o.height;
  wo.title = title;
  MujocoWindow win(m, d, wo);
  std::optional<PngSequence> pngs;
  if (!o.png_dir.empty()) pngs.emplace(o.png_dir, static_cast<std::int64_t>(o.png_interval_s * 1e9));
  win.set_camera(o.top ? *o.top : default_camera);
  if (hooks.on_start) hooks.on_start(win);
  run_view_loop(win, o, pngs, stop, hooks, counters);
}

std::int64_t station_feed_interval_ns(const ViewOptions& o) {
  return static_cast<std::int64_t>(1e9 / (o.window ? o.fps : std::max(1.0, 4.0 / o.png_interval_s)));
}

void ViewThread::start_logged(std::function<void(const std::atomic<bool>& stop)> body) {
  start(std::move(body), [](const std::string& e) { spdlog::error("event=view_failed error=\"{}\"", e); });
}

void ViewThread::start(std::function<void(const std::atomic<bool>& stop)> body,
                       std::function<void(const std::string& error)> on_error) {
  if (thread_.joinable()) throw std::logic_error("ViewThread already running");
  stop_.store(false);
  thread_ = std::thread([this, body = std::move(body), on_error = std::move(on_error)] {
    lower_this_thread_priority();  // best effort: refused, the view still runs
    try {
      body(stop_);
    } catch (const std::exception& e) {
      {
        std::lock_guard<std::mutex> lk(mu_);
        error_ = e.what();
      }
      if (on_error) on_error(e.what());
    }
  });
}

void ViewThread::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
}

std::string ViewThread::error() const {
  std::lock_guard<std::mutex> lk(mu_);
  return error_;
}

CameraMode initial_camera_mode(const ViewOptions& o) { return o.top ? CameraMode::kFree : CameraMode::kFollow; }

CameraMode next_camera_mode(CameraMode m) {
  switch (m) {
    case CameraMode::kFollow: return CameraMode::kFree;
    case CameraMode::kFree: return CameraMode::kTop;
    case CameraMode::kTop: return CameraMode::kFollow;
  }
  return CameraMode::kFollow;
}

void aim_camera(MujocoWindow& win, CameraMode m, const Eigen::Vector3d& target) {
  if (m == CameraMode::kTop) {
    win.set_camera(top_down_camera(target.x(), target.y(), win.camera().distance));
  } else if (m == CameraMode::kFollow) {
    win.set_lookat(target);
  }
}

}  // namespace hemm::view
