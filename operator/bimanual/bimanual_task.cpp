#include "operator/bimanual/bimanual_task.h"

#include <algorithm>

namespace hemm::op {

void BimanualTask::tick(const device::DeviceSample& in, const servo::ModelSnapshot&, servo::TickOutput& out) noexcept {
  out.publish_setpoint = false;  // the bimanual station drives no robot yet
  out.renderer = "planes";      // closed forms: a plane and two springs per hand, no work to count
  out.work = 0;
  for (int k = 0; k < in.end_effectors && k < device::kMaxEndEffectors; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const device::EndEffectorSample& e = in.ee[i];
    const HandEnvironment& env = env_[i];
    device::EndEffectorCommand& c = out.command.ee[i];
    if (!have_start_[i]) {
      start_[i] = e.orientation_H;
      have_start_[i] = true;
    }
    if (!e.enabled) continue;  // braked: render nothing
    // The plane: one-sided spring-damper on the penetration.
    const double depth = (env.plane_point_H - e.position_H).dot(env.plane_normal_H);
    if (depth > 0.0) {
      const double f = env.plane_stiffness * depth - env.plane_damping * e.velocity_H.dot(env.plane_normal_H);
      c.force_H = std::max(f, 0.0) * env.plane_normal_H;
      out.points[i].proxy_position_H = e.position_H + depth * env.plane_normal_H;
    }
    // The orientation spring (shortest rotation back to the start).
    Eigen::Quaterniond dq = start_[i] * e.orientation_H.conjugate();
    if (dq.w() < 0.0) dq.coeffs() = -dq.coeffs();
    const Eigen::AngleAxisd aa(dq);
    c.torque_H = env.orientation_stiffness * aa.angle() * aa.axis() - env.orientation_damping * e.angular_velocity_H;
    // The object between the fingers.
    if (env.grip_object && e.handle.has_grip && e.handle.grip_position > env.grip_object_at_m)
      c.grip_force = env.grip_object_stiffness * (e.handle.grip_position - env.grip_object_at_m);
  }
  ++ticks_;
  if (view_ != nullptr) {  // filled in place: one copy of the record
    DeviceViewRecord& v = view_->back();
    fill_device_view(in, out, view_arms_, ticks_, v);
    v.objects = 0;
    v.pairs = 0;
    view_->publish();
  }
}

}  // namespace hemm::op
