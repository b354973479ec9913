#include "operator/station/operator_station.h"

#include <algorithm>
#include <bit>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <future>
#include <sstream>
#include <stdexcept>

#include <spdlog/spdlog.h>

#include "common/clock/steady_clock.h"
#include "common/config/config.h"
#include "common/net/station_cli.h"
#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/device/trajectory_csv.h"
#include "operator/station/demo_scripts.h"
#include "operator/station/tool6_bimanual.h"
#include "operator/station/tool6_explorer.h"
#include "config_operator.pb.h"
#include "report.pb.h"

namespace hemm::op {

void apply_probe3d_config(const config::Probe3dConfig& c, OperatorStationOptions* o) {
  if (!c.enabled()) return;
  o->model.live_voxmap = true;
  o->model.voxmap.voxel_size = c.voxel_size_m();
  o->model.voxmap.downsample_leaf = 0.5 * c.voxel_size_m();
  // Two image rows of the SIMULATED mast camera on a table top (live_voxmap.h).
  o->model.voxmap.normal_radius = std::max(0.05, 2.5 * c.voxel_size_m());
  o->model.voxmap.clear_margin = std::max(o->model.voxmap.clear_margin, 1.5 * c.voxel_size_m());
  o->model.voxmap.shape_completion = c.shape_completion();
  o->model.voxmap.unknown_solid = c.unknown_solid();
  o->model.shape_log_dir = c.shape_log_dir();
  o->model.voxmap_roi_R = Eigen::AlignedBox3d(Eigen::Vector3d(c.roi_x_min_m(), -c.roi_half_width_m(), c.roi_z_min_m()),
                                              Eigen::Vector3d(c.roi_x_max_m(), c.roi_half_width_m(), c.roi_z_max_m()));
  o->model.voxmap_rate_hz = c.rebuild_rate_hz();
  // Around the probe (validated "probe" or "robot"): re-centred when the
  // probe comes within a quarter of the cube's edge of a face.
  o->model.voxmap_roi = c.roi() == "robot" ? VoxmapRoi::kRobot : VoxmapRoi::kProbe;
  o->model.voxmap_probe_roi.size = c.roi_size_m();
  o->model.voxmap_probe_roi.margin = 0.25 * c.roi_size_m();
  // Issue 24: the depth camera's gaze and the registration of its frames.
  o->gaze = c.gaze();
  o->gaze_params.lookahead_s = c.gaze_lookahead_s();
  o->gaze_params.hysteresis_m = c.gaze_hysteresis_m();
  o->model.depth_registration = c.depth_registration();
  if (c.tool() == "pointshell") {  // the 6-DoF tool in place of the point probe
    o->task.tool6.enabled = true;
    o->task.tool6.budget = c.tool_work_budget();
    o->task.tool6.tick_budget_ns = std::llround(c.tool_tick_budget_us() * 1e3);
    o->task.tool6.tick_margin_ns = std::llround(c.tool_tick_margin_us() * 1e3);
    o->task.tool6.calibration_voxel = c.voxel_size_m();
    o->task.tool6.calibration_layers = o->model.voxmap.layers;
    o->task.tool6.contact_stiffness = c.tool_contact_stiffness();
    o->task.tool6.inferred_stiffness_scale = c.inferred_stiffness();
    o->task.tool6.origin_R = Eigen::Vector3d(c.origin_x_m(), 0.0, c.origin_z_m());
    o->hand6_script = c.tool_hand_script();
    o->hand6_route_file = c.tool_hand_route();  // as given: relative to the config file (station_runner resolves it)
    o->tool_device_offset_D =
        Eigen::Vector3d(c.tool_device_offset_x_m(), c.tool_device_offset_y_m(), c.tool_device_offset_z_m());
    return;
  }
  o->task.probe_3d = true;
  o->task.probe3d.force = o->task.proxy;
  o->task.probe3d.force.probe_radius = c.probe_radius_m();
  o->task.probe3d_range = c.range_m();
  o->task.probe3d_origin_R = Eigen::Vector3d(c.origin_x_m(), 0.0, c.origin_z_m());
  // The tool probe of manipulation (operator_task.h tool_probe_radius) needs
  // the signed distance to reach past its radius: rho < (layers - 0.5)
  // voxels, as probe_radius_m's check (6 layers for 5 cm at 1 cm voxels).
  o->model.voxmap.layers = std::max(
      o->model.voxmap.layers, static_cast<int>(std::ceil(o->task.tool_probe_radius / c.voxel_size_m() + 0.5 + 1e-9)));
}

namespace {
// The robot answers an EStop within a round trip and a simulation step; this
// allows for round trips of seconds (the link's own limit is 2 s).
constexpr std::chrono::milliseconds kAckTimeout{5000};

// The task hands the view it wrote (the task's own OperatorView) to the
// closed-loop hand's mailbox right after each tick.
class ViewPublishingTask final : public servo::ServoTask {
 public:
  ViewPublishingTask(servo::ServoTask& task, const OperatorView& written, NewestMailbox<OperatorView>& box)
      : task_(task), written_(written), box_(box) {}
  void on_servo_start() noexcept override { task_.on_servo_start(); }
  void on_servo_stop() noexcept override { task_.on_servo_stop(); }
  void tick(const device::DeviceSample& in, const servo::ModelSnapshot& model,
            servo::TickOutput& out) noexcept override {
    task_.tick(in, model, out);
    box_.publish(written_);
  }

