#include "operator/view/operator_scene.h"

#include <cinttypes>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <numbers>

#include "common/haptics/vps/voxmap.h"
#include "wire.pb.h"

namespace hemm::op {

void build_operator_scene(const ViewModel& model, const StationLogRecord* tick, const OperatorSceneStyle& st,
                          view::PrimitiveList& out) {
  out.clear();
  // The map: a wall behind each piece's free-side face.
  for (const mapping::Segment2& s : model.segments) {
    const Eigen::Vector2d d = s.b - s.a;
    const double len = d.norm();
    if (!(len > 1e-6) || !s.a.allFinite() || !s.b.allFinite()) continue;
    const Eigen::Vector2d mid = 0.5 * (s.a + s.b) - 0.5 * st.wall_thickness * s.normal;
    out.box(Eigen::Vector3d(mid.x(), mid.y(), 0.5 * st.wall_height), std::atan2(d.y(), d.x()),
            Eigen::Vector3d(0.5 * len, 0.5 * st.wall_thickness, 0.5 * st.wall_height),
            s.fitted                                ? view_colours::kMapFitted
            : s.shadow                              ? view_colours::kMapShadow
            : s.kind == mapping::SensorKind::kLaser ? view_colours::kMapLaser
                                                    : view_colours::kMapSonar);
  }
  // The live voxmap: its surface cubes (model.voxmap_cubes, frame W).
  const Eigen::Vector3d cube_half = Eigen::Vector3d::Constant(model.voxmap_cubes.half);
  // Inferred surfaces (a fitted primitive's unseen side, unknown space) apart.
  for (std::size_t i = 0; i < model.voxmap_cubes.centres.size(); ++i) {
    const bool inferred = i < model.voxmap_cubes.inferred.size() && model.voxmap_cubes.inferred[i] != 0;
    out.box(model.voxmap_cubes.centres[i], 0.0, cube_half,
            inferred ? view_colours::kVoxmapInferred : view_colours::kVoxmap);
  }
  const double top = 2.0 * st.robot_half.z();
  // The last received pose: an outline of the footprint with its heading.
  if (model.have_state) {
    const math::Pose2& p = model.state.T_W_R_odom;
    const Eigen::Rotation2Dd R(p.theta);
    const Eigen::Vector2d c(p.x, p.y);
    const double hx = st.robot_half.x(), hy = st.robot_half.y();
    const Eigen::Vector2d corners[4] = {c + R * Eigen::Vector2d(hx, hy), c + R * Eigen::Vector2d(-hx, hy),
                                        c + R * Eigen::Vector2d(-hx, -hy), c + R * Eigen::Vector2d(hx, -hy)};
    const double z = top + 0.02;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector2d& a = corners[i];
      const Eigen::Vector2d& b = corners[(i + 1) % 4];
      out.line(Eigen::Vector3d(a.x(), a.y(), z), Eigen::Vector3d(b.x(), b.y(), z), 3.0, view_colours::kRobotReceived);
    }
    const Eigen::Vector2d nose = c + R * Eigen::Vector2d(hx + 0.1, 0.0);
    out.line(Eigen::Vector3d(c.x(), c.y(), z), Eigen::Vector3d(nose.x(), nose.y(), z), 3.0,
             view_colours::kRobotReceived);
  }
  if (tick == nullptr) return;
  // The robot as rendered by the servo task (predicted to the tick).
  if (model.have_state) {
    out.box(Eigen::Vector3d(tick->robot[0], tick->robot[1], st.robot_half.z()), tick->robot[2], st.robot_half,
            view_colours::kRobot);
    const Eigen::Vector2d c(tick->robot[0], tick->robot[1]);
    const Eigen::Vector2d nose = c + Eigen::Rotation2Dd(tick->robot[2]) * Eigen::Vector2d(st.robot_half.x(), 0.0);
    out.arrow(Eigen::Vector3d(c.x(), c.y(), top + 0.01), Eigen::Vector3d(nose.x(), nose.y(), top + 0.01), 0.05,
              view::Rgba{0.9f, 0.9f, 0.95f, 1.0f});
  }
  const Eigen::Vector3d proxy(tick->proxy_W[0], tick->proxy_W[1], st.marker_z);
  const Eigen::Vector3d device(tick->goal_W[0], tick->goal_W[1], st.marker_z - 0.02);
  if (proxy.allFinite()) out.sphere(proxy, st.proxy_radius, view_colours::kProxy);
  if (device.allFinite()) out.sphere(device, st.device_radius, view_colours::kDevicePoint);
  if (proxy.allFinite() && device.allFinite() && (proxy - device).norm() > st.proxy_radius)
    out.line(proxy, device, 2.0, view_colours::kDevicePoint);
  const Eigen::Vector3d f(tick->force_W[0], tick->force_W[1], 0.0);
  if (f.allFinite() && f.norm() > 0.02 && proxy.allFinite())
    out.arrow(proxy, proxy + st.force_scale * f, 0.04, view_colours::kForce);
}

