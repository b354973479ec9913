#include "robot_side/sim/wire_convert.h"

#include <cmath>

#include "common/mapping/depth_stream.h"
#include "common/math/finite.h"

namespace hemm::robot {
namespace {
constexpr uint32_t kMaxBeams = 100000;
}  // namespace

void to_wire(const Pose2& p, proto::Pose2* out) {
  out->set_x(p.x);
  out->set_y(p.y);
  out->set_theta(p.theta);
}

void to_wire(const Eigen::Isometry3d& T, proto::Pose3* out) { mapping::pose3_to_wire(T, out); }

std::optional<std::string> from_wire(const proto::Pose2& p, Pose2* out) {
  if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.theta())) return "pose2 not finite";
  *out = {p.x(), p.y(), p.theta()};
  return std::nullopt;
}

std::optional<std::string> from_wire(const proto::Pose3& p, Eigen::Isometry3d* out) {
  return mapping::pose3_from_wire(p, out);
}

void to_wire(const RobotStateSim& s, wire::RobotState* out) {
  out->Clear();
  out->set_stamp_ns(s.stamp_ns);
  to_wire(s.T_W_R_odom, out->mutable_t_w_r_odom());
  to_wire(s.T_W_R_truth, out->mutable_t_w_r_truth());
  out->set_v(s.v);
  out->set_omega(s.omega);
  out->set_wheel_left(s.wheel_left);
  out->set_wheel_right(s.wheel_right);
  for (int i = 0; i < kinematics::kArm5Dof; ++i) {
    out->add_q(s.q(i));
    out->add_qd(s.qd(i));
    out->add_tau(s.tau(i));
  }
  to_wire(s.T_R_E, out->mutable_t_r_e());
  out->set_safety(s.safety);
  out->set_mode(s.mode);
  out->set_last_command_seq(s.last_command_seq);
  out->set_arm_refusals(s.arm_refusals);
  out->set_last_arm_refusal(static_cast<wire::ArmRefusalReason>(s.last_arm_refusal));
  out->set_last_refused_seq(s.last_refused_seq);
  if (s.head.present) {
    wire::HeadState* h = out->mutable_head();
    h->set_pan(s.head.pan);
    h->set_tilt(s.head.tilt);
    h->set_pan_setpoint(s.head.pan_setpoint);
    h->set_tilt_setpoint(s.head.tilt_setpoint);
    h->set_gaze_active(s.head.gaze_active);
    h->set_gaze_refusals(s.head.gaze_refusals);
    h->set_last_gaze_refusal(static_cast<wire::GazeRefusalReason>(s.head.last_gaze_refusal));
    h->set_last_gaze_refused_seq(s.head.last_gaze_refused_seq);
    h->set_pan_truth(s.head.pan_truth);
    h->set_tilt_truth(s.head.tilt_truth);
  }
}

std::optional<std::string> from_wire(const wire::RobotState& m, RobotStateSim* out) {
  RobotStateSim s;
  if (m.q_size() != 5 || m.qd_size() != 5 || m.tau_size() != 5) return "robot state needs 5 joints";
  if (auto e = from_wire(m.t_w_r_odom(), &s.T_W_R_odom)) return "T_W_R_odom: " + *e;
  if (m.has_t_w_r_truth()) {
    if (auto e = from_wire(m.t_w_r_truth(), &s.T_W_R_truth)) return "T_W_R_truth: " + *e;
  }
  if (auto e = from_wire(m.t_r_e(), &s.T_R_E)) return "T_R_E: " + *e;
  for (int i = 0; i < 5; ++i) {
    s.q(i) = m.q(i);
    s.qd(i) = m.qd(i);
    s.tau(i) = m.tau(i);
  }
  if (!s.q.allFinite() || !s.qd.allFinite() || !s.tau.allFinite()) return "joint values not finite";
  if (!std::isfinite(m.v()) || !std::isfinite(m.omega()) || !std::isfinite(m.wheel_left()) ||
      !std::isfinite(m.wheel_right()))
    return "base speeds not finite";
  if (!wire::Mode_IsValid(m.mode())) return "unknown mode";
  if (!wire::ArmRefusalReason_IsValid(m.last_arm_refusal())) return "unknown arm refusal reason";
  if ((m.arm_refusals() == 0) != (m.last_arm_refusal() == wire::ARM_REFUSAL_UNSPECIFIED))
    return "arm refusal count and reason disagree";
  s.stamp_ns = m.stamp_ns();
  s.v = m.v();
  s.omega = m.omega();
  s.wheel_left = m.wheel_left();
  s.wheel_right = m.wheel_right();
  s.safety = m.safety();
  s.mode = m.mode();
  s.last_command_seq = m.last_command_seq();
  s.arm_refusals = m.arm_refusals();
  s.last_arm_refusal = static_cast<int>(m.last_arm_refusal());
  s.last_refused_seq = m.last_refused_seq();
  if (m.has_head()) {
    const wire::HeadState& h = m.head();
    if (!std::isfinite(h.pan()) || !std::isfinite(h.tilt()) || !std::isfinite(h.pan_setpoint()) ||
        !std::isfinite(h.tilt_setpoint()) || !std::isfinite(h.pan_truth()) || !std::isfinite(h.tilt_truth()))
      return "head angles not finite";
    if (!wire::GazeRefusalReason_IsValid(h.last_gaze_refusal())) return "unknown gaze refusal reason";
    s.head = {true, h.pan(), h.tilt(), h.pan_setpoint(), h.tilt_setpoint(), h.gaze_active(), h.gaze_refusals(),
              static_cast<int>(h.last_gaze_refusal()), h.last_gaze_refused_seq(), h.pan_truth(), h.tilt_truth()};
  }
  *out = s;
  return std::nullopt;
}