 private:
  servo::ServoTask& task_;
  const OperatorView& written_;
  NewestMailbox<OperatorView>& box_;
};

// The closed-loop hand takes the newest view into its own copy (`seen`, the
// one it was made with) right before it decides.
class ViewTakingHand final : public device::HandScript {
 public:
  ViewTakingHand(std::shared_ptr<const device::HandScript> hand, std::shared_ptr<OperatorView> seen,
                 std::shared_ptr<NewestMailbox<OperatorView>> box)
      : hand_(std::move(hand)), seen_(std::move(seen)), box_(std::move(box)) {}
  device::HandTarget at(double t_s) const noexcept override {
    if (const OperatorView* v = box_->take()) *seen_ = *v;
    return hand_->at(t_s);
  }

 private:
  std::shared_ptr<const device::HandScript> hand_;
  std::shared_ptr<OperatorView> seen_;
  std::shared_ptr<NewestMailbox<OperatorView>> box_;
};

}  // namespace

std::string to_string(const OperatorStationSummary& s) {
  std::ostringstream o;
  o << "servo: " << servo::to_string(s.timing) << "\n"
    << "servo worst ticks: " << rt::worst_ticks_text(s.timing.worst) << "\n"
    << "model: scans_in=" << s.model.scans_in << " scans_rejected=" << s.model.scans_rejected
    << " scans_dropped=" << s.model.scans_dropped << " states_in=" << s.model.states_in
    << " states_rejected=" << s.model.states_rejected << " snapshots=" << s.model.snapshots
    << " robot_restarts=" << s.model.resyncs << "\n"
    << "registration: accepted=" << s.model.registration.accepted << " rejected=" << s.model.registration.rejected
    << " degenerate=" << s.model.registration.degenerate << " limited=" << s.model.registration.limited
    << " last_rms_m=" << s.model.registration.last_rms << " max_rms_m=" << s.model.registration.max_rms
    << " max_step_m=" << s.model.registration.max_step
    << " correction=(" << s.model.registration.correction.x << ", " << s.model.registration.correction.y << ", "
    << s.model.registration.correction.theta << ")\n"
    << "shapes: circles=" << s.model.shapes.circles << " rectangles=" << s.model.shapes.rectangles
    << " lines=" << s.model.shapes.lines
    << " bridges=" << s.model.shapes.bridges << " kept=" << s.model.shapes.kept << " raw_replaced=" << s.model.shapes.raw_replaced
    << " max_circle_rms_m=" << s.model.shapes.max_circle_rms_m << " fit_ms last=" << s.model.shapes.last_fit_ms
    << " max=" << s.model.shapes.max_fit_ms << "\n"
    << "commands: sent=" << s.commands.commands_sent << " failures=" << s.commands.send_failures
    << " link_down=" << s.commands.link_down << " mode_changes=" << s.commands.mode_changes_sent << " stale=" << s.commands.stale
    << " mode_switches=" << s.mode_switches << " deadman_pressed=" << s.commands.deadman_pressed << "\n"
    << "device: nonfinite_poses=" << s.device_nonfinite_poses
    << (s.device_nonfinite_poses > 0 ? " (all motion was held on those ticks)" : "") << "\n"
    << "e-stop: device presses=" << s.estop_presses << " sent=" << s.commands.estops_sent
    << " acknowledged=" << s.estop_acks << " refused=" << s.estop_refusals << " robot reports "
    << (s.robot_estop < 0 ? "nothing" : s.robot_estop ? "engaged" : "released") << "\n"
    << "arm targets refused by the robot: " << s.arm_refusals.refused << " (floor " << s.arm_refusals.floor
    << ", base " << s.arm_refusals.base << ", scene " << s.arm_refusals.scene << " of " << s.arm_refusals.events
    << " reports), last " << short_name(s.arm_refusals.last_reason) << " seq=" << s.arm_refusals.last_seq
    << ", bad reports " << s.arm_refusals.errors << "\n"
    << "logs: servo written=" << s.servo_log_written << " dropped=" << s.servo_log_dropped
    << " world written=" << s.world_log_written << " dropped=" << s.world_log_dropped << "\n";
  o << "robot (predicted): x=" << s.robot_pose.x << " y=" << s.robot_pose.y << " theta=" << s.robot_pose.theta
    << (s.robot_pose_valid ? "" : " (no robot state)") << "\n";
  if (s.has_goal)
    o << "nav-to-goal: goal=(" << s.goal_W.x() << ", " << s.goal_W.y() << ") arrived=" << (s.arrived ? "yes" : "no")
      << " distance_m=" << s.goal_distance_m << " first_arrival_s=" << s.first_arrival_s
      << " arrivals=" << s.arrivals << " goal " << s.goal_index + 1 << "/" << s.route_size << "\n";
  if (s.has_tool6) {
    o << "tool6 budget: " << to_string(s.tool6_budget) << "\n";
    o << "tool6 inferred force share: " << s.tool6_inferred_force_share << " (" << s.tool6_inferred_contact_ticks
      << " of " << s.tool6_contact_ticks << " contact ticks)\n";
  }
  return o.str();
}

report::OperatorStation to_report(const OperatorStationSummary& s) {
  report::OperatorStation r;
  servo::fill(r.mutable_timing(), s.timing);
  report::LocalModel& m = *r.mutable_model();
  m.set_scans_in(s.model.scans_in);
  m.set_scans_rejected(s.model.scans_rejected);
  m.set_scans_dropped(s.model.scans_dropped);
  m.set_states_in(s.model.states_in);
  m.set_states_rejected(s.model.states_rejected);
  m.set_commands_dropped(s.model.commands_dropped);
  m.set_snapshots(s.model.snapshots);
  m.set_freed(s.model.freed);
  m.set_registration_attempted(s.model.registration.attempted);
  m.set_registration_accepted(s.model.registration.accepted);
  m.set_registration_rejected(s.model.registration.rejected);
  m.set_registration_degenerate(s.model.registration.degenerate);
  m.set_registration_last_rms_m(s.model.registration.last_rms);
  m.set_registration_last_step_m(s.model.registration.last_step);
  m.set_registration_limited(s.model.registration.limited);
  m.set_registration_max_rms_m(s.model.registration.max_rms);
  m.set_registration_last_inlier_ratio(s.model.registration.last_inlier_ratio);
  m.set_registration_max_step_m(s.model.registration.max_step);
  m.set_correction_x_m(s.model.registration.correction.x);
  m.set_correction_y_m(s.model.registration.correction.y);
  m.set_correction_theta_rad(s.model.registration.correction.theta);
  const ShapeStats& sh = s.model.shapes;
  m.set_shape_fits(sh.fits);
  m.set_shape_circles(sh.circles);
  m.set_shape_lines(sh.lines);
  m.set_shape_bridges(sh.bridges);
  m.set_shape_kept(sh.kept);
  m.set_shape_rectangles(sh.rectangles);
  m.set_shape_rectangles_kept(sh.rectangles_kept);
  m.set_shape_max_rectangle_rms_m(sh.max_rectangle_rms_m);
  m.set_shape_raw_replaced(sh.raw_replaced);
  m.set_shape_max_circle_rms_m(sh.max_circle_rms_m);
  m.set_shape_last_fit_ms(sh.last_fit_ms);
  m.set_shape_max_fit_ms(sh.max_fit_ms);
  m.set_shape_raw_replaced_bytes(sh.raw_replaced_bytes);
  m.set_shape_primitive_bytes(sh.primitive_bytes);
  m.set_shape_outline_bytes(sh.outline_bytes);
  m.set_resyncs(s.model.resyncs);
  m.set_old_epoch_dropped(s.model.old_epoch_dropped);
  const VoxmapStats& vx = s.model.voxmap;
  m.set_voxmap_chunks_accepted(vx.stream.accepted);
  m.set_voxmap_chunks_stale(vx.stream.stale);
  m.set_voxmap_chunks_malformed(vx.stream.malformed);
  m.set_voxmap_chunks_dropped(vx.chunks_dropped);
  m.set_voxmap_chunks_integrated(vx.chunks_integrated);
  m.set_voxmap_builds(vx.builds);
  m.set_voxmap_cells(vx.cells);
  m.set_voxmap_occupied_cells(vx.occupied_cells);
  m.set_voxmap_cell_bytes(vx.memory_bytes);
  m.set_voxmap_snapshot_bytes(vx.snapshot_bytes);
  m.set_voxmap_last_build_ms(vx.last_build_ms);
  m.set_voxmap_max_build_ms(vx.max_build_ms);
  m.set_voxmap_max_integrate_ms(vx.max_integrate_ms);
  m.set_voxmap_roi_moves(vx.roi_moves);
  m.set_voxmap_roi_on_probe(vx.roi_on_probe);
  m.set_voxmap_restarts(vx.restarts);
  m.set_voxmap_old_epoch_chunks(vx.old_epoch_chunks);
  const mapping::DepthRegistrationStats& dr = vx.registration;
  if (dr.frames > 0) {
    m.set_depth_reg_frames(dr.frames);
    m.set_depth_reg_accepted(dr.accepted);
    m.set_depth_reg_too_few_points(dr.too_few_points);
    m.set_depth_reg_no_surface(dr.no_surface);
    m.set_depth_reg_poor_fit(dr.poor_fit);
    m.set_depth_reg_no_gain(dr.no_gain);
    m.set_depth_reg_degenerate(dr.degenerate);
    m.set_depth_reg_step_too_large(dr.step_too_large);
    m.set_depth_reg_last_rmse_before_m(dr.last_rmse_before_m);
    m.set_depth_reg_last_rmse_after_m(dr.last_rmse_after_m);
    m.set_depth_reg_max_step_m(dr.max_step_m);
    if (dr.truth_frames > 0) {
      const double n = static_cast<double>(dr.truth_frames);
      m.set_depth_reg_mean_error_before_m(dr.sum_error_before_m / n);
      m.set_depth_reg_mean_error_after_m(dr.sum_error_after_m / n);
      m.set_depth_reg_mean_error_before_rad(dr.sum_error_before_rad / n);
      m.set_depth_reg_mean_error_after_rad(dr.sum_error_after_rad / n);
      m.set_depth_reg_mean_point_error_before_m(dr.sum_point_error_before_m / n);
      m.set_depth_reg_mean_point_error_after_m(dr.sum_point_error_after_m / n);
    }
  }
  m.set_voxmap_primitives(vx.newest.primitives);
  m.set_voxmap_boxes(vx.newest.boxes);
  m.set_voxmap_cylinders(vx.newest.cylinders);
  m.set_voxmap_spheres(vx.newest.spheres);
  m.set_voxmap_primitives_kept(vx.newest.primitives_kept);
  m.set_voxmap_primitives_refused_free(vx.newest.primitives_refused_free);
  m.set_voxmap_cells_completed(vx.newest.cells_completed);
  m.set_voxmap_voxels_primitive(vx.newest.voxels_primitive);
  m.set_voxmap_voxels_inferred(vx.newest.voxels_inferred);
  m.set_voxmap_voxels_unknown(vx.newest.voxels_unknown);
  const double builds = std::max<double>(1.0, static_cast<double>(vx.builds));
  m.set_voxmap_last_completion_ms(1e-6 * static_cast<double>(vx.newest.completion_ns));
  m.set_voxmap_max_completion_ms(vx.max_completion_ms);
  m.set_voxmap_mean_completion_ms(vx.sum_completion_ms / builds);
  m.set_voxmap_last_unknown_ms(1e-6 * static_cast<double>(vx.newest.unknown_ns));
  m.set_voxmap_max_unknown_ms(vx.max_unknown_ms);
  m.set_voxmap_mean_unknown_ms(vx.sum_unknown_ms / builds);
  m.set_voxmap_free_space_bytes(vx.free_space_bytes);
  m.set_voxmap_mean_build_ms(vx.sum_build_ms / builds);
  report::CommandStream& c = *r.mutable_commands();
  c.set_sent(s.commands.commands_sent);
  c.set_send_failures(s.commands.send_failures);
  c.set_link_down(s.commands.link_down);
  c.set_mode_changes_sent(s.commands.mode_changes_sent);
  c.set_stale(s.commands.stale);
  c.set_estops_sent(s.commands.estops_sent);
  c.set_deadman_pressed(s.commands.deadman_pressed);
  if (s.commands.gaze_active > 0) {
    c.set_gaze_active(s.commands.gaze_active);
    c.set_gaze_moves(s.commands.gaze_moves);
  }
  r.set_device_nonfinite_poses(s.device_nonfinite_poses);
  r.set_mode_switches(s.mode_switches);
  report::OperatorEStop& e = *r.mutable_estop();
  e.set_device_presses(s.estop_presses);
  e.set_acknowledged(s.estop_acks);
  e.set_refused(s.estop_refusals);
  if (s.robot_estop >= 0) e.set_robot_engaged(s.robot_estop == 1);
  report::OperatorArmRefusals& ar = *r.mutable_arm_refusals();
  ar.set_refused(s.arm_refusals.refused);
  ar.set_reports(s.arm_refusals.events);
  ar.set_floor(s.arm_refusals.floor);
  ar.set_base(s.arm_refusals.base);
  ar.set_scene(s.arm_refusals.scene);
  ar.set_last_reason(short_name(s.arm_refusals.last_reason));
  ar.set_last_seq(s.arm_refusals.last_seq);
  ar.set_bad_reports(s.arm_refusals.errors);
  if (s.has_tool6) {
    to_report(s.tool6_budget, r.mutable_tool6_budget());
    r.set_tool6_inferred_force_share(s.tool6_inferred_force_share);
    r.set_tool6_contact_ticks(s.tool6_contact_ticks);
    r.set_tool6_inferred_contact_ticks(s.tool6_inferred_contact_ticks);
  }
  report::Logs& l = *r.mutable_logs();
  l.set_servo_written(s.servo_log_written);
  l.set_servo_dropped(s.servo_log_dropped);
  l.set_world_written(s.world_log_written);
  l.set_world_dropped(s.world_log_dropped);
  report::RobotPose& p = *r.mutable_robot_pose();
  p.set_valid(s.robot_pose_valid);
  p.set_x_m(s.robot_pose.x);
  p.set_y_m(s.robot_pose.y);
  p.set_theta_rad(s.robot_pose.theta);
  if (s.has_goal) {
    report::NavGoal& g = *r.mutable_nav_goal();
    g.set_goal_x_m(s.goal_W.x());
    g.set_goal_y_m(s.goal_W.y());
    g.set_arrived(s.arrived);
    if (s.first_arrival_s >= 0.0) g.set_first_arrival_s(s.first_arrival_s);
    g.set_arrivals(s.arrivals);
    g.set_goal_index(s.goal_index);
    g.set_route_size(s.route_size);
    if (s.goal_distance_m >= 0.0) g.set_goal_distance_m(s.goal_distance_m);
  }
  return r;
}

std::string to_json(const OperatorStationSummary& s) { return config::to_json(to_report(s)); }

bool write_map_csv(const mapping::LocalMap& map, const std::string& path, std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    if (error) *error = "cannot open " + path + " for writing";
    return false;
  }
  std::fprintf(f, "ax,ay,bx,by,nx,ny,stamp_ns,kind\n");
  for (const auto& s : map.segments)
    std::fprintf(f, "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%" PRId64 ",%d\n", s.a.x(), s.a.y(), s.b.x(), s.b.y(),
                 s.normal.x(), s.normal.y(), s.stamp_ns, static_cast<int>(s.kind));
  const bool ok = std::fclose(f) == 0;
  if (!ok && error) *error = "write failed: " + path;
  return ok;
}

