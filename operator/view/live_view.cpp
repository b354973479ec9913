#include "operator/view/live_view.h"

#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cinttypes>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "common/view/mujoco_window.h"
#include "common/view/png_sequence.h"
#include "common/net/station_cli.h"
#include "common/view/view_loop.h"
#include "operator/device/haptic_device.h"
#include "operator/view/operator_scene.h"

namespace hemm::op {
namespace {

// The view's MuJoCo world: a floor with a 0.5 m grid and a light from above;
// everything the station knows is drawn into it as primitives. The explicit
// extent sets the clip planes (0.1 m .. 500 m) for a world with no bodies.
constexpr const char* kStationWorldXml = R"(<mujoco model="hemm_operator_view">
  <statistic extent="10" center="0 0 0"/>
  <visual>
    <global fovy="45"/>
    <headlight ambient="0.45 0.45 0.45" diffuse="0.45 0.45 0.45" specular="0 0 0"/>
  </visual>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.24 0.24 0.26" rgb2="0.2 0.2 0.22"
             width="64" height="64"/>
    <material name="grid" texture="grid" texrepeat="1 1" texuniform="true" specular="0"/>
  </asset>
  <worldbody>
    <light pos="0 0 10" dir="0 0 -1" directional="true" diffuse="0.3 0.3 0.3" specular="0 0 0" castshadow="false"/>
    <geom name="floor" type="plane" size="0 0 0.05" material="grid"/>
  </worldbody>
</mujoco>
)";

view::MjModelPtr load_world() { return sim::load_model_xml("operator_view.xml", kStationWorldXml); }

}  // namespace

LiveViewLinks station_view_links(OperatorClient& client, OperatorStation& station, asio::io_context& io) {
  LiveViewLinks l;
  l.link_stats = [&client] { return client.statistics(); };
  // One more place to press the e-stop, through the station like the others
  // (a request id, the robot's Ack awaited and logged).
  l.estop = [&station, &io] {
    spdlog::warn("event=estop_requested source=view");
    asio::post(io, [&station] {
      station.request_estop(true, "view key", [](const std::string& reply) {
        spdlog::warn("event=estop_reply via=view reply=\"{}\"", net::printable_text(reply));
      });
    });
  };
  return l;
}

OperatorLiveView::OperatorLiveView(const view::ViewOptions& o, OperatorStation& station, LiveViewLinks links)
    : OperatorLiveView(o, std::move(links)) {
  servo_stats_ = &station.servo_stats();
  station.attach_view([this](const OperatorModelSnapshot& s) { feed_.on_snapshot(s); }, &feed_.ticks(),
                       &feed_.presses());
}

OperatorLiveView::OperatorLiveView(const view::ViewOptions& o, LiveViewLinks links) : o_(o), links_(std::move(links)) {
  if (!o_.enabled()) throw std::invalid_argument("OperatorLiveView: neither a window nor PNGs asked for");
}

OperatorLiveView::~OperatorLiveView() { stop(); }

void start_view_thread(view::ViewThread& thread, std::function<void(const std::atomic<bool>& stop)> body) {
  thread.start_logged(std::move(body));
}

LiveViewStats live_view_stats(const view::ViewLoopCounters& c, std::uint64_t dropped_geoms,
                              const view::ViewThread& thread) {
  LiveViewStats s;
  s.frames = c.frames.load();
  s.pngs = c.pngs.load();
  s.dropped_geoms = dropped_geoms;
  s.error = thread.error();
  return s;
}

void OperatorLiveView::start() {
  start_view_thread(thread_, [this](const std::atomic<bool>& stop) { run(stop); });
}

void OperatorLiveView::stop() { thread_.stop(); }

LiveViewStats OperatorLiveView::stats() const {
  LiveViewStats s = live_view_stats(counters_, dropped_.load(), thread_);
  s.model_copies = feed_.copies();
  return s;
}

void OperatorLiveView::run(const std::atomic<bool>& stop) {
  view::MjModelPtr model = load_world();
  view::MjDataPtr data = view::make_data(model.get());
  const view::CameraSpec camera = view::orbit_camera(7.0, 90.0, -60.0);  // from the south, above
  view::CameraMode cam_mode = view::initial_camera_mode(o_);

  ViewModel vm;
  StationLogRecord tick;
  bool have_tick = false;
  ServoHealthMeter meter;
  ServoHealth health;
  std::int64_t next_health = 0;
  bool estop_requested = false;
  view::PrimitiveList prims;
  const OperatorSceneStyle style;

  view::ViewLoopHooks hooks;
  view::set_logging_hooks(o_, hooks);
  hooks.on_key = [&](view::MujocoWindow&, int key) {
    if (key == 'm') {
      feed_.press(device::kButton1);
    } else if (key == 'e') {
      estop_requested = true;
      if (links_.estop) links_.estop();
    } else if (key == 'c') {
      cam_mode = view::next_camera_mode(cam_mode);
    }
  };
  hooks.draw = [&](view::MujocoWindow& win, std::int64_t now, view::Image* capture) {
    if (feed_.take_model(vm)) update_voxmap_cubes(vm, style.voxmap_cubes);
    while (feed_.take_tick(tick)) have_tick = true;
    if (servo_stats_ != nullptr && now >= next_health) {
      health = meter.update(*servo_stats_, now);
      next_health = now + 500'000'000;
    }
    if (have_tick) view::aim_camera(win, cam_mode, Eigen::Vector3d(tick.robot[0], tick.robot[1], 0.0));
    build_operator_scene(vm, have_tick ? &tick : nullptr, style, prims);
    const net::LinkStatistics link = links_.link_stats ? links_.link_stats() : net::LinkStatistics{};
    OverlayInputs in;
    in.model = &vm;
    in.tick = have_tick ? &tick : nullptr;
    in.link = links_.link_stats ? &link : nullptr;
    in.servo = servo_stats_ != nullptr ? &health : nullptr;
    // Ages against the clock the stamps come from: a replay's is the recorded ticks'.
    in.now_ns = servo_stats_ == nullptr && have_tick ? tick.t_ns : now;
    in.estop_requested = estop_requested;
    dropped_.fetch_add(win.render(prims.items(), make_operator_overlay(in), capture), std::memory_order_relaxed);
  };
  hooks.text = [&](view::MujocoWindow& win, std::int64_t now) {
    view::TextChunks t = view::camera_text(win.camera(), win.fovy_deg());
    t.emplace_back("hemm:station", "operator");
    t.emplace_back("hemm:frame_ns", std::to_string(now));
    t.emplace_back("hemm:tick_ns", have_tick ? std::to_string(tick.t_ns) : "-1");
    t.emplace_back("hemm:model_version", std::to_string(vm.version));
    return t;
  };
  view::run_live_view(model.get(), data.get(), o_, "hemm operator station", camera, stop, hooks, counters_);
  spdlog::info("event=view_stopped frames={} pngs={}", counters_.frames.load(), counters_.pngs.load());
}

}  // namespace hemm::op
