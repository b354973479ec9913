#include "robot_side/twoarm/arms_wire.h"

#include <cmath>
#include <cstdio>
#include <utility>

#include "common/haptics/passivity/tdpa_wire.h"
#include "common/mapping/depth_stream.h"

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

namespace {

bool finite_pose(const proto::Pose3& p) {
  const auto& a = p.position();
  const auto& o = p.orientation();
  for (double v : {a.x(), a.y(), a.z(), o.w(), o.x(), o.y(), o.z()}) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

ArmsRefusal refusal(wire::ArmsRefusalReason r, uint32_t index, std::string detail) {
  return ArmsRefusal{r, index, std::move(detail)};
}

// Where a refused target was, against the grasp frame now: what an operator
// needs to tell a slip of the mapping from a pose at the edge of the reach.
std::string target_vs_grasp(const Eigen::Isometry3d& T, const Eigen::Isometry3d& G) {
  const Eigen::Vector3d p = T.translation();
  const Eigen::Vector3d z = T.linear().col(2);
  const double d_mm = 1e3 * (p - G.translation()).norm();
  const double d_rad = rotation_angle(G.linear(), T.linear());
  char buf[200];
  std::snprintf(buf, sizeof buf, " (target at %.3f %.3f %.3f m in A, z_G %.2f %.2f %.2f; %.0f mm and %.2f rad from G now)",
                p.x(), p.y(), p.z(), z.x(), z.y(), z.z(), d_mm, d_rad);
  return buf;
}

void vec(const Eigen::Vector3d& v, proto::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

}  // namespace

std::optional<ArmsRefusal> validate_arms_command(const TwoArmModel& model, const ArmsCommandLimits& limits,
                                                 const wire::ArmsCommand& cmd,
                                                 const std::array<ArmReading, kArms>& readings,
                                                 ValidatedArmsCommand* out) {
  ValidatedArmsCommand v;
  v.deadman = cmd.deadman();
  v.mode = cmd.mode();
  // Finite numbers and known, distinct indices first: cheap, and nothing
  // below runs on garbage.
  for (const wire::ArmTarget& a : cmd.arm()) {
    if (a.index() >= kArms || v.has_arm[a.index()])
      return refusal(wire::ARMS_REFUSAL_UNKNOWN_ARM, a.index(), "arm " + std::to_string(a.index()) + " unknown or named twice");
    v.has_arm[a.index()] = true;
    if (!finite_pose(a.t_a_g())) return refusal(wire::ARMS_REFUSAL_NONFINITE, a.index(), "arm target not finite");
  }
  for (const wire::GripperTarget& g : cmd.gripper()) {
    if (g.index() >= kArms || v.has_gripper[g.index()])
      return refusal(wire::ARMS_REFUSAL_UNKNOWN_GRIPPER, g.index(),
                     "gripper " + std::to_string(g.index()) + " unknown or named twice");
    v.has_gripper[g.index()] = true;
    if (!std::isfinite(g.opening_m()) || !std::isfinite(g.force_n()))
      return refusal(wire::ARMS_REFUSAL_NONFINITE, g.index(), "gripper target not finite");
  }
  for (const wire::DirectTwist& t : cmd.twist()) {
    if (t.index() >= kArms || v.has_twist[t.index()])
      return refusal(wire::ARMS_REFUSAL_UNKNOWN_ARM, t.index(), "twist of arm " + std::to_string(t.index()) + " unknown or named twice");
    v.has_twist[t.index()] = true;
    if (v.has_arm[t.index()])
      return refusal(wire::ARMS_REFUSAL_BAD_POSE, t.index(), "arm named with both a target pose and a twist");
    const Eigen::Vector3d lin(t.v_a().x(), t.v_a().y(), t.v_a().z());
    const Eigen::Vector3d ang(t.omega_a().x(), t.omega_a().y(), t.omega_a().z());
    if (!lin.allFinite() || !ang.allFinite())
      return refusal(wire::ARMS_REFUSAL_NONFINITE, t.index(), "twist not finite");
    v.twist[t.index()] = haptics::tdpa::ArmTwist{lin, ang};
  }
  for (const wire::PassivityPort& p : cmd.passivity()) {
    if (p.index() >= kArms || v.has_energy[p.index()])
      return refusal(wire::ARMS_REFUSAL_UNKNOWN_ARM, p.index(),
                     "passivity port of arm " + std::to_string(p.index()) + " unknown or named twice");
    v.has_energy[p.index()] = true;
    std::string why;
    if (!haptics::tdpa::read_energy_in(p, &v.peer_energy_in_J[p.index()], &why))
      return refusal(wire::ARMS_REFUSAL_PASSIVITY, p.index(), why);
  }
  for (const wire::GripperTarget& g : cmd.gripper()) {
    const GripperTarget t{g.opening_m(), g.force_n()};
    if (auto e = check_target(model.arms[g.index()].gripper, t))
      return refusal(wire::ARMS_REFUSAL_GRIPPER_RANGE, g.index(), *e);
    v.named.gripper[g.index()] = t;
  }
  for (const wire::ArmTarget& a : cmd.arm()) {
    const std::size_t i = a.index();
    Eigen::Isometry3d T;
    if (!a.has_t_a_g()) return refusal(wire::ARMS_REFUSAL_BAD_POSE, a.index(), "arm target without a pose");
    if (auto e = mapping::pose3_from_wire(a.t_a_g(), &T)) return refusal(wire::ARMS_REFUSAL_BAD_POSE, a.index(), *e);
    const Eigen::Isometry3d G = grasp_pose_A(model.arms[i], readings[i].q);
    if ((T.translation() - G.translation()).norm() > limits.max_target_jump_m)
      return refusal(wire::ARMS_REFUSAL_OUT_OF_REACH, a.index(),
                     "target more than max_target_jump_m from the grasp frame" + target_vs_grasp(T, G));
    const GraspReach reach = grasp_closest_reach(model.arms[i], T, readings[i].q);
    if (!reach.reached) {
      if (!(reach.position_error_m <= limits.reach_margin_m && reach.orientation_error_rad <= limits.reach_margin_rad)) {
        char far[96];
        std::snprintf(far, sizeof far, "; the closest within the limits %.0f mm and %.2f rad off", 1e3 * reach.position_error_m,
                      reach.orientation_error_rad);
        return refusal(wire::ARMS_REFUSAL_OUT_OF_REACH, a.index(),
                       "no joint angles within the limits reach the target" + target_vs_grasp(T, G) + far);
      }
      v.at_reach_edge[i] = true;
      v.reach_error_m[i] = reach.position_error_m;
      v.reach_error_rad[i] = reach.orientation_error_rad;
    }
    v.named.T_A_G[i] = T;
  }
  *out = v;
  return std::nullopt;
}

TwoArmTargets merge_arms_command(const TwoArmTargets& current, const ValidatedArmsCommand& v) noexcept {
  TwoArmTargets next = current;
  for (std::size_t i = 0; i < kArms; ++i) {
    if (v.has_arm[i]) next.T_A_G[i] = v.named.T_A_G[i];
    if (v.has_gripper[i]) next.gripper[i] = v.named.gripper[i];
  }
  return next;
}

std::optional<ArmsRefusal> check_energy_not_decreasing(const ValidatedArmsCommand& v, const PeerEnergyRecord& r) {
  for (std::size_t i = 0; i < kArms; ++i) {
    if (v.has_energy[i] && r.have[i] && (v.peer_energy_in_J[i].array() < r.energy_in_J[i].array()).any())
      return refusal(wire::ARMS_REFUSAL_PASSIVITY, static_cast<uint32_t>(i),
                     "passivity port of arm " + std::to_string(i) + ": input energy below the last one taken");
  }
  return std::nullopt;
}

void note_energy(const ValidatedArmsCommand& v, PeerEnergyRecord* r) noexcept {
  for (std::size_t i = 0; i < kArms; ++i) {
    if (!v.has_energy[i]) continue;
    r->have[i] = true;
    r->energy_in_J[i] = v.peer_energy_in_J[i];
  }
}

ArmsCommandResult apply_arms_command(const TwoArmModel& model, const ArmsCommandLimits& limits,
                                     const wire::ArmsCommand& cmd, const TwoArmTargets& current,
                                     const std::array<ArmReading, kArms>& readings) {
  ArmsCommandResult out;
  ValidatedArmsCommand v;
  if (auto r = validate_arms_command(model, limits, cmd, readings, &v)) {
    out.refusal = std::move(*r);
    return out;
  }
  out.targets = merge_arms_command(current, v);
  return out;
}

void to_wire(const TwoArmTargets& targets, bool deadman, wire::ArmsCommand* out) {
  out->Clear();
  out->set_deadman(deadman);
  for (uint32_t i = 0; i < kArms; ++i) {
    wire::ArmTarget* a = out->add_arm();
    a->set_index(i);
    mapping::pose3_to_wire(targets.T_A_G[i], a->mutable_t_a_g());
    wire::GripperTarget* g = out->add_gripper();
    g->set_index(i);
    g->set_opening_m(targets.gripper[i].opening_m);
    g->set_force_n(targets.gripper[i].force_N);
  }
}

void to_wire(const TwoArmModel& model, const std::array<ArmReading, kArms>& readings, const TwoArmTargets& targets,
             const TwoArmOutput& c, int64_t stamp_ns, wire::ArmsState* out) {
  (void)model;
  out->clear_arm();
  out->clear_gripper();
  out->set_stamp_ns(stamp_ns);
  for (uint32_t i = 0; i < kArms; ++i) {
    const ArmReading& r = readings[i];
    const ImpedanceOutput& a = c.arm[i];
    wire::ArmState* s = out->add_arm();
    s->set_index(i);
    for (int j = 0; j < hk::kArm7Dof; ++j) {
      s->add_q(r.q(j));
      s->add_qd(r.qd(j));
      s->add_tau(a.tau(j));
    }
    mapping::pose3_to_wire(a.T_A_G, s->mutable_t_a_g());
    vec(a.twist_A.head<3>(), s->mutable_v_a());
    vec(a.twist_A.tail<3>(), s->mutable_omega_a());
    vec(c.wrench_ext_A[i].head<3>(), s->mutable_force_a());
    vec(c.wrench_ext_A[i].tail<3>(), s->mutable_torque_a());
    mapping::pose3_to_wire(targets.T_A_G[i], s->mutable_t_a_g_target());
    s->set_force_limited(a.force_limited);
    wire::GripperState* g = out->add_gripper();
    g->set_index(i);
    g->set_opening_m(c.gripper[i].opening_m);
    g->set_grip_force_n(c.gripper[i].grip_force_N);
    g->set_holding(c.gripper[i].holding);
    g->set_target_opening_m(targets.gripper[i].opening_m);
    g->set_target_force_n(targets.gripper[i].force_N);
  }
  out->set_min_arm_arm_m(std::isfinite(c.avoidance.min_arm_arm_m) ? c.avoidance.min_arm_arm_m : 0.0);
}

std::optional<std::string> check_arms_state(const wire::ArmsState& s) {
  if (s.arm_size() > 16 || s.gripper_size() > 16) return "arms state: more than 16 arms or grippers";
  for (const wire::ArmState& a : s.arm()) {
    if (a.q_size() != hk::kArm7Dof || a.qd_size() != hk::kArm7Dof || a.tau_size() != hk::kArm7Dof)
      return "arms state: arm " + std::to_string(a.index()) + " without 7 joint values";
    for (int j = 0; j < hk::kArm7Dof; ++j) {
      if (!std::isfinite(a.q(j)) || !std::isfinite(a.qd(j)) || !std::isfinite(a.tau(j)))
        return "arms state: non-finite joint value";
    }
    Eigen::Isometry3d T;
    if (auto e = mapping::pose3_from_wire(a.t_a_g(), &T)) return "arms state: T_A_G: " + *e;
    for (const proto::Vec3* v : {&a.v_a(), &a.omega_a(), &a.force_a(), &a.torque_a()}) {
      if (!std::isfinite(v->x()) || !std::isfinite(v->y()) || !std::isfinite(v->z())) return "arms state: non-finite twist or wrench";
    }
  }
  for (const wire::GripperState& g : s.gripper()) {
    if (!std::isfinite(g.opening_m()) || !std::isfinite(g.grip_force_n())) return "arms state: non-finite gripper value";
  }
  return std::nullopt;
}

}  // namespace hemm::twoarm
