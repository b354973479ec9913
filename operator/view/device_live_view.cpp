#include "operator/view/device_live_view.h"

#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <sstream>
#include <stdexcept>

#include "common/view/mujoco_window.h"
#include "common/view/png_sequence.h"

namespace hemm::op {
namespace {

// No floor (the rig's table is drawn), a headlight and a light from above;
// the extent sets the clip planes (3 cm .. 150 m).
constexpr const char* kDeviceWorldXml = R"(<mujoco model="hemm_device_view">
  <statistic extent="3" center="0 0 0"/>
  <visual>
    <global fovy="45"/>
    <headlight ambient="0.45 0.45 0.45" diffuse="0.45 0.45 0.45" specular="0 0 0"/>
    <rgba haze="0.12 0.12 0.14 1"/>
  </visual>
  <worldbody>
    <light pos="0 0 10" dir="0 0 -1" directional="true" diffuse="0.3 0.3 0.3" specular="0 0 0" castshadow="false"/>
  </worldbody>
</mujoco>
)";

// What a PNG's reader needs to check it: the tick, the arms' joint angles,
// the end-effectors' positions and the objects' poses (x y z, then qw qx qy
// qz; frames as in device_view_record.h), and where W is drawn (T_H_W, three
// rows of four).
void add_tick_text(const DeviceSceneSetup& s, const DeviceViewRecord* t, view::TextChunks& out) {
  out.emplace_back("hemm:tick_ns", t != nullptr ? std::to_string(t->t_ns) : "-1");
  std::ostringstream o;
  o.precision(9);
  const Eigen::Matrix4d T = s.T_H_W.matrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) o << T(r, c) << (r == 2 && c == 3 ? "" : " ");
  out.emplace_back("hemm:T_H_W", o.str());
  if (t == nullptr) return;
  for (std::size_t k = 0; k < static_cast<std::size_t>(std::clamp(t->end_effectors, 0, 2)); ++k) {
    std::ostringstream p;
    p.precision(9);
    p << t->position_H[k].x() << " " << t->position_H[k].y() << " " << t->position_H[k].z();
    out.emplace_back("hemm:ee" + std::to_string(k) + "_H", p.str());
    if (t->has_arms) {
      std::ostringstream q;
      q.precision(9);
      for (int i = 0; i < kinematics::kArm7Dof; ++i) q << (i > 0 ? " " : "") << t->q[k][i];
      out.emplace_back("hemm:q" + std::to_string(k), q.str());
    }
  }
  for (std::size_t k = 0; k < static_cast<std::size_t>(std::clamp(t->objects, 0, 2)); ++k) {
    std::ostringstream p;
    p.precision(9);
    const Eigen::Vector3d x = t->object_W[k].translation();
    const Eigen::Quaterniond q(t->object_W[k].linear());
    p << x.x() << " " << x.y() << " " << x.z() << " " << q.w() << " " << q.x() << " " << q.y() << " " << q.z();
    out.emplace_back("hemm:object" + std::to_string(k) + "_W", p.str());
  }
}

}  // namespace

DeviceLiveView::DeviceLiveView(const view::ViewOptions& o, DeviceSceneSetup setup) : o_(o), setup_(std::move(setup)) {
  if (!o_.enabled()) throw std::invalid_argument("DeviceLiveView: neither a window nor PNGs asked for");
}

DeviceLiveView::~DeviceLiveView() { stop(); }

void DeviceLiveView::start(const servo::TimingStats* servo) {
  servo_ = servo;
  start_view_thread(thread_, [this](const std::atomic<bool>& stop) { run(stop); });
}

void DeviceLiveView::stop() { thread_.stop(); }

LiveViewStats DeviceLiveView::stats() const { return live_view_stats(counters_, dropped_.load(), thread_); }

void DeviceLiveView::run(const std::atomic<bool>& stop) {
  view::MjModelPtr model = sim::load_model_xml("device_view.xml", kDeviceWorldXml);
  view::MjDataPtr data = view::make_data(model.get());
  const view::CameraSpec camera = default_device_camera(setup_);
  DeviceViewRecord tick;
  bool have_tick = false;
  ServoHealthMeter meter;
  ServoHealth health;
  std::int64_t next_health = 0;
  view::PrimitiveList prims;
  const DeviceSceneStyle style = device_scene_style(setup_);

  view::ViewLoopHooks hooks;
  view::set_logging_hooks(o_, hooks);
  hooks.on_key = [&](view::MujocoWindow& win, int key) {
    if (key == 'c') win.set_camera(o_.top ? *o_.top : camera);
  };
  hooks.draw = [&](view::MujocoWindow& win, std::int64_t now, view::Image* capture) {
    if (const DeviceViewRecord* r = ticks_.take()) {
      tick = *r;
      have_tick = true;
    }
    if (servo_ != nullptr && now >= next_health) {
      health = meter.update(*servo_, now);
      next_health = now + 500'000'000;
    }
    build_device_scene(setup_, have_tick ? &tick : nullptr, style, prims);
    const view::Overlay overlay =
        make_device_overlay(setup_, have_tick ? &tick : nullptr, servo_ != nullptr ? &health : nullptr);
    dropped_.fetch_add(win.render(prims.items(), overlay, capture), std::memory_order_relaxed);
  };
  hooks.text = [&](view::MujocoWindow& win, std::int64_t now) {
    view::TextChunks t = view::camera_text(win.camera(), win.fovy_deg());
    t.emplace_back("hemm:station", "operator-device");
    t.emplace_back("hemm:frame_ns", std::to_string(now));
    add_tick_text(setup_, have_tick ? &tick : nullptr, t);
    return t;
  };
  view::run_live_view(model.get(), data.get(), o_, "hemm operator: " + setup_.device, camera, stop, hooks, counters_);
  spdlog::info("event=view_stopped frames={} pngs={} dropped_geoms={}", counters_.frames.load(), counters_.pngs.load(),
               dropped_.load());
}

}  // namespace hemm::op
