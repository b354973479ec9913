#include "operator/telemanip/telemanip_report.h"

#include <cmath>
#include <sstream>

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
    h->set_clutch_ticks(m.clutch_steps);
    h->set_contact_ticks(st.contact_ticks);
    h->set_no_model_ticks(st.no_model_ticks);
    h->set_grasp_ticks(st.grasp_ticks);
    h->set_peak_force_n(st.peak_force_n);
    h->set_mean_contact_force_n(st.contact_ticks > 0 ? st.sum_force_n / static_cast<double>(st.contact_ticks) : 0.0);
    telereport_vec(st.last_force_D, h->mutable_last_force_d());
    telereport_vec(m.T_A_G_cmd.translation(), h->mutable_commanded_p_a());
    if (remote != nullptr && remote->valid) telereport_vec(remote->arm[static_cast<std::size_t>(k)].p_A, h->mutable_remote_p_a());
    h->set_felt_weight_n(task.held().weight_n[static_cast<std::size_t>(k)]);
  }
  r.set_held_holds(task.held().holds);
  r.set_held_ticks(task.held().held_ticks);
  r.set_held_peak_squeeze_n(task.held().peak_squeeze_n);
  if (timing != nullptr) servo::fill(r.mutable_timing(), *timing);
  r.set_mode(to_string(task.params().mode));
  r.set_ports_rejected(link.ports_rejected);
  r.set_wrenches_rejected(link.wrenches_rejected);
  r.set_direct_commands(link.direct_commands);
  r.set_passivity_resets(task.direct_resets());
  if (task.params().mode == FeedbackMode::kDirect) {
    for (int k = 0; k < kTeleArms; ++k) {
      const DirectHandState& d = task.direct_hand(k);
      const DirectHandStats& st = d.stats;
      const haptics::tdpa::ArmPortSummary p = haptics::tdpa::summarize(d.side);
      report::TelemanipDirectHand* h = r.add_direct();
      h->set_index(static_cast<std::uint32_t>(k));
      h->set_energy_in_j(p.in_J);
      h->set_energy_out_j(p.out_J);
      h->set_peer_energy_in_j(p.peer_in_J);
      h->set_dissipated_j(p.dissipated_J);
      h->set_min_margin_j(p.min_margin_J);
      h->set_pc_active_ticks(p.pc_active_ticks);
      h->set_ticks(st.ticks);
      h->set_peer_accepted(st.peer_accepted);
      h->set_peer_old(d.side.peer_old);
      h->set_peer_refused(d.side.peer_refused);
      h->set_contact_ticks(st.contact_ticks);
      const double n = static_cast<double>(st.contact_ticks);
      h->set_wrench_error_rms_n(st.contact_ticks > 0 ? std::sqrt(st.error_sum_sq / n) : 0.0);
      h->set_wrench_error_max_n(st.error_max_n);
      h->set_mean_shown_n(st.contact_ticks > 0 ? st.shown_sum_n / n : 0.0);
      h->set_mean_wrist_n(st.contact_ticks > 0 ? st.wrist_sum_n / n : 0.0);
      h->set_peak_shown_n(st.peak_shown_n);
      h->set_pc_on(task.params().direct[static_cast<std::size_t>(k)].pc_mode == haptics::tdpa::PcMode::kControl);
    }
  }
  r.set_rendering(task.params().render);
  r.set_gripper_shells(static_cast<std::uint32_t>(task.grippers().tools.size()));
  if (!task.grippers().tools.empty()) r.set_shell_points(task.grippers().tools.back().shell.size());
  return r;
}

void set_suggested_mode(report::Telemanip* r, FeedbackMode in_use, double round_trip_s, double loss,
                        const haptics::tdpa::ModeThresholds& t) {
  namespace td = haptics::tdpa;
  const td::FeedbackMode cur = in_use == FeedbackMode::kDirect ? td::FeedbackMode::kDirect : td::FeedbackMode::kModelMediated;
  const td::FeedbackMode s = td::suggest_mode(round_trip_s, loss, cur, t);
  r->set_suggested_mode(s == td::FeedbackMode::kDirect ? "direct" : "model");
  r->set_round_trip_ms(1e3 * round_trip_s);
  r->set_loss(loss);
}

std::string direct_summary(const report::Telemanip& r) {
  std::ostringstream o;
  o << "telemanip: mode " << r.mode() << ", suggested " << r.suggested_mode() << " (round trip " << r.round_trip_ms()
    << " ms, loss " << r.loss() << ")\n";
  for (const report::TelemanipDirectHand& h : r.direct())
    o << "telemanip: direct hand " << h.index() << ": E_in " << h.energy_in_j() << " J, E_out " << h.energy_out_j()
      << " J within the robot's " << h.peer_energy_in_j() << " J (margin " << h.min_margin_j() << " J), dissipated "
      << h.dissipated_j() << " J, controller active " << h.pc_active_ticks() << " of " << h.ticks()
      << " ticks; contact ticks " << h.contact_ticks() << ": shown " << h.mean_shown_n() << " N against wrist "
      << h.mean_wrist_n() << " N, error rms " << h.wrench_error_rms_n() << " N, max " << h.wrench_error_max_n()
      << " N\n";
  return o.str();
}

}  // namespace hemm::op::telemanip