OperatorStation::OperatorStation(asio::io_context& io, OperatorClient& client, const OperatorStationOptions& o)
    : io_(io), client_(client), o_(o), link_timer_(io) {
  OperatorTaskParams tp = o.task;
  if (!o.goal_route.empty() &&
      (o.device != "sim-omni" || o.hand || (o.script != "nav-to-goal" && o.script != "nav-to-wall")))
    throw std::invalid_argument("a goal route needs the sim-omni device with --script nav-to-goal or nav-to-wall");
  if (!o.probe_line.empty() && (o.device != "sim-omni" || o.hand || o.script != "probe-cylinder"))
    throw std::invalid_argument("a probe line needs the sim-omni device with --script probe-cylinder");
  // A closed-loop SIMULATED hand (nav-to-goal) watches the display the task
  // writes each tick (OperatorView). It runs where the Omni's simulated
  // hardware runs, on its own thread when threaded: the task writes its own
  // view, which crosses to the hand's copy through a newest-wins mailbox
  // (published after each tick, taken as the hand decides). In lock-step both
  // happen on the servo thread in that order: the hand sees what it always did.
  auto closed_loop = [this](std::shared_ptr<const device::HandScript> hand, std::shared_ptr<OperatorView> seen) {
    if (!seen) return hand;
    view_box_ = std::make_shared<NewestMailbox<OperatorView>>();
    view_ = std::make_shared<OperatorView>(*seen);
    return std::shared_ptr<const device::HandScript>(
        std::make_shared<ViewTakingHand>(std::move(hand), std::move(seen), view_box_));
  };
  if (o.device == "sim-omni" && o.hand) {
    device_ = std::make_unique<device::SimulatedOmni>(device::SimulatedOmniModel{}, closed_loop(o.hand, o.view));
  } else if (o.device == "sim-omni") {
    DemoScript d = make_demo_script(o.script, DemoScriptOptions{o.goal_route, o.probe_line});
    if (!d.hand) throw std::invalid_argument("unknown --script '" + o.script + "'");
    tp.initial_mode = d.mode;
    nav_goal_ = d.nav_goal;
    device_ = std::make_unique<device::SimulatedOmni>(device::SimulatedOmniModel{}, closed_loop(d.hand, d.view));
  } else if (o.device == "replay") {
    device::Trajectory traj;
    if (auto e = device::load_trajectory_csv(o.replay_file, device::phantom_omni_limits(), &traj))
      throw std::runtime_error("replay file: " + e->to_string());
    device_ = std::make_unique<device::ReplayDevice>(std::move(traj), device::phantom_omni_limits());
  } else if (o.device == "sim-hand6") {
    // The SIMULATED rigid 6-DoF scripted hand of the 6-DoF tool (tool6_explorer.h).
    if (!tp.tool6.enabled) throw std::invalid_argument("device sim-hand6 needs probe_3d { tool: \"pointshell\" }");
    const device::DeviceLimits hand = device::rigid_hand_limits(1);
    device_ = std::make_unique<device::ReplayDevice>(
        load_hand6_route(o.hand6_route_file, o.hand6_script, tp.tool6.origin_R, hand.ee[0]), hand);
  } else if (o.device == "sim-bimanual") {
    // The right arm of the SIMULATED bimanual device holds the 6-DoF tool
    // (tool6_bimanual.h); without the tool it runs without a robot (main.cpp).
    if (!tp.tool6.enabled)
      throw std::invalid_argument("device sim-bimanual in the networked station holds the 6-DoF tool: it needs "
                                  "probe_3d { tool: \"pointshell\" } (without it hemm-operator runs the device "
                                  "against its local planes, no robot)");
    device_ = make_tool6_bimanual_device(o.bimanual ? *o.bimanual : config::BimanualDeviceConfig{},
                                         load_hand6_route(o.hand6_route_file, o.hand6_script, tp.tool6.origin_R,
                                                          device::rigid_hand_limits(1).ee[0]),
                                         o.tool_device_offset_D, static_cast<double>(o.servo.period_ns) * 1e-9,
                                         &tp.tool6);
  } else {
    throw std::invalid_argument("unknown device type '" + o.device + "' (sim-omni, replay, sim-hand6 or sim-bimanual)");
  }
  if (tp.tool6.enabled) {
    if (!device_->limits().ee[0].renders_torque)
      throw std::invalid_argument(
          "the 6-DoF tool (probe_3d.tool \"pointshell\") needs a 6-DoF device (sim-hand6 or sim-bimanual)");
    tp.tool6.limits = device_->limits().ee[0];
  }
  if (!(o.stats_period_s > 0)) throw std::invalid_argument("stats_period_s must be positive");
  model_ = std::make_unique<ModelThread>(channel_, o.model);
  if (!o.log_path.empty()) {
    servo_log_ = std::make_unique<servo::ServoLogger>(16384, servo::servo_log_header(device_->limits().end_effectors), &servo::format_servo_log_record);
    world_log_ = std::make_unique<StationLogger>(16384, station_log_header(), &format_station_log_record);
  }
  if (!view_) view_ = std::make_shared<OperatorView>();  // the summary's final pose comes from it
  task_ = std::make_unique<OperatorServoTask>(tp, world_log_.get(), view_.get());
  if (o.model.live_voxmap) task_->set_probe_output(&model_->probe_positions());
  if (view_box_) view_task_ = std::make_unique<ViewPublishingTask>(*task_, *view_, *view_box_);
  loop_ = std::make_unique<servo::ServoLoop>(*device_, view_task_ ? *view_task_ : static_cast<servo::ServoTask&>(*task_),
                                             channel_, o.servo, servo_log_.get());
  sender_ = std::make_unique<CommandSender>(
      io_, task_->setpoints(),
      [this](const wire::StreamMessage& m) {
        if (taps_.on_stream) taps_.on_stream(steady_now_ns(), true, m);
        return client_.streams().send(m);
      },
      [this](const wire::SessionFrame& f) {
        if (taps_.on_session) taps_.on_session(steady_now_ns(), true, f);
        client_.send_session_frame(f);
      },
      model_.get(),
      CommandSenderParams{o.command_rate_hz, 100'000'000, o.gaze, o.gaze_params}, [] { return steady_now_ns(); },
      [this] { return client_.link_up(); });
}

