#include "robot_side/view/robot_view.h"

#include <mujoco/mujoco.h>
#include <spdlog/spdlog.h>

#include <cinttypes>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "common/view/mujoco_window.h"
#include "common/view/png_sequence.h"
#include "robot_side/view/twoarm_scene.h"
#include "wire.pb.h"

namespace hemm::robot {
namespace {

constexpr view::Rgba kLaserHit{0.95f, 0.15f, 0.1f, 0.6f};
constexpr view::Rgba kLaserMiss{0.95f, 0.6f, 0.55f, 0.2f};
constexpr view::Rgba kSonar{0.1f, 0.8f, 0.2f, 1.0f};
constexpr view::Rgba kContactHit{0.95f, 0.05f, 0.05f, 1.0f};
constexpr view::Rgba kContactFloor{0.6f, 0.6f, 0.6f, 1.0f};

Eigen::Isometry3d planar(const Pose2& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(p.x, p.y, 0.0);
  T.linear() = Eigen::AngleAxisd(p.theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// Rays of the newest scans from the sensor's true pose at acquisition, and
// the contacts. floor: the scene's plane geoms (a wheel on the floor is not a
// collision).
void build_sim_scene(const SimViewFrame& f, const mjModel* m, view::PrimitiveList& out) {
  out.clear();
  for (const RangeScanData& s : f.scans) {
    const Eigen::Isometry3d T_W_S = planar(s.T_W_R_truth) * s.T_R_S;
    const Eigen::Vector3d o = T_W_S.translation();
    const bool sonar = s.beam_width > 0.0;
    for (std::size_t i = 0; i < s.ranges.size(); ++i) {
      const double a = s.angle_min + static_cast<double>(i) * s.angle_step;
      const bool valid = i < s.valid.size() && s.valid[i] != 0;
      if (!valid && sonar) continue;
      const double r = valid ? static_cast<double>(s.ranges[i]) : s.range_max;
      const Eigen::Vector3d p = T_W_S * Eigen::Vector3d(r * std::cos(a), r * std::sin(a), 0.0);
      out.line(o, p, sonar ? 2.0 : 1.0, sonar ? kSonar : valid ? kLaserHit : kLaserMiss);
    }
  }
  for (const SimContact& c : f.contacts) {
    const bool floor = (c.geom1 >= 0 && c.geom1 < m->ngeom && m->geom_type[c.geom1] == mjGEOM_PLANE) ||
                       (c.geom2 >= 0 && c.geom2 < m->ngeom && m->geom_type[c.geom2] == mjGEOM_PLANE);
    const view::Rgba col = floor ? kContactFloor : kContactHit;
    out.sphere(c.pos_W, floor ? 0.015 : 0.03, col);
    out.arrow(c.pos_W, c.pos_W + 0.005 * c.force_W, floor ? 0.01 : 0.02, col);  // 5 mm per N
  }
}

view::Overlay sim_overlay(const SimViewFrame& f, const mjModel* m, std::int64_t t0_ns) {
  view::Overlay o;
  char buf[512];
  int hits = 0;
  for (const SimContact& c : f.contacts) {
    const bool floor = (c.geom1 >= 0 && m->geom_type[c.geom1] == mjGEOM_PLANE) ||
                       (c.geom2 >= 0 && m->geom_type[c.geom2] == mjGEOM_PLANE);
    if (!floor) ++hits;
  }
  const RobotStateSim& s = f.state;
  o.left = "SIMULATION\ntrue pose\nodometry\nspeed\nsafety\ncontacts\nlink";
  std::snprintf(buf, sizeof buf,
                "t %.2f s\nx %.3f  y %.3f  heading %.1f deg\nx %.3f  y %.3f  heading %.1f deg\nv %.2f m/s  omega %.2f "
                "rad/s\n%s\n%zu (%d not with the floor)\n%s%s",
                static_cast<double>(f.t_ns - t0_ns) * 1e-9, s.T_W_R_truth.x, s.T_W_R_truth.y,
                s.T_W_R_truth.theta * 57.29577951308232, s.T_W_R_odom.x, s.T_W_R_odom.y,
                s.T_W_R_odom.theta * 57.29577951308232, s.v_truth, s.omega_truth, safety_text(s.safety).c_str(),
                f.contacts.size(), hits, f.link_up ? "up" : "down", f.in_control ? ", operator in control" : "");
  o.right = buf;
  o.bottom = "c: camera (follow / free / top)   mouse: rotate, move, zoom";
  if (s.safety & wire::SAFETY_ESTOP) o.banners.push_back({"E-STOP", view::Rgba{0.85f, 0.05f, 0.05f, 1.0f}});
  if (hits > 0) o.banners.push_back({"COLLISION", view::Rgba{0.85f, 0.05f, 0.05f, 1.0f}});
  if (!f.link_up) o.banners.push_back({"NO OPERATOR LINK", view::Rgba{0.85f, 0.45f, 0.05f, 1.0f}});
  return o;
}

}  // namespace

RobotLiveView::RobotLiveView(const view::ViewOptions& o, std::string scene_path)
    : o_(o),
      scene_path_(std::move(scene_path)),
      feed_(std::make_shared<SimViewFeed>(view::station_feed_interval_ns(o))) {
  if (!o_.enabled()) throw std::invalid_argument("RobotLiveView: neither a window nor PNGs asked for");
}

RobotLiveView::~RobotLiveView() { stop(); }

void RobotLiveView::start() {
  thread_.start_logged([this](const std::atomic<bool>& stop) { run(stop); });
}

void RobotLiveView::stop() { thread_.stop(); }

void RobotLiveView::run(const std::atomic<bool>& stop) {
  view::MjModelPtr model = sim::load_model_file(scene_path_);  // throws "PATH: MuJoCo's message"
  // The world's walls and furniture see-through (the view's copy only), so
  // a camera above a room still shows the robot behind a 2.5 m wall.
  for (int g = 0; g < model->ngeom; ++g)
    if (model->geom_bodyid[g] == 0 && model->geom_type[g] != mjGEOM_PLANE) model->geom_rgba[4 * g + 3] *= 0.35f;
  view::MjDataPtr data = view::make_data(model.get());
  const view::CameraSpec camera = view::orbit_camera(6.0, 90.0, -60.0);  // from the south, above
  view::CameraMode cam_mode = view::initial_camera_mode(o_);
  SimViewFrame frame;
  bool have = false;
  std::int64_t t0_ns = 0;  // simulation time of the first frame
  view::PrimitiveList prims;
  view::ViewLoopHooks hooks;
  view::set_logging_hooks(o_, hooks);
  hooks.on_key = [&](view::MujocoWindow&, int key) {
    if (key == 'c') cam_mode = view::next_camera_mode(cam_mode);
  };
  hooks.draw = [&](view::MujocoWindow& win, std::int64_t, view::Image* capture) {
    if (feed_->take(frame)) {
      if (frame.qpos.size() != static_cast<std::size_t>(model->nq))
        throw std::runtime_error("the simulation's state does not fit the scene " + scene_path_);
      if (!have) t0_ns = frame.t_ns;
      have = true;
      std::copy(frame.qpos.begin(), frame.qpos.end(), data->qpos);
      mj_kinematics(model.get(), data.get());
      mj_comPos(model.get(), data.get());
      mj_camlight(model.get(), data.get());
    }
    view::Overlay overlay;
    if (have) {
      const Pose2& p = frame.state.T_W_R_truth;
      view::aim_camera(win, cam_mode, Eigen::Vector3d(p.x, p.y, 0.3));
      build_sim_scene(frame, model.get(), prims);
      overlay = sim_overlay(frame, model.get(), t0_ns);
    } else {
      prims.clear();
      overlay.left = "SIMULATION";
      overlay.right = "(waiting for the first state)";
    }
    win.render(prims.items(), overlay, capture);
  };
  hooks.text = [&](view::MujocoWindow& win, std::int64_t now) {
    view::TextChunks t = view::camera_text(win.camera(), win.fovy_deg());
    t.emplace_back("hemm:station", "robot");
    t.emplace_back("hemm:frame_ns", std::to_string(now));
    t.emplace_back("hemm:sim_ns", have ? std::to_string(frame.t_ns) : "-1");
    char pose[100];
    std::snprintf(pose, sizeof pose, "%.6f %.6f %.6f", frame.state.T_W_R_truth.x, frame.state.T_W_R_truth.y,
                  frame.state.T_W_R_truth.theta);
    t.emplace_back("hemm:true_pose", have ? pose : "-");
    return t;
  };
  view::run_live_view(model.get(), data.get(), o_, "hemm robot station (SIMULATION)", camera, stop, hooks,
                      counters_);
  spdlog::info("event=view_stopped frames={} pngs={}", counters_.frames.load(), counters_.pngs.load());
}

}  // namespace hemm::robot
