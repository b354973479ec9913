#include "robot_side/view/twoarm_view.h"

#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "common/sim/mujoco_owner.h"
#include "common/sim/mujoco_pose.h"
#include "common/view/mujoco_window.h"
#include "robot_side/view/twoarm_scene.h"

namespace hemm::robot {
TwoArmLiveView::TwoArmLiveView(const view::ViewOptions& o, std::string scene_path)
    : o_(o),
      scene_path_(std::move(scene_path)),
      feed_(std::make_shared<TwoArmViewFeed>(view::station_feed_interval_ns(o))) {
  if (!o_.enabled()) throw std::invalid_argument("TwoArmLiveView: neither a window nor PNGs asked for");
}

TwoArmLiveView::~TwoArmLiveView() { stop(); }

void TwoArmLiveView::start() {
  thread_.start_logged([this](const std::atomic<bool>& stop) { run(stop); });
}

void TwoArmLiveView::stop() { thread_.stop(); }

void TwoArmLiveView::run(const std::atomic<bool>& stop) {
  view::MjModelPtr model = sim::load_model_file(scene_path_);  // throws "PATH: MuJoCo's message"
  for (int g = 0; g < model->ngeom; ++g)
    if (model->geom_group[g] == 3) model->geom_group[g] = 0;
  const int torso = mj_name2id(model.get(), mjOBJ_BODY, "torso");
  if (torso < 0) throw std::runtime_error(scene_path_ + ": no body 'torso' (the arms' frame A)");
  view::MjDataPtr data = view::make_data(model.get());
  const view::CameraSpec camera = view::orbit_camera(2.4, 180.0, -30.0);  // from in front of the bench, above
  view::CameraMode cam_mode = view::initial_camera_mode(o_);
  TwoArmViewFrame frame;
  bool have = false;
  std::int64_t t0_ns = 0;  // robot time of the first frame
  Eigen::Isometry3d T_W_A = Eigen::Isometry3d::Identity();
  view::PrimitiveList prims;
  view::ViewLoopHooks hooks;
  view::set_logging_hooks(o_, hooks);
  hooks.on_key = [&](view::MujocoWindow&, int key) {
    if (key == 'c') cam_mode = view::next_camera_mode(cam_mode);
  };
  hooks.draw = [&](view::MujocoWindow& win, std::int64_t, view::Image* capture) {
    if (const TwoArmViewFrame* f = feed_->take()) {
      if (f->nq != model->nq) throw std::runtime_error("the simulation's state does not fit the scene " + scene_path_);
      frame = *f;
      if (!have) t0_ns = frame.t_ns;
      have = true;
      std::copy(frame.qpos.begin(), frame.qpos.begin() + frame.nq, data->qpos);
      mj_kinematics(model.get(), data.get());
      mj_comPos(model.get(), data.get());
      mj_camlight(model.get(), data.get());
      T_W_A = sim::mujoco_pose(data->xpos + 3 * torso, data->xmat + 9 * torso);
    }
    view::Overlay overlay;
    if (have) {
      const Eigen::Vector3d mid =
          T_W_A * (0.5 * (frame.snapshot.control.arm[0].T_A_G.translation() +
                          frame.snapshot.control.arm[1].T_A_G.translation()));
      view::aim_camera(win, cam_mode, mid);
      build_twoarm_scene(frame, T_W_A, TwoArmSceneStyle{}, prims);
      overlay = twoarm_overlay(frame, t0_ns);
    } else {
      prims.clear();
      overlay.left = "SIMULATION";
      overlay.right = "(waiting for the first state)";
    }
    win.render(prims.items(), overlay, capture);
  };
  hooks.text = [&](view::MujocoWindow& win, std::int64_t now) {
    view::TextChunks t = view::camera_text(win.camera(), win.fovy_deg());
    t.emplace_back("hemm:station", "robot-twoarm");
    t.emplace_back("hemm:frame_ns", std::to_string(now));
    t.emplace_back("hemm:sim_ns", have ? std::to_string(frame.t_ns) : "-1");
    for (std::size_t a = 0; a < twoarm::kArms; ++a) {
      char g[120] = "-";
      if (have) {
        const Eigen::Vector3d p = T_W_A * frame.snapshot.control.arm[a].T_A_G.translation();
        std::snprintf(g, sizeof g, "%.6f %.6f %.6f", p.x(), p.y(), p.z());
      }
      t.emplace_back(a == 0 ? "hemm:grasp_right_W" : "hemm:grasp_left_W", g);
    }
    return t;
  };
  view::run_live_view(model.get(), data.get(), o_, "hemm two-arm station (SIMULATION)", camera, stop, hooks,
                      counters_);
  spdlog::info("event=view_stopped frames={} pngs={}", counters_.frames.load(), counters_.pngs.load());
}

}  // namespace hemm::robot