OperatorStation::~OperatorStation() { stop(); }

void OperatorStation::attach_view(ModelThread::SnapshotObserver on_snapshot,
                                  NewestMailbox<StationLogRecord>* ticks, std::atomic<std::uint32_t>* presses) {
  if (started_) throw std::logic_error("OperatorStation::attach_view after start()");
  model_->set_snapshot_observer(std::move(on_snapshot));
  task_->set_view_outputs(ticks, presses);
}

void OperatorStation::attach_session_taps(SessionTaps taps) {
  if (started_) throw std::logic_error("OperatorStation::attach_session_taps after start()");
  taps_ = std::move(taps);
  model_->set_step_tap(taps_.on_step);
  task_->set_tick_tap(taps_.ticks);
}

servo::RealtimeStatus OperatorStation::start() {
  if (started_) throw std::logic_error("OperatorStation already started");
  started_ = true;
  client_.streams().on(wire::StreamMessage::kRobotState,
                       [this](const net::DatagramHeader&, int64_t recv_ns, const wire::StreamMessage& m) {
                         if (taps_.on_stream) taps_.on_stream(recv_ns, false, m);
                         model_->submit_state(m.robot_state());
                         std::string err;
                         if (const auto e = observe_arm_refusals(arm_refusals_, m.robot_state(), &err)) {
                           spdlog::warn("event=arm_target_refused reason={} seq={} new={} total={}", short_name(e->reason),
                                        e->seq, e->new_refusals, e->total);
                         } else if (!err.empty() && std::has_single_bit(arm_refusals_.summary.errors)) {
                           spdlog::warn("event=robot_state_bad_refusal error=\"{}\" count={}", err,
                                        arm_refusals_.summary.errors);
                         }
                       });
  client_.streams().on(wire::StreamMessage::kRangeScan,
                       [this](const net::DatagramHeader&, int64_t recv_ns, const wire::StreamMessage& m) {
                         if (taps_.on_stream) taps_.on_stream(recv_ns, false, m);
                         model_->submit_scan(std::make_shared<const wire::RangeScan>(m.range_scan()));
                       });
  client_.streams().on(wire::StreamMessage::kDepthChunk,
                       [this](const net::DatagramHeader&, int64_t recv_ns, const wire::StreamMessage& m) {
                         // Recorded (about 1.6 Mbit/s of a session's recording) for the
                         // MCAP export's /robot/depth; a replay does not rebuild the voxmap.
                         if (taps_.on_stream) taps_.on_stream(recv_ns, false, m);
                         model_->submit_depth_chunk(std::make_shared<const wire::DepthChunk>(m.depth_chunk()));
                       });
  client_.on_session_frame(wire::SessionFrame::kAck, [this](const wire::SessionFrame& f) { on_ack(f.ack()); });
  client_.on_session_frame(wire::SessionFrame::kEstop,
                           [this](const wire::SessionFrame& f) { on_robot_estop(f.estop()); });
  if (taps_.on_session)
    client_.set_session_frame_tap([this](const wire::SessionFrame& f) { taps_.on_session(steady_now_ns(), false, f); });
  if (servo_log_) {
    if (auto e = servo_log_->start(o_.log_path)) throw std::runtime_error(*e);
    if (auto e = world_log_->start(o_.log_path + ".world.csv")) throw std::runtime_error(*e);
    std::string err;
    if (task_->tool6() != nullptr && !write_tool6_params(*task_->tool6(), o_.log_path + ".tool6.txt", &err))
      throw std::runtime_error(err);
  }
  model_->step(steady_now_ns());  // a first snapshot before the servo starts
  model_->start();
  const servo::RealtimeStatus rt = loop_->start();
  asio::post(io_, [this] {
    sender_->start();
    poll_link();
  });
  return rt;
}

