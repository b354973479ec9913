#include "operator/telemanip/telemanip_report.h"

namespace hemm::op::telemanip {

namespace {

void telereport_vec(const Eigen::Vector3d& v, report::TelemanipVec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

}  // namespace

report::Telemanip make_telemanip_report(const TelemanipLinkStats& link, const TelemanipTask& task,
                                        const RemoteArmsState* remote, const servo::TimingSummary* timing) {
  report::Telemanip r;
  r.set_commands_sent(link.commands_sent);
  r.set_deadman_pressed(link.deadman_pressed);
  r.set_stale(link.stale);
  r.set_send_failures(link.send_failures);
  r.set_link_down(link.link_down);
  r.set_states_in(link.states_in);
  r.set_states_rejected(link.states_rejected);
  r.set_states_reordered(link.states_reordered);
  report::TelemanipRefusals* f = r.mutable_refusals();
  const ArmsRefusalSummary& s = link.refusals;
  f->set_refused(s.refused);
  f->set_events(s.events);
  f->set_nonfinite(s.by_reason[wire::ARMS_REFUSAL_NONFINITE]);
  f->set_unknown_arm(s.by_reason[wire::ARMS_REFUSAL_UNKNOWN_ARM]);
  f->set_unknown_gripper(s.by_reason[wire::ARMS_REFUSAL_UNKNOWN_GRIPPER]);
  f->set_bad_pose(s.by_reason[wire::ARMS_REFUSAL_BAD_POSE]);
  f->set_out_of_reach(s.by_reason[wire::ARMS_REFUSAL_OUT_OF_REACH]);
  f->set_gripper_range(s.by_reason[wire::ARMS_REFUSAL_GRIPPER_RANGE]);
  f->set_last_reason(short_name(s.last_reason));
  f->set_last_seq(s.last_seq);
  f->set_last_index(s.last_index);
  f->set_bad_reports(s.errors);
  for (int k = 0; k < kTeleArms; ++k) {
    report::TelemanipHand* h = r.add_hand();
    const ArmMappingState& m = task.mapping(k);
    const HandRenderStats& st = task.render_stats(k);
    h->set_index(static_cast<std::uint32_t>(k));
    h->set_presses(m.presses);
    h->set_engaged_ticks(st.engaged_ticks);
    h->set_clamped_steps(m.clamped_steps);
    h->set_contact_ticks(st.contact_ticks);
    h->set_no_model_ticks(st.no_model_ticks);
    h->set_peak_force_n(st.peak_force_n);
    h->set_mean_contact_force_n(st.contact_ticks > 0 ? st.sum_force_n / static_cast<double>(st.contact_ticks) : 0.0);
    telereport_vec(st.last_force_D, h->mutable_last_force_d());
    telereport_vec(m.T_A_G_cmd.translation(), h->mutable_commanded_p_a());
    if (remote != nullptr && remote->valid) telereport_vec(remote->arm[static_cast<std::size_t>(k)].p_A, h->mutable_remote_p_a());
  }
  if (timing != nullptr) servo::fill(r.mutable_timing(), *timing);
  r.set_rendering(task.params().render);
  r.set_gripper_shells(static_cast<std::uint32_t>(task.grippers().tools.size()));
  if (!task.grippers().tools.empty()) r.set_shell_points(task.grippers().tools.back().shell.size());
  return r;
}

}  // namespace hemm::op::telemanip