const char* mode_name(std::uint32_t m) {
  switch (m) {
    case wire::MODE_EXPLORATION: return "exploration";
    case wire::MODE_NAVIGATION: return "navigation";
    case wire::MODE_MANIPULATION: return "manipulation";
    case wire::MODE_IDLE: return "idle";
    default: return "?";
  }
}

std::string overlay_text(const char* f, ...) {
  char buf[256];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}

view::Overlay make_operator_overlay(const OverlayInputs& in) {
  view::Overlay o;
  std::string& l = o.left;
  std::string& r = o.right;
  auto row = [&](const char* k, const std::string& v) {
    l += std::string(k) + "\n";
    r += v + "\n";
  };
  const ViewModel* m = in.model;
  const StationLogRecord* t = in.tick;
  if (t != nullptr) {
    row("mode", overlay_text("%s  (scale %.1f: W m per device m)", mode_name(t->mode), t->scale));
    row("robot (predicted)", overlay_text("x %.2f  y %.2f  heading %.1f deg", t->robot[0], t->robot[1], t->robot[2] * 180.0 / std::numbers::pi));
    row("force", overlay_text("%.2f N  (contacts %d)", std::hypot(t->force_W[0], t->force_W[1]), t->contacts));
  } else {
    row("mode", "(no servo tick yet)");
  }
  if (m != nullptr && m->have_state) {
    const double age_ms = static_cast<double>(in.now_ns - m->state.stamp_local_ns) * 1e-6;
    row("last robot state", overlay_text("x %.2f  y %.2f  age %.0f ms", m->state.T_W_R_odom.x, m->state.T_W_R_odom.y, age_ms));
  }
  if (m != nullptr && m->version != 0) {
    row("local map", overlay_text("%zu segments, %zu pieces%s  (model v%" PRIu64 ", %.0f ms old)", m->map_segments,
                         m->pieces_total, m->pieces_total > m->segments.size() ? " (some not drawn)" : "", m->version,
                         static_cast<double>(in.now_ns - m->stamp_ns) * 1e-6));
  }
  if (m != nullptr && m->voxmap) {
    row("live voxmap", overlay_text("build %" PRIu64 ": %zu surface voxels of %.0f mm, drawn as %zu cubes", m->voxmap_builds,
                                    m->voxmap_cubes.surface_voxels, m->voxmap->voxel_size * 1e3,
                                    m->voxmap_cubes.centres.size()));
  }
  if (in.link != nullptr) {
    const net::LinkStatistics& s = *in.link;
    const std::uint64_t expected = s.rx.delivered + s.rx.lost;
    const double loss = expected > 0 ? 100.0 * static_cast<double>(s.rx.lost) / static_cast<double>(expected) : 0.0;
    if (s.clock.valid)
      row("link", overlay_text("%s  RTT %.0f ms (median %.0f)  lost %" PRIu64 " (%.1f %%)", s.link_up ? "up" : "DOWN",
                      s.clock.rtt_last_ns * 1e-6, s.clock.rtt_median_ns * 1e-6, s.rx.lost, loss));
    else
      row("link", overlay_text("%s  RTT -  lost %" PRIu64, s.link_up ? "up" : "DOWN", s.rx.lost));
  }
  if (in.servo != nullptr) {
    const ServoHealth& h = *in.servo;
    row("servo loop", overlay_text("period %.3f ms (p99 %.3f)  misses %" PRIu64 " (+%" PRIu64 " in %.1f s)  ticks %" PRIu64,
                          h.period_median_ms, h.period_p99_ms, h.misses, h.window_misses, h.window_s, h.ticks));
    // No compute row or histogram plot here (the device views have them): a
    // ninth row and the corner plot hid the robot and the map's walls.
  }
  if (!l.empty()) l.pop_back();
  if (!r.empty()) r.pop_back();
  o.bottom = "m: mode   e: e-stop   c: camera (follow / free / top)   mouse: rotate, move, zoom";
  if (in.link != nullptr && !in.link->link_up) o.banners.push_back({"LINK DOWN", view_colours::kAlarm});
  const bool estop = (m != nullptr && m->have_state && (m->state.safety & wire::SAFETY_ESTOP) != 0);
  if (estop) o.banners.push_back({"E-STOP", view_colours::kAlarm});
  else if (in.estop_requested) o.banners.push_back({"E-STOP REQUESTED", view_colours::kAlarm});
  if (m == nullptr || !m->have_state) o.banners.push_back({"NO ROBOT STATE", view_colours::kWarning});
  return o;
}

}  // namespace hemm::op
