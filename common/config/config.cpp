#include "common/config/config.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/io/tokenizer.h>
#include <google/protobuf/text_format.h>
#include <google/protobuf/util/json_util.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <cmath>
#include <sstream>
#include <utility>
#include <stdexcept>

#include "config_operator.pb.h"
#include "config_robot.pb.h"

namespace hemm::config {
namespace {

namespace pb = google::protobuf;

// Collects the first parse error (protobuf reports 0-based line/column).
class FirstErrorCollector : public pb::io::ErrorCollector {
 public:
  void AddError(int line, pb::io::ColumnNumber column, const std::string& message) override {
    if (!has_error) {
      has_error = true;
      this->line = line + 1;
      this->column = column + 1;
      this->message = message;
    }
  }
  void AddWarning(int, pb::io::ColumnNumber, const std::string&) override {}

  bool has_error = false;
  int line = 0;
  int column = 0;
  std::string message;
};

// Finds where a dotted field path ("a.b.c", with optional "[i]" indices) was
// written, walking the parse-info tree. Returns {0,0} if it was not written
// (e.g. a required value missing, or a default broke a rule).
std::pair<int, int> locate(const pb::Message& msg, const pb::TextFormat::ParseInfoTree& root,
                           const std::string& path) {
  const pb::Descriptor* desc = msg.GetDescriptor();
  const pb::TextFormat::ParseInfoTree* tree = &root;
  std::pair<int, int> where{0, 0};
  std::stringstream ss(path);
  std::string part;
  while (std::getline(ss, part, '.')) {
    int index = -1;
    if (auto open = part.find('['); open != std::string::npos) {
      index = std::atoi(part.c_str() + open + 1);
      part.resize(open);
    }
    if (desc == nullptr || tree == nullptr) break;
    const pb::FieldDescriptor* field = desc->FindFieldByName(part);
    if (field == nullptr) break;
    const int i = field->is_repeated() ? std::max(index, 0) : -1;
    pb::TextFormat::ParseLocation loc = tree->GetLocation(field, i);
    if (loc.line < 0) break;
    where = {loc.line + 1, loc.column + 1};
    if (field->cpp_type() != pb::FieldDescriptor::CPPTYPE_MESSAGE) break;
    tree = tree->GetTreeForNested(field, i);
    desc = field->message_type();
  }
  return where;
}

bool in_range(uint64_t v, uint64_t lo, uint64_t hi) { return v >= lo && v <= hi; }

void check_link(const LinkConfig& link, const std::string& prefix, std::vector<FieldIssue>& out) {
  if (link.station_name().size() > 64) out.push_back({prefix + "station_name", "longer than 64 bytes"});
  if (!in_range(link.heartbeat_period_ms(), 1, 10000))
    out.push_back({prefix + "heartbeat_period_ms", "must be 1..10000"});
  if (link.link_timeout_ms() < 2 * link.heartbeat_period_ms())
    out.push_back({prefix + "link_timeout_ms", "must be at least twice heartbeat_period_ms"});
  if (!in_range(link.connect_timeout_ms(), 10, 600000))
    out.push_back({prefix + "connect_timeout_ms", "must be 10..600000"});
  if (!in_range(link.handshake_timeout_ms(), 10, 600000))
    out.push_back({prefix + "handshake_timeout_ms", "must be 10..600000"});
  if (!in_range(link.ping_period_ms(), 1, 10000)) out.push_back({prefix + "ping_period_ms", "must be 1..10000"});
  if (!in_range(link.max_frame_bytes(), 1024, 64u << 20))
    out.push_back({prefix + "max_frame_bytes", "must be 1024..67108864"});
  if (!in_range(link.replay_window(), 64, 65536)) out.push_back({prefix + "replay_window", "must be 64..65536"});
  if (!in_range(link.stale_margin_ms(), 10, 10000)) out.push_back({prefix + "stale_margin_ms", "must be 10..10000"});
  if (link.rtt_ms() > 60000) out.push_back({prefix + "rtt_ms", "must be 0..60000"});
  if (link.connect_for_ms() > 3600000) out.push_back({prefix + "connect_for_ms", "must be 0..3600000"});
}

void check_port(uint32_t port, bool zero_ok, const std::string& field, std::vector<FieldIssue>& out) {
  if (port > 65535 || (!zero_ok && port == 0))
    out.push_back({field, zero_ok ? "must be 0..65535" : "must be 1..65535"});
}

void check_positive(double v, const std::string& field, std::vector<FieldIssue>& out) {
  if (!(v > 0.0)) out.push_back({field, "must be positive"});
}

void check_probability(double v, const std::string& field, std::vector<FieldIssue>& out) {
  if (!(v >= 0.0 && v <= 1.0)) out.push_back({field, "must be within 0..1"});
}

}  // namespace

std::string ConfigError::to_string() const {
  std::ostringstream os;
  os << file;
  if (line > 0) {
    os << ':' << line;
    if (column > 0) os << ':' << column;
  }
  os << ": ";
  if (!field.empty()) os << field << ": ";
  os << message;
  return os.str();
}

std::optional<ConfigError> parse_text_config(const std::string& text, const std::string& file_name,
                                             Validator validate, pb::Message* out) {
  std::unique_ptr<pb::Message> parsed(out->New());
  pb::TextFormat::Parser parser;
  FirstErrorCollector errors;
  pb::TextFormat::ParseInfoTree info;
  parser.RecordErrorsTo(&errors);
  parser.WriteLocationsTo(&info);
  if (!parser.ParseFromString(text, parsed.get())) {
    ConfigError e{file_name, errors.line, errors.column, "", errors.message};
    if (!errors.has_error) e.message = "could not parse";
    return e;
  }
  if (validate != nullptr) {
    std::vector<FieldIssue> issues = validate(*parsed);
    if (!issues.empty()) {
      const FieldIssue& first = issues.front();
      auto [line, column] = locate(*parsed, info, first.field);
      std::string message = first.message;
      if (issues.size() > 1) message += " (and " + std::to_string(issues.size() - 1) + " more problem(s))";
      return ConfigError{file_name, line, column, first.field, message};
    }
  }
  out->GetReflection()->Swap(out, parsed.get());
  return std::nullopt;
}

std::optional<ConfigError> load_text_config(const std::string& path, Validator validate, pb::Message* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return ConfigError{path, 0, 0, "", "cannot open file"};
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return ConfigError{path, 0, 0, "", "read error"};
  constexpr size_t kMaxConfigBytes = 1 << 20;
  if (ss.str().size() > kMaxConfigBytes) return ConfigError{path, 0, 0, "", "file larger than 1 MiB"};
  return parse_text_config(ss.str(), path, validate, out);
}

namespace {

// The two-arm station's block (robot kind "twoarm").
void check_twoarm(const RobotConfig& c, std::vector<FieldIssue>& out) {
  if (c.kind() != "mobile" && c.kind() != "twoarm") out.push_back({"kind", "must be mobile or twoarm"});
  const auto& t = c.twoarm();
  const std::pair<double, const char*> gains[] = {
      {t.stiffness_n_per_m(), "twoarm.stiffness_n_per_m"},
      {t.damping_ns_per_m(), "twoarm.damping_ns_per_m"},
      {t.rot_stiffness_nm_per_rad(), "twoarm.rot_stiffness_nm_per_rad"},
      {t.rot_damping_nms_per_rad(), "twoarm.rot_damping_nms_per_rad"},
      {t.null_stiffness_nm_per_rad(), "twoarm.null_stiffness_nm_per_rad"},
      {t.null_damping_nms_per_rad(), "twoarm.null_damping_nms_per_rad"},
      {t.avoidance_stiffness_n_per_m(), "twoarm.avoidance_stiffness_n_per_m"}};
  for (const auto& [v, name] : gains) {
    if (!(v >= 0 && v <= 1e5)) out.push_back({name, "must be within [0, 1e5]"});
  }
  if (!(t.stiffness_n_per_m() <= 5000)) out.push_back({"twoarm.stiffness_n_per_m", "must be at most 5000 (1 kHz stability)"});
  if (!(t.force_limit_n() > 0 && t.force_limit_n() <= 150))
    out.push_back({"twoarm.force_limit_n", "must be within (0, 150] (the LWR's payload force)"});
  if (!(t.torque_limit_nm() > 0 && t.torque_limit_nm() <= 30))
    out.push_back({"twoarm.torque_limit_nm", "must be within (0, 30]"});
  if (!(t.joint_limit_margin_rad() >= 0 && t.joint_limit_margin_rad() <= 0.5))
    out.push_back({"twoarm.joint_limit_margin_rad", "must be within [0, 0.5]"});
  if (!(t.avoidance_activation_m() > 0 && t.avoidance_activation_m() <= 0.3))
    out.push_back({"twoarm.avoidance_activation_m", "must be within (0, 0.3]"});
  if (!(t.max_target_jump_m() > 0 && t.max_target_jump_m() <= 2))
    out.push_back({"twoarm.max_target_jump_m", "must be within (0, 2]"});
  if (!(t.reach_margin_m() >= 0 && t.reach_margin_m() <= 0.1))
    out.push_back({"twoarm.reach_margin_m", "must be within [0, 0.1]"});
  if (!(t.reach_margin_rad() >= 0 && t.reach_margin_rad() <= 0.5))
    out.push_back({"twoarm.reach_margin_rad", "must be within [0, 0.5]"});
  if (!(t.relative_stiffness_ratio() >= 0 && t.relative_stiffness_ratio() <= 1))
    out.push_back({"twoarm.relative_stiffness_ratio", "must be within [0, 1] (1: independent arms)"});
  if (!(t.gripper_approach_speed_mps() >= 0 && t.gripper_approach_speed_mps() <= 1))
    out.push_back({"twoarm.gripper_approach_speed_mps", "must be within [0, 1] (0: not capped)"});
  // The direct mode's twist is held this long from its send time; past the
  // watchdog's time it would carry the arm on through a silence.
  if (!(t.direct_twist_hold_ms() > 0 && t.direct_twist_hold_ms() <= c.safety().watchdog_ms()))
    out.push_back({"twoarm.direct_twist_hold_ms", "must be within (0, safety.watchdog_ms]"});
  if (t.task() != "" && t.task() != "box" && t.task() != "peg" && t.task() != "bar")
    out.push_back({"twoarm.task", "must be box, peg, bar or empty (no task judged)"});
}

}  // namespace

std::vector<FieldIssue> validate_robot_config(const pb::Message& m) {
  const auto& c = static_cast<const RobotConfig&>(m);
  std::vector<FieldIssue> out;
  check_link(c.link(), "link.", out);
  check_port(c.net().session_port(), false, "net.session_port", out);
  check_port(c.net().stream_port(), true, "net.stream_port", out);
  if (!in_range(c.net().state_rate_hz(), 200, 1000)) out.push_back({"net.state_rate_hz", "must be 200..1000"});
  if (!(c.sim().timestep_s() > 0 && c.sim().timestep_s() <= 0.01))
    out.push_back({"sim.timestep_s", "must be within (0, 0.01]"});
  const auto& l = c.laser();
  if (!in_range(l.beams(), 2, 4096)) out.push_back({"laser.beams", "must be 2..4096"});
  if (!(l.fov_deg() > 0 && l.fov_deg() <= 360)) out.push_back({"laser.fov_deg", "must be within (0, 360]"});
  check_positive(l.range_min_m(), "laser.range_min_m", out);
  if (!(l.range_max_m() > l.range_min_m())) out.push_back({"laser.range_max_m", "must exceed range_min_m"});
  if (!(l.sigma_m() >= 0)) out.push_back({"laser.sigma_m", "must be non-negative"});
  if (!(l.rate_hz() > 0 && l.rate_hz() <= 1000)) out.push_back({"laser.rate_hz", "must be within (0, 1000]"});
  check_probability(l.dropout_probability(), "laser.dropout_probability", out);
  const auto& s = c.sonar();
  if (!in_range(s.count(), 1, 64)) out.push_back({"sonar.count", "must be 1..64"});
  if (!(s.cone_deg() > 0 && s.cone_deg() < 90)) out.push_back({"sonar.cone_deg", "must be within (0, 90)"});
  if (!in_range(s.rays_per_cone(), 1, 64)) out.push_back({"sonar.rays_per_cone", "must be 1..64"});
  check_positive(s.range_min_m(), "sonar.range_min_m", out);
  if (!(s.range_max_m() > s.range_min_m())) out.push_back({"sonar.range_max_m", "must exceed range_min_m"});
  if (!(s.sigma_m() >= 0)) out.push_back({"sonar.sigma_m", "must be non-negative"});
  if (!(s.rate_hz() > 0 && s.rate_hz() <= 1000)) out.push_back({"sonar.rate_hz", "must be within (0, 1000]"});
  check_probability(s.dropout_probability(), "sonar.dropout_probability", out);
  check_positive(c.base().max_speed_mps(), "base.max_speed_mps", out);
  check_positive(c.base().max_yaw_rate_rps(), "base.max_yaw_rate_rps", out);
  check_positive(c.base().max_accel_mps2(), "base.max_accel_mps2", out);
  check_positive(c.base().max_yaw_accel_rps2(), "base.max_yaw_accel_rps2", out);
  if (!(c.base().skid_slip_factor() >= 1 && c.base().skid_slip_factor() <= 5))
    out.push_back({"base.skid_slip_factor", "must be within [1, 5]"});
  check_positive(c.arm().max_joint_speed_rps(), "arm.max_joint_speed_rps", out);
  check_positive(c.arm().max_joint_torque_nm(), "arm.max_joint_torque_nm", out);
  if (!(c.arm().kp() >= 0)) out.push_back({"arm.kp", "must be non-negative"});
  if (!(c.arm().kd() >= 0)) out.push_back({"arm.kd", "must be non-negative"});
  if (!in_range(c.safety().watchdog_ms(), 10, 10000)) out.push_back({"safety.watchdog_ms", "must be 10..10000"});
  if (!(c.safety().collision_margin_m() >= 0 && c.safety().collision_margin_m() < 5))
    out.push_back({"safety.collision_margin_m", "must be within [0, 5)"});
  if (!(c.safety().guard_reaction_time_s() >= 0 && c.safety().guard_reaction_time_s() <= 1))
    out.push_back({"safety.guard_reaction_time_s", "must be within [0, 1]"});
  for (double v : {c.sim().start_x_m(), c.sim().start_y_m(), c.sim().start_theta_rad()})
    if (!(std::abs(v) <= 1000)) out.push_back({"sim.start_*", "must be finite, within 1000"});
  if (c.sim().control_fifo_priority() < 0 || c.sim().control_fifo_priority() > 99)
    out.push_back({"sim.control_fifo_priority", "must be 0 (a normal thread) or a SCHED_FIFO priority 1..99"});
  if (c.sim().control_cpu() < -1 || c.sim().control_cpu() > 1023)
    out.push_back({"sim.control_cpu", "must be -1 (not pinned) or a CPU number 0..1023"});
  if (c.sim().start_arm_q_size() != 0 && c.sim().start_arm_q_size() != 5)
    out.push_back({"sim.start_arm_q", "must be empty or 5 joint angles"});
  for (double q : c.sim().start_arm_q())
    if (!(std::abs(q) <= 10)) out.push_back({"sim.start_arm_q", "must be finite, within 10 rad"});
  const auto& dc = c.depth_camera();
  if (dc.mount() != "mast" && dc.mount() != "wrist" && dc.mount() != "pan-tilt")
    out.push_back({"depth_camera.mount", "must be mast, wrist or pan-tilt"});
  if (!in_range(dc.width(), 1, 1024)) out.push_back({"depth_camera.width", "must be 1..1024"});
  if (!in_range(dc.height(), 1, 1024)) out.push_back({"depth_camera.height", "must be 1..1024"});
  if (!(dc.hfov_deg() > 0 && dc.hfov_deg() < 170)) out.push_back({"depth_camera.hfov_deg", "must be within (0, 170)"});
  check_positive(dc.range_min_m(), "depth_camera.range_min_m", out);
  if (!(dc.range_max_m() > dc.range_min_m() && dc.range_max_m() <= 100))
    out.push_back({"depth_camera.range_max_m", "must exceed range_min_m, at most 100"});
  if (!(dc.rate_hz() > 0 && dc.rate_hz() <= 60)) out.push_back({"depth_camera.rate_hz", "must be within (0, 60]"});
  if (!(std::abs(dc.mast_x_m()) <= 1 && dc.mast_z_m() >= 0 && dc.mast_z_m() <= 3))
    out.push_back({"depth_camera.mast_x_m", "mast within 1 m of the base centre, 0..3 m high"});
  if (!(std::abs(dc.mast_pitch_deg()) <= 90)) out.push_back({"depth_camera.mast_pitch_deg", "must be within [-90, 90]"});
  // The pan-tilt head (fields 140-152).
  if (!(std::abs(dc.head_y_m()) <= 1)) out.push_back({"depth_camera.head_y_m", "must be within 1 m of the base centre"});
  if (!(dc.pan_min_deg() >= -180 && dc.pan_min_deg() < dc.pan_max_deg() && dc.pan_max_deg() <= 180 &&
        dc.pan_min_deg() <= 0 && dc.pan_max_deg() >= 0))
    out.push_back({"depth_camera.pan_min_deg", "need -180 <= pan_min_deg <= 0 <= pan_max_deg <= 180, min < max"});
  if (!(dc.tilt_min_deg() >= -90 && dc.tilt_min_deg() < dc.tilt_max_deg() && dc.tilt_max_deg() <= 90 &&
        dc.mast_pitch_deg() >= dc.tilt_min_deg() && dc.mast_pitch_deg() <= dc.tilt_max_deg()))
    out.push_back({"depth_camera.tilt_min_deg", "need -90 <= tilt_min_deg <= mast_pitch_deg <= tilt_max_deg <= 90"});
  if (!(dc.head_rate_dps() > 0 && dc.head_rate_dps() <= 720))
    out.push_back({"depth_camera.head_rate_dps", "must be within (0, 720]"});
  if (!(dc.head_time_constant_s() >= 0 && dc.head_time_constant_s() <= 2))
    out.push_back({"depth_camera.head_time_constant_s", "must be within [0, 2]"});
  for (double b : {dc.pan_bias_deg(), dc.tilt_bias_deg()})
    if (!(std::abs(b) <= 10)) out.push_back({"depth_camera.pan_bias_deg", "encoder biases must be within 10 deg"});
  if (!(dc.encoder_sigma_deg() >= 0 && dc.encoder_sigma_deg() <= 5))
    out.push_back({"depth_camera.encoder_sigma_deg", "must be within [0, 5]"});
  if (!(dc.gaze_min_range_m() >= 0 && dc.gaze_min_range_m() < dc.gaze_max_range_m() && dc.gaze_max_range_m() <= 100))
    out.push_back({"depth_camera.gaze_min_range_m", "need 0 <= gaze_min_range_m < gaze_max_range_m <= 100"});
  if (!in_range(dc.gaze_timeout_ms(), 10, 10000)) out.push_back({"depth_camera.gaze_timeout_ms", "must be 10..10000"});
  check_twoarm(c, out);
  return out;
}

// The direct mode's passivity block (docs/telemanipulation_passivity.md).
void check_passivity(const OperatorPassivityConfig& c, std::vector<FieldIssue>& out) {
  const double rtt = c.max_direct_rtt_ms();
  if (!(std::isfinite(rtt) && rtt >= 0.0)) out.push_back({"passivity.max_direct_rtt_ms", "must be finite and >= 0"});
  check_probability(c.max_direct_loss(), "passivity.max_direct_loss", out);
  if (!(c.hysteresis() >= 0.0 && c.hysteresis() < 1.0))
    out.push_back({"passivity.hysteresis", "must be within 0..1 (1 excluded)"});
}

std::vector<FieldIssue> validate_operator_config(const pb::Message& m) {
  const auto& c = static_cast<const OperatorConfig&>(m);
  std::vector<FieldIssue> out;
  check_link(c.link(), "link.", out);
  check_passivity(c.passivity(), out);
  if (c.net().robot_address().empty()) out.push_back({"net.robot_address", "must not be empty"});
  check_port(c.net().session_port(), false, "net.session_port", out);
  check_port(c.net().stream_port(), true, "net.stream_port", out);
  check_port(c.net().local_stream_port(), true, "net.local_stream_port", out);
  if (!in_range(c.net().command_rate_hz(), 100, 1000)) out.push_back({"net.command_rate_hz", "must be 100..1000"});
  const std::string& type = c.device().type();
  if (type != "sim-omni" && type != "replay" && type != "sim-bimanual" && type != "sim-hand6")
    out.push_back({"device.type", "must be \"sim-omni\", \"replay\", \"sim-bimanual\" or \"sim-hand6\""});
  if (type == "replay" && c.device().replay_file().empty())
    out.push_back({"device.replay_file", "required when device.type is \"replay\""});
  if (!in_range(c.servo().rate_hz(), 100, 10000)) out.push_back({"servo.rate_hz", "must be 100..10000"});
  if (c.servo().cpu() < -1 || c.servo().cpu() > 1023)
    out.push_back({"servo.cpu", "must be -1 (not pinned) or a CPU number 0..1023"});
  if (c.servo().simulated_hardware() != "threaded" && c.servo().simulated_hardware() != "lock-step")
    out.push_back({"servo.simulated_hardware", "must be \"threaded\" or \"lock-step\""});
  const auto& p3 = c.probe_3d();
  if (!(p3.voxel_size_m() >= 0.003 && p3.voxel_size_m() <= 0.05))
    out.push_back({"probe_3d.voxel_size_m", "must be within [0.003, 0.05]"});
  if (!(p3.probe_radius_m() > 0 && p3.probe_radius_m() < 3.5 * p3.voxel_size_m()))
    out.push_back({"probe_3d.probe_radius_m", "must be > 0 and below 3.5 voxels (the voxmap's distance layers)"});
  if (!(p3.range_m() > 0 && p3.range_m() <= 10)) out.push_back({"probe_3d.range_m", "must be within (0, 10]"});
  if (!(std::abs(p3.origin_x_m()) <= 3 && std::abs(p3.origin_z_m()) <= 3))
    out.push_back({"probe_3d.origin_x_m", "origin within 3 m"});
  if (!(p3.roi_x_max_m() > p3.roi_x_min_m() && p3.roi_half_width_m() > 0 && p3.roi_z_max_m() > p3.roi_z_min_m() &&
        p3.roi_x_max_m() - p3.roi_x_min_m() <= 10 && p3.roi_half_width_m() <= 5 && p3.roi_z_max_m() - p3.roi_z_min_m() <= 5))
    out.push_back({"probe_3d.roi_x_min_m", "the region of interest must be a non-empty box within 10 x 10 x 5 m"});
  if (p3.roi() != "probe" && p3.roi() != "robot") out.push_back({"probe_3d.roi", "must be \"probe\" or \"robot\""});
  if (!(p3.gaze_lookahead_s() >= 0 && p3.gaze_lookahead_s() <= 5))
    out.push_back({"probe_3d.gaze_lookahead_s", "must be within [0, 5]"});
  if (!(p3.gaze_hysteresis_m() >= 0 && p3.gaze_hysteresis_m() <= 2))
    out.push_back({"probe_3d.gaze_hysteresis_m", "must be within [0, 2]"});
  // A quarter of the edge is the re-centring margin: it must hold the probe
  // (1 cm) and the voxmap's distance layers around what it touches.
  if (!(p3.roi_size_m() >= 0.2 && p3.roi_size_m() <= 3))
    out.push_back({"probe_3d.roi_size_m", "must be within [0.2, 3] m"});
  if (!(p3.rebuild_rate_hz() > 0 && p3.rebuild_rate_hz() <= 50))
    out.push_back({"probe_3d.rebuild_rate_hz", "must be within (0, 50]"});
  const bool shell = p3.tool() == "pointshell";
  if (!shell && p3.tool() != "point") out.push_back({"probe_3d.tool", "must be \"point\" or \"pointshell\""});
  if (shell && !p3.enabled()) out.push_back({"probe_3d.tool", "\"pointshell\" needs probe_3d.enabled"});
  if (shell && type != "sim-hand6" && type != "sim-bimanual")
    out.push_back({"device.type", "the 6-DoF tool (probe_3d.tool \"pointshell\") needs a 6-DoF device: \"sim-hand6\" "
                                  "or \"sim-bimanual\""});
  if (!shell && type == "sim-hand6")
    out.push_back({"device.type", "the 6-DoF device \"sim-hand6\" holds the 6-DoF tool: it needs probe_3d.tool "
                                  "\"pointshell\""});
  if (!(p3.tool_work_budget() >= 100 && p3.tool_work_budget() <= 1000000))
    out.push_back({"probe_3d.tool_work_budget", "must be within [100, 1000000]"});
  if (!(p3.tool_tick_budget_us() >= 0 && p3.tool_tick_budget_us() <= 100000))
    out.push_back({"probe_3d.tool_tick_budget_us", "must be within [0, 100000] (0: the work budget alone)"});
  if (!(p3.tool_tick_margin_us() >= 0 && p3.tool_tick_margin_us() <= 100000))
    out.push_back({"probe_3d.tool_tick_margin_us", "must be within [0, 100000]"});
  if (!(p3.tool_contact_stiffness() > 0 && p3.tool_contact_stiffness() <= 1e10))
    out.push_back({"probe_3d.tool_contact_stiffness", "must be within (0, 1e10] N/m^3"});
  // The route itself is read (and checked, with its file and line) when the station starts.
  if (shell && p3.tool_hand_script().empty())
    out.push_back({"probe_3d.tool_hand_script", "must name an explore6 route of tool_hand_route (e.g. \"explore-table\")"});
  if (shell && p3.tool_hand_route().empty())
    out.push_back({"probe_3d.tool_hand_route", "must name the scene file whose header holds the route"});
  if (!(p3.inferred_stiffness() > 0 && p3.inferred_stiffness() <= 1))
    out.push_back({"probe_3d.inferred_stiffness", "must be within (0, 1] (1: full stiffness)"});
  return out;
}

std::optional<ConfigError> load_robot_config(const std::string& path, RobotConfig* out) {
  return load_text_config(path, &validate_robot_config, out);
}

std::optional<ConfigError> load_operator_config(const std::string& path, OperatorConfig* out) {
  return load_text_config(path, &validate_operator_config, out);
}

std::string resolve_relative_to(const std::string& config_path, const std::string& path) {
  if (path.empty()) return path;
  std::filesystem::path p(path);
  if (p.is_absolute()) return path;
  return (std::filesystem::path(config_path).parent_path() / p).lexically_normal().string();
}

std::string to_json(const google::protobuf::Message& report, JsonLayout layout) {
  google::protobuf::util::JsonPrintOptions o;
  o.add_whitespace = layout == JsonLayout::kIndented;
  o.always_print_primitive_fields = true;
  o.preserve_proto_field_names = true;
  std::string out;
  if (const auto st = google::protobuf::util::MessageToJsonString(report, &out, o); !st.ok())
    throw std::runtime_error("cannot print " + report.GetTypeName() + " as JSON: " + st.ToString());
  return out;  // add_whitespace ends it with a newline, its absence with none
}

}  // namespace hemm::config
