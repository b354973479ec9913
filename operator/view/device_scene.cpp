#include "operator/view/device_scene.h"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>

#include "operator/view/operator_scene.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;
namespace colours = device_view_colours;

DeviceViewObject view_object(const vps::PointShell& shell, std::size_t max_points) {
  DeviceViewObject o;
  const std::size_t n = shell.size();
  for (std::size_t i = 0; i < n; ++i) o.box_M.extend(shell.point(i));
  if (n == 0 || max_points == 0) return o;
  const std::size_t step = (n + max_points - 1) / max_points;
  for (std::size_t i = 0; i < n; i += step) o.points_M.push_back(shell.point(i));
  return o;
}

Eigen::Isometry3d view_placement_of_W(const std::array<Eigen::Isometry3d, device::kMaxEndEffectors>& T_W_H,
                                      int end_effectors) {
  const int n = std::clamp(end_effectors, 1, device::kMaxEndEffectors);
  Eigen::Isometry3d T = T_W_H[0];
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int k = 0; k < n; ++k) sum += T_W_H[static_cast<std::size_t>(k)].translation();
  T.translation() = sum / n;
  return T.inverse();
}

namespace {

std::optional<DeviceViewArms> arms_of(const hb::SimulationConfig& sim) {
  DeviceViewArms a;
  a.rig = sim.plant.rig;
  for (std::size_t k = 0; k < hb::kArms; ++k) a.handles[k] = hb::handle_spec(sim.plant.handles[k]);
  return a;
}

}  // namespace

DeviceSceneSetup vps_view_setup(const VpsLocalModel& model, const VpsTaskParams& task, int end_effectors,
                                const hb::SimulationConfig* arms, std::string device_name,
                                const DeviceSceneBudget& budget) {
  DeviceSceneSetup s;
  s.device = std::move(device_name);
  if (arms != nullptr) s.arms = arms_of(*arms);
  for (std::size_t k = 0; k < device::kMaxEndEffectors; ++k) s.T_W_H[k] = task.ee[k].T_W_H;
  s.T_H_W = view_placement_of_W(s.T_W_H, std::min(end_effectors, std::max(model.object_count, 1)));
  for (int k = 0; k < model.object_count; ++k)
    s.objects.push_back(view_object(model.objects[static_cast<std::size_t>(k)].shell, budget.object_points));
  s.scene = surface_cubes(model.scene, budget.scene_cubes);
  return s;
}

DeviceSceneSetup bimanual_view_setup(const BimanualSetup& setup) {
  DeviceSceneSetup s;
  s.device = "simulated-bimanual-lwr";
  s.arms = arms_of(setup.sim);
  for (std::size_t k = 0; k < device::kMaxEndEffectors; ++k)
    s.planes[k] = DeviceViewPlane{setup.env[k].plane_point_H, setup.env[k].plane_normal_H.normalized()};
  return s;
}

void build_device_scene(const DeviceSceneSetup& s, const DeviceViewRecord* tick, const DeviceSceneStyle& st,
                        view::PrimitiveList& out) {
  out.clear();
  if (s.arms) {
    for (const hb::Box* b : {&s.arms->rig.table, &s.arms->rig.column})
      out.box(0.5 * (b->min_D + b->max_D), Eigen::Matrix3d::Identity(), 0.5 * (b->max_D - b->min_D),
              b == &s.arms->rig.table ? colours::kTable : colours::kColumn);
  }
  // The static scene, as placed in H.
  const Eigen::Matrix3d R_H_W = s.T_H_W.linear();
  for (const Eigen::Vector3d& c : s.scene.centres)
    out.box(s.T_H_W * c, R_H_W, Eigen::Vector3d::Constant(s.scene.half), colours::kScene);
  for (const auto& p : s.planes) {
    if (!p) continue;
    const Eigen::Matrix3d R = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), p->normal_H).toRotationMatrix();
    out.box(p->point_H - 0.002 * p->normal_H, R, Eigen::Vector3d(0.2, 0.2, 0.002), colours::kPlane);
  }
  if (tick == nullptr) return;
  const int n = std::clamp(tick->end_effectors, 0, device::kMaxEndEffectors);
  // The arms: capsules from the mount through each joint origin to the
  // flange, then the handle.
  if (s.arms && tick->has_arms) {
    const hb::RigGeometry& rig = s.arms->rig;
    for (std::size_t a = 0; a < hb::kArms; ++a) {
      const Eigen::Isometry3d& T_D_A = rig.T_D_A[a];
      if (!tick->q[a].allFinite()) continue;
      kinematics::Arm7Frames f;
      kinematics::forward_kinematics(rig.arm, tick->q[a], f);
      Eigen::Vector3d prev = T_D_A.translation();
      for (int i = 1; i <= kinematics::kArm7Dof; ++i) {
        const Eigen::Vector3d p = T_D_A * f.origin(i);
        out.capsule(prev, p, rig.link_radius[i - 1], colours::kArm);
        prev = p;
      }
      const Eigen::Isometry3d T_D_J7 = T_D_A * f.joint(kinematics::kArm7Flange);
      const hb::HandleSpec& h = s.arms->handles[a];
      out.capsule(T_D_J7.translation(), T_D_J7 * Eigen::Vector3d(0.0, 0.0, h.capsule_length), h.capsule_radius,
                  colours::kHandle);
    }
  } else {
    for (std::size_t k = 0; k < static_cast<std::size_t>(n); ++k)
      if (tick->position_H[k].allFinite()) out.sphere(tick->position_H[k], st.end_effector_radius, colours::kHandle);
  }
  // The objects: box, points, and the line from the hand that holds each.
  const int objects = std::min(tick->objects, static_cast<int>(s.objects.size()));
  for (std::size_t k = 0; k < static_cast<std::size_t>(objects); ++k) {
    const Eigen::Isometry3d T_H_M = s.T_H_W * tick->object_W[k];
    if (!T_H_M.matrix().allFinite()) continue;
    const DeviceViewObject& o = s.objects[k];
    view::Rgba box_colour = colours::kObject[k];
    box_colour.a = colours::kObjectBoxAlpha;
    if (!o.box_M.isEmpty())
      out.box(T_H_M * o.box_M.center(), T_H_M.linear(), 0.5 * o.box_M.sizes(), box_colour);
    for (const Eigen::Vector3d& p : o.points_M) out.sphere(T_H_M * p, st.point_radius, colours::kObject[k]);
    if (k < static_cast<std::size_t>(n) && tick->position_H[k].allFinite())
      out.line(tick->position_H[k], T_H_M.translation(), 1.5, colours::kGrasp);
  }
  // The wrench each end-effector was commanded.
  for (std::size_t k = 0; k < static_cast<std::size_t>(n); ++k) {
    const Eigen::Vector3d& p = tick->position_H[k];
    if (!p.allFinite()) continue;
    const auto arrow = [&](const Eigen::Vector3d& v, double scale, view::Rgba c) {
      if (!v.allFinite() || !(scale * v.norm() > 0.005)) return;  // shorter than 5 mm: hidden in the handle
      out.arrow(p, p + std::min(scale * v.norm(), st.max_arrow) * v.normalized(), st.arrow_width, c);
    };
    arrow(tick->force_H[k], st.force_scale, colours::kForce);
    arrow(tick->torque_H[k], st.torque_scale, colours::kTorque);
  }
}