void OperatorStation::poll_link() {
  if (stopped_) return;
  const net::LinkStatistics st = client_.statistics();
  if (st.clock.valid) {
    model_->set_clock_offset(st.clock.offset_ns);
    model_->set_command_delay(st.clock.rtt_median_ns / 2);
    loop_->set_link_stats(st.clock.rtt_last_ns, st.clock.offset_ns);
  }
  link_timer_.expires_after(std::chrono::nanoseconds(static_cast<std::int64_t>(o_.stats_period_s * 1e9)));
  link_timer_.async_wait([this](const asio::error_code& ec) {
    if (!ec) poll_link();
  });
}

void OperatorStation::request_estop(bool engaged, const std::string& reason, Reply done) {
  const std::uint64_t id = stopped_ ? 0 : sender_->send_estop(engaged, reason);
  if (id == 0) {
    done(std::string("error no link to the robot: nothing sent") +
         (engaged ? " (without a link the robot stops by itself)" : ""));
    return;
  }
  spdlog::warn("event=estop_request request_id={} engaged={} reason=\"{}\"", id, engaged, net::printable_text(reason));
  PendingAck p;
  p.engaged = engaged;
  p.done = std::move(done);
  p.timer = std::make_unique<asio::steady_timer>(io_, kAckTimeout);
  p.timer->async_wait([this, id](const asio::error_code& ec) {
    if (ec) return;
    auto it = pending_acks_.find(id);
    if (it == pending_acks_.end()) return;
    const Reply d = std::move(it->second.done);
    pending_acks_.erase(it);
    d("error request_id=" + std::to_string(id) + " no acknowledgement from the robot within " +
      std::to_string(kAckTimeout.count()) + " ms");
  });
  pending_acks_.emplace(id, std::move(p));
}

