#include "robot_side/view/twoarm_scene.h"

#include <cstdio>

#include "wire.pb.h"

namespace hemm::robot {

std::string safety_text(std::uint32_t s) {
  std::string out;
  auto add = [&](std::uint32_t bit, const char* name) {
    if (s & bit) out += std::string(out.empty() ? "" : " ") + name;
  };
  add(wire::SAFETY_NO_OPERATOR, "no-operator");
  add(wire::SAFETY_WATCHDOG, "watchdog");
  add(wire::SAFETY_COLLISION_GUARD, "guard");
  add(wire::SAFETY_ESTOP, "E-STOP");
  add(wire::SAFETY_JOINT_LIMIT, "joint-limit");
  add(wire::SAFETY_LINK_LOST, "link-lost");
  add(wire::SAFETY_REARM, "re-arm");
  return out.empty() ? "ok" : out;
}

void build_twoarm_scene(const TwoArmViewFrame& f, const Eigen::Isometry3d& T_W_A, const TwoArmSceneStyle& style,
                        view::PrimitiveList& out) {
  namespace c = twoarm_view_colours;
  out.clear();
  const twoarm::TwoArmSnapshot& s = f.snapshot;
  for (std::size_t a = 0; a < twoarm::kArms; ++a) {
    const Eigen::Isometry3d T_W_target = T_W_A * s.targets.T_A_G[a];
    const Eigen::Isometry3d T_W_G = T_W_A * s.control.arm[a].T_A_G;
    const Eigen::Vector3d p = T_W_target.translation();
    out.sphere(p, style.target_radius, c::kArm[a]);
    const view::Rgba axis[3] = {{0.9f, 0.1f, 0.1f, 1.0f}, {0.1f, 0.9f, 0.1f, 1.0f}, {0.1f, 0.1f, 0.9f, 1.0f}};
    for (int k = 0; k < 3; ++k) out.line(p, p + style.axis_length * T_W_target.linear().col(k), 2.0, axis[k]);
    out.line(T_W_G.translation(), p, 2.0, c::kArm[a]);
    const Eigen::Vector3d force_W = T_W_A.linear() * s.control.wrench_ext_A[a].head<3>();
    if (force_W.norm() * style.force_scale > 1e-3)
      out.arrow(T_W_G.translation(), T_W_G.translation() + style.force_scale * force_W, 0.01,
                s.control.arm[a].force_limited ? c::kYielding : c::kWrench);
  }
  for (int i = 0; i < f.ncontacts; ++i) {
    const SimContact& k = f.contacts[static_cast<std::size_t>(i)];
    out.sphere(k.pos_W, style.contact_radius, c::kContact);
    if (k.force_W.norm() * style.force_scale > 1e-3)
      out.arrow(k.pos_W, k.pos_W + style.force_scale * k.force_W, 0.006, c::kContact);
  }
}

view::Overlay twoarm_overlay(const TwoArmViewFrame& f, std::int64_t t0_ns) {
  const twoarm::TwoArmSnapshot& s = f.snapshot;
  view::Overlay o;
  o.left = "SIMULATION\nsafety\narms\nright\nleft\ntask\nlink";
  char arm[2][160];
  bool yielding = false;
  for (std::size_t a = 0; a < twoarm::kArms; ++a) {
    const twoarm::GripperState& g = s.control.gripper[a];
    yielding = yielding || s.control.arm[a].force_limited;
    std::snprintf(arm[a], sizeof arm[a], "wrist %.1f N%s, gripper %.0f mm, squeeze %.1f N%s",
                  s.control.wrench_ext_A[a].head<3>().norm(), s.control.arm[a].force_limited ? " (yielding)" : "",
                  1e3 * g.opening_m, g.grip_force_N, g.holding ? ", holding" : "");
  }
  char task[200] = "-";
  if (f.has_task)
    std::snprintf(task, sizeof task, "%s%s%s, tilt %.2f rad, squeeze %.1f N, object contact %.1f N",
                  f.lifted ? "lifted" : "not lifted", f.task.goal ? ", at its goal" : "",
                  f.dropped ? ", DROPPED" : "", f.task.tilt_rad, f.task.squeeze_N, f.task.object_env_force_N);
  char buf[900];
  std::snprintf(buf, sizeof buf, "t %.2f s\n%s\n%s%s\n%s\n%s\n%s\n%s%s (%d contacts%s)",
                static_cast<double>(f.t_ns - t0_ns) * 1e-9, safety_text(s.safety).c_str(),
                s.armed ? "armed" : "not armed", s.following ? ", following" : ", holding", arm[0], arm[1], task,
                f.link_up ? "up" : "down", f.in_control ? ", operator in control" : "", f.contacts_seen,
                f.contacts_seen > f.ncontacts ? ", some not drawn" : "");
  o.right = buf;
  o.bottom = "c: camera (follow / free / top)   mouse: rotate, move, zoom";
  const view::Rgba red{0.85f, 0.05f, 0.05f, 1.0f}, orange{0.85f, 0.45f, 0.05f, 1.0f};
  if (s.safety & wire::SAFETY_ESTOP) o.banners.push_back({"E-STOP", red});
  if (!f.link_up) o.banners.push_back({"NO OPERATOR LINK", orange});
  if (yielding) o.banners.push_back({"WRIST FORCE LIMIT", red});
  if (f.has_task && f.dropped) o.banners.push_back({"DROPPED", red});
  return o;
}

}  // namespace hemm::robot