DeviceSceneStyle device_scene_style(const DeviceSceneSetup& s) {
  DeviceSceneStyle st;
  if (s.arms) return st;
  for (double* v : {&st.force_scale, &st.torque_scale, &st.max_arrow, &st.arrow_width, &st.end_effector_radius,
                    &st.point_radius})
    *v *= 0.25;
  return st;
}

view::CameraSpec default_device_camera(const DeviceSceneSetup& s) {
  view::CameraSpec c;
  if (s.arms) {
    // Between the hands (0.7 m in front of the column) and the shoulders,
    // seen from behind the operator's right shoulder.
    c.lookat = Eigen::Vector3d(-0.45, 0.0, 0.3);
    c.distance = 1.7;
    c.azimuth = 30.0;
    c.elevation = -35.0;
  } else {
    c.lookat = s.T_H_W * Eigen::Vector3d::Zero();
    c.distance = 0.6;
    c.azimuth = 30.0;
    c.elevation = -35.0;
  }
  return c;
}


view::Overlay make_device_overlay(const DeviceSceneSetup& s, const DeviceViewRecord* t, const ServoHealth* servo) {
  view::Overlay o;
  auto row = [&](const char* k, const std::string& v) {
    o.left += std::string(k) + "\n";
    o.right += v + "\n";
  };
  row("device", s.device + (s.objects.empty() ? "" : overlay_text("  (%zu VPS objects)", s.objects.size())));
  if (servo != nullptr) {
    row("servo loop", overlay_text("period %.3f ms (p99 %.3f)  misses %" PRIu64 " (+%" PRIu64 " in %.1f s)  ticks %" PRIu64,
                          servo->period_median_ms, servo->period_p99_ms, servo->misses, servo->window_misses,
                          servo->window_s, servo->ticks));
    row("servo tick", servo_figures_text(*servo));
    o.plot = servo->histogram;
  }
  if (t == nullptr) {
    row("tick", "(none yet)");
  } else {
    row("tick", overlay_text("%" PRIu64, t->tick));
    const char* side[2] = {"right", "left"};
    for (std::size_t k = 0; k < static_cast<std::size_t>(std::clamp(t->end_effectors, 0, 2)); ++k)
      row(k == 0 ? "force / torque" : "",
          overlay_text("%s %.2f N  %.3f N m%s", side[k], t->force_H[k].norm(), t->torque_H[k].norm(),
              t->enabled[k] ? "" : "  (disabled)"));
    if (t->pairs > 0) {
      row("VPS", overlay_text("%.0f us this tick", static_cast<double>(t->vps_ns) * 1e-3));
      const char* pair[3] = {"right-scene", "left-scene", "right-left"};
      std::string pen;
      for (std::size_t i = 0; i < static_cast<std::size_t>(std::min(t->pairs, 3)); ++i)
        pen += overlay_text("%s%s %.2f mm (%d)", i > 0 ? "  " : "", pair[i], t->penetration_m[i] * 1e3, t->contacts[i]);
      row("penetration", pen);
      row("observer energy", overlay_text("%.4f J / %.4f J", t->energy_J[0], t->energy_J[1]));
    }
  }
  if (!o.left.empty()) o.left.pop_back();
  if (!o.right.empty()) o.right.pop_back();
  o.bottom = "c: camera back to the start   mouse: rotate, move, zoom";
  return o;
}

}  // namespace hemm::op