void OperatorStation::on_ack(const wire::Ack& a) {
  const std::string reason = net::printable_text(a.reason());
  spdlog::info("event=ack request_id={} ok={} reason=\"{}\"", a.request_id(), a.ok(), reason);
  auto it = pending_acks_.find(a.request_id());
  if (it == pending_acks_.end()) return;
  ++(a.ok() ? estop_acks_ : estop_refusals_);
  it->second.timer->cancel();
  const Reply d = std::move(it->second.done);
  pending_acks_.erase(it);
  d(std::string(a.ok() ? "ok" : "error") + " request_id=" + std::to_string(a.request_id()) + " " + reason);
}

void OperatorStation::on_robot_estop(const wire::EStop& e) {
  robot_estop_ = e.engaged() ? 1 : 0;
  spdlog::warn("event=robot_estop engaged={} reason=\"{}\"", e.engaged(), net::printable_text(e.reason()));
}

std::string OperatorStation::status_line() const {
  return std::string("ok session=") + (client_.session_open() ? "open" : "closed") +
         " link=" + (client_.link_up() ? "up" : "down") + " estop=" +
         (robot_estop_ < 0 ? "unknown" : robot_estop_ ? "engaged" : "released") + " mode=" +
         wire::Mode_Name(to_wire_mode(sender_->mode()));
}