void to_wire(const BaseArmCommand& c, wire::Command* out) {
  out->Clear();
  out->set_stamp_ns(c.stamp_ns);
  out->set_mode(c.mode);
  out->set_v(c.v);
  out->set_omega(c.omega);
  out->mutable_arm_target()->set_x(c.arm_target_R.x());
  out->mutable_arm_target()->set_y(c.arm_target_R.y());
  out->mutable_arm_target()->set_z(c.arm_target_R.z());
  out->set_wrist_pitch(c.wrist_pitch);
  out->set_wrist_roll(c.wrist_roll);
  out->set_deadman(c.deadman);
  if (c.gaze.present) {
    out->mutable_gaze()->set_active(c.gaze.active);
    out->mutable_gaze()->mutable_point_w()->set_x(c.gaze.point_W.x());
    out->mutable_gaze()->mutable_point_w()->set_y(c.gaze.point_W.y());
    out->mutable_gaze()->mutable_point_w()->set_z(c.gaze.point_W.z());
  }
}

std::optional<std::string> from_wire(const wire::Command& m, uint64_t seq, BaseArmCommand* out) {
  if (!wire::Mode_IsValid(m.mode()) || m.mode() == wire::MODE_UNSPECIFIED) return "command mode unknown";
  if (!std::isfinite(m.v()) || !std::isfinite(m.omega()) || !math::finite3(m.arm_target()) ||
      !std::isfinite(m.wrist_pitch()) || !std::isfinite(m.wrist_roll()))
    return "command has non-finite values";
  if (m.has_gaze() && !math::finite3(m.gaze().point_w())) return "command gaze target not finite";
  BaseArmCommand c;
  c.stamp_ns = m.stamp_ns();
  c.seq = seq;
  c.mode = m.mode();
  c.v = m.v();
  c.omega = m.omega();
  c.arm_target_R << m.arm_target().x(), m.arm_target().y(), m.arm_target().z();
  c.wrist_pitch = m.wrist_pitch();
  c.wrist_roll = m.wrist_roll();
  c.deadman = m.deadman();
  if (m.has_gaze()) {
    c.gaze.present = true;
    c.gaze.active = m.gaze().active();
    c.gaze.point_W << m.gaze().point_w().x(), m.gaze().point_w().y(), m.gaze().point_w().z();
  }
  *out = c;
  return std::nullopt;
}

namespace {
void fill_header(const RangeScanData& s, wire::RangeScan* m) {
  m->set_stamp_ns(s.stamp_ns);
  m->set_scan_id(s.scan_id);
  m->set_sensor(s.kind == RangeSensorKind::kLaser ? wire::RANGE_SENSOR_LASER : wire::RANGE_SENSOR_SONAR);
  m->set_sensor_name(s.sensor_name);
  to_wire(s.T_W_R_odom, m->mutable_t_w_r());
  to_wire(s.T_W_R_truth, m->mutable_t_w_r_truth());
  to_wire(s.T_R_S, m->mutable_t_r_s());
  m->set_angle_min(s.angle_min);
  m->set_angle_step(s.angle_step);
  m->set_beam_count(static_cast<uint32_t>(s.size()));
  m->set_range_min(s.range_min);
  m->set_range_max(s.range_max);
  m->set_beam_width(s.beam_width);
}
void fill_beams(const RangeScanData& s, size_t first, size_t n, wire::RangeScan* m) {
  m->set_first_beam(static_cast<uint32_t>(first));
  m->clear_ranges();
  m->clear_valid();
  m->clear_no_return();
  const bool nr = s.no_return.size() == s.ranges.size();
  for (size_t i = first; i < first + n; ++i) {
    m->add_ranges(s.ranges[i]);
    m->add_valid(s.valid[i] != 0);
    if (nr) m->add_no_return(s.no_return[i] != 0);
  }
}
}  // namespace