void OperatorStation::stop() {
  if (!started_ || stopped_) return;
  stopped_ = true;
  loop_->stop();
  model_->stop();
  // The sender and the link timer live on the io thread: cancel them there if
  // it still runs, else here (nothing else touches them then).
  auto detach = [this] {
    sender_->stop();
    link_timer_.cancel();
    client_.streams().on(wire::StreamMessage::kRobotState, nullptr);
    client_.streams().on(wire::StreamMessage::kRangeScan, nullptr);
    client_.streams().on(wire::StreamMessage::kDepthChunk, nullptr);
    client_.on_session_frame(wire::SessionFrame::kAck, nullptr);
    client_.on_session_frame(wire::SessionFrame::kEstop, nullptr);
    client_.set_session_frame_tap(nullptr);
    for (auto& [id, p] : pending_acks_) p.timer->cancel();
  };
  if (io_.stopped() || io_.get_executor().running_in_this_thread()) {
    detach();
  } else {
    auto done = std::make_shared<std::promise<void>>();
    auto fut = done->get_future();
    asio::post(io_, [detach, done] {
      detach();
      done->set_value();
    });
    // If the io thread does not run handlers within 2 s it is not running:
    // then nothing else touches these objects and detaching here is safe.
    if (fut.wait_for(std::chrono::seconds(2)) != std::future_status::ready) detach();
  }
  if (servo_log_) {
    servo_log_->stop();
    world_log_->stop();
    std::string err;
    write_map_csv(model_->map(), o_.log_path + ".map.csv", &err);
    if (task_->tool6() != nullptr) {
      if (const auto vm = model_->newest_voxmap()) {
        write_voxmap_csv(*vm, o_.log_path + ".voxmap.csv", &err);
        write_voxmap_vps(*vm, task_->tool6()->tool().shell, o_.log_path + ".voxmap.vps", &err);
      }
    }
  }
}