std::vector<wire::RangeScan> to_wire_chunks(const RangeScanData& s, size_t max_bytes) {
  std::vector<wire::RangeScan> out;
  const size_t n = std::min(s.ranges.size(), s.valid.size());
  wire::RangeScan header;
  fill_header(s, &header);
  header.set_first_beam(static_cast<uint32_t>(n));  // worst-case varint size
  const size_t head = header.ByteSizeLong() + 18;  // + tags and lengths of the three packed fields
  // 4 bytes per float, 1 per bool (packed).
  const size_t bytes_per_beam = s.no_return.size() == n ? 6 : 5;
  size_t per = max_bytes > head + bytes_per_beam ? (max_bytes - head) / bytes_per_beam : 1;
  per = std::max<size_t>(1, per);
  for (size_t first = 0; first < n || (n == 0 && out.empty());) {
    size_t take = std::min(per, n - first);
    wire::RangeScan m = header;
    fill_beams(s, first, take, &m);
    while (take > 1 && m.ByteSizeLong() > max_bytes) {  // safety net; the estimate is conservative
      take = take * 9 / 10;
      fill_beams(s, first, take, &m);
    }
    out.push_back(std::move(m));
    first += take;
    if (n == 0) break;
  }
  return out;
}

std::optional<std::string> from_wire(const wire::RangeScan& m, RangeScanData* out, uint32_t* first_beam) {
  if (m.ranges_size() != m.valid_size()) return "ranges and valid differ in length";
  if (m.no_return_size() != 0 && m.no_return_size() != m.ranges_size()) return "no_return length mismatch";
  if (m.beam_angles_size() != 0 && m.beam_angles_size() != m.ranges_size()) return "beam_angles length mismatch";
  if (m.beam_count() > kMaxBeams) return "too many beams";
  if (static_cast<uint64_t>(m.first_beam()) + static_cast<uint64_t>(m.ranges_size()) > m.beam_count())
    return "chunk exceeds beam_count";
  if (m.sensor() != wire::RANGE_SENSOR_LASER && m.sensor() != wire::RANGE_SENSOR_SONAR) return "unknown sensor";
  if (!std::isfinite(m.angle_min()) || !std::isfinite(m.angle_step()) || !std::isfinite(m.beam_width()))
    return "angles not finite";
  if (!(m.range_min() >= 0 && m.range_max() > m.range_min() && std::isfinite(m.range_max())))
    return "bad range limits";
  if (m.sensor_name().size() > 64) return "sensor name too long";
  RangeScanData s;
  if (auto e = from_wire(m.t_w_r(), &s.T_W_R_odom)) return "T_W_R: " + *e;
  if (m.has_t_w_r_truth()) {
    if (auto e = from_wire(m.t_w_r_truth(), &s.T_W_R_truth)) return "T_W_R_truth: " + *e;
  }
  if (auto e = from_wire(m.t_r_s(), &s.T_R_S)) return "T_R_S: " + *e;
  s.stamp_ns = m.stamp_ns();
  s.scan_id = m.scan_id();
  s.kind = m.sensor() == wire::RANGE_SENSOR_LASER ? RangeSensorKind::kLaser : RangeSensorKind::kSonar;
  s.sensor_name = m.sensor_name();
  s.angle_min = m.angle_min();
  s.angle_step = m.angle_step();
  s.range_min = m.range_min();
  s.range_max = m.range_max();
  s.beam_width = m.beam_width();
  s.ranges.assign(m.ranges().begin(), m.ranges().end());
  s.valid.resize(s.ranges.size());
  for (size_t i = 0; i < s.ranges.size(); ++i) {
    // A valid beam must hold a finite range within the limits.
    const bool ok = m.valid(static_cast<int>(i)) && std::isfinite(s.ranges[i]) && s.ranges[i] >= m.range_min() &&
                    s.ranges[i] <= m.range_max();
    s.valid[i] = ok ? 1 : 0;
  }
  if (m.no_return_size() != 0) {
    s.no_return.resize(s.ranges.size());
    for (size_t i = 0; i < s.ranges.size(); ++i)
      s.no_return[i] = (m.no_return(static_cast<int>(i)) && !s.valid[i]) ? 1 : 0;
  }
  *first_beam = m.first_beam();
  *out = std::move(s);
  return std::nullopt;
}

}  // namespace hemm::robot