OperatorStationSummary OperatorStation::summary() const {
  OperatorStationSummary s;
  s.timing = loop_->summary();
  s.model = model_->stats();
  s.commands = sender_->stats();
  s.mode_switches = task_->mode_switches();
  s.estop_presses = task_->estop_presses();
  s.device_nonfinite_poses = task_->nonfinite_poses();
  s.estop_acks = estop_acks_;
  s.estop_refusals = estop_refusals_;
  s.robot_estop = robot_estop_;
  s.arm_refusals = arm_refusals_.summary;
  if (servo_log_) {
    s.servo_log_written = servo_log_->written();
    s.servo_log_dropped = servo_log_->dropped();
    s.world_log_written = world_log_->written();
    s.world_log_dropped = world_log_->dropped();
  }
  // The servo thread wrote these; it has stopped (or not started) when the
  // summary is taken after stop().
  s.robot_pose = view_->T_W_R;
  s.robot_pose_valid = view_->valid;
  if (nav_goal_) {
    s.has_goal = true;
    s.goal_W = nav_goal_->route().back();
    s.arrived = nav_goal_->arrived();
    s.first_arrival_s = nav_goal_->first_arrival_s();
    s.arrivals = nav_goal_->arrivals();
    s.goal_index = nav_goal_->goal_index();
    s.route_size = nav_goal_->route().size();
    if (s.robot_pose_valid)
      s.goal_distance_m = (s.goal_W - Eigen::Vector2d(s.robot_pose.x, s.robot_pose.y)).norm();
  }
  if (const Tool6Explorer* t = task_->tool6(); t != nullptr) {
    s.has_tool6 = true;
    s.tool6_budget.params = t->budget().params();
    s.tool6_budget.calibration = t->calibration();
    s.tool6_budget.stats = t->budget().stats();
    s.tool6_inferred_force_share = t->inferred_force_share();
    s.tool6_contact_ticks = t->contact_ticks();
    s.tool6_inferred_contact_ticks = t->inferred_contact_ticks();
  }
  return s;
}

}  // namespace hemm::op
