#include "operator/device/trajectory_csv.h"

#include <charconv>
#include <cmath>
#include <fstream>

#include "operator/device/csv_row.h"

namespace hemm::device {
namespace {

constexpr const char* kHeaderPos = "t_s,x,y,z,buttons";
constexpr const char* kHeaderFull = "t_s,x,y,z,qw,qx,qy,qz,buttons";
constexpr std::string_view kV2Prefix = "t_s,ee0_";

// Version 2 columns of one end-effector, in file order.
enum Column {
  kX, kY, kZ, kQw, kQx, kQy, kQz, kVx, kVy, kVz, kWx, kWy, kWz,
  kEnabled, kButtons, kInputs, kDeadman, kGrip, kGripV, kJoyX, kJoyY, kSwitch, kAttached,
  kColumns
};
static_assert(kColumns == kTrajectoryColumnsPerEndEffector);
constexpr const char* kColumnNames[kColumns] = {
    "x",  "y",  "z",       "qw",      "qx",     "qy",      "qz",   "vx",     "vy",    "vz",     "wx",      "wy",
    "wz", "enabled", "buttons", "inputs", "deadman", "grip", "grip_v", "joy_x", "joy_y", "switch", "attached"};
constexpr int kMaxFields = 1 + kColumns * kMaxEndEffectors;

bool parse_double(std::string_view s, double* v) {
  if (s.empty()) return false;
  const char* b = s.data();
  const char* e = b + s.size();
  if (*b == '+') ++b;  // from_chars refuses a leading '+'
  const auto r = std::from_chars(b, e, *v);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(*v);
}

bool parse_u32(std::string_view s, std::uint32_t* v) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), *v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_flag(std::string_view s, bool* v) {
  if (s != "0" && s != "1") return false;
  *v = s == "1";
  return true;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// Splits at commas into f[0..capacity); returns the field count, or -1 if the
// line has more than `capacity` fields.
int split(std::string_view line, std::string_view* f, int capacity) {
  int n = 0;
  std::size_t start = 0;
  while (true) {
    const std::size_t c = line.find(',', start);
    if (n == capacity) return -1;
    f[n++] = trim(line.substr(start, c == std::string_view::npos ? c : c - start));
    if (c == std::string_view::npos) return n;
    start = c + 1;
  }
}

// A quaternion within rounding of unit length is kept bit for bit (so a
// recorded orientation replays exactly); one further off is normalised.
// Returns false if it is not a unit quaternion within 1e-3.
bool unit_quaternion(double w, double x, double y, double z, Eigen::Quaterniond* q, double* norm) {
  *q = Eigen::Quaterniond(w, x, y, z);
  *norm = q->norm();
  if (std::abs(*norm - 1.0) > 1e-3) return false;
  if (std::abs(*norm - 1.0) > 1e-12) q->normalize();
  return true;
}

std::string column_name(int ee, int column) {
  return "ee" + std::to_string(ee) + "_" + kColumnNames[column];
}

// One version 2 row (fields after t_s) into s; an error message or empty.
std::string parse_v2_end_effectors(const std::string_view* f, int end_effectors, const DeviceLimits& limits,
                                   TrajectorySample* s) {
  s->end_effectors = end_effectors;
  for (int k = 0; k < end_effectors; ++k) {
    const std::string_view* c = f + k * kColumns;
    EndEffectorSample& e = s->ee[static_cast<std::size_t>(k)];
    auto bad = [&](int column, const char* what) {
      return "field " + column_name(k, column) + ": " + what + ": '" + std::string(c[column]) + "'";
    };
    double v[kColumns] = {};
    for (int i : {kX, kY, kZ, kQw, kQx, kQy, kQz, kVx, kVy, kVz, kWx, kWy, kWz, kGrip, kGripV, kJoyX, kJoyY})
      if (!parse_double(c[i], &v[i])) return bad(i, "not a finite number");
    bool flag[kColumns] = {};
    for (int i : {kEnabled, kDeadman, kSwitch, kAttached})
      if (!parse_flag(c[i], &flag[i])) return bad(i, "not 0 or 1");
    std::uint32_t inputs = 0;
    if (!parse_u32(c[kButtons], &e.handle.buttons)) return bad(kButtons, "not an unsigned 32-bit integer");
    if (!parse_u32(c[kInputs], &inputs) || (inputs & ~kAllHandleInputs) != 0)
      return bad(kInputs, "not a set of input bits (0 .. 15)");
    for (int i : {kJoyX, kJoyY})
      if (std::abs(v[i]) > 1.0) return bad(i, "joystick axis outside [-1, 1]");

    e.position_H = Eigen::Vector3d(v[kX], v[kY], v[kZ]);
    if (!limits.ee[static_cast<std::size_t>(k)].contains(e.position_H, kTrajectoryWorkspaceTolerance))
      return "ee" + std::to_string(k) + ": position outside the device workspace";
    double norm = 0.0;
    if (!unit_quaternion(v[kQw], v[kQx], v[kQy], v[kQz], &e.orientation_H, &norm))
      return "ee" + std::to_string(k) + ": orientation is not a unit quaternion (norm " + std::to_string(norm) + ")";
    e.velocity_H = Eigen::Vector3d(v[kVx], v[kVy], v[kVz]);
    e.angular_velocity_H = Eigen::Vector3d(v[kWx], v[kWy], v[kWz]);
    e.enabled = flag[kEnabled];

    HandleInputs& h = e.handle;
    h.has_deadman = (inputs & kHasDeadman) != 0;
    h.has_grip = (inputs & kHasGrip) != 0;
    h.has_joystick = (inputs & kHasJoystick) != 0;
    h.has_clutch = (inputs & kHasClutch) != 0;
    // An input the handle lacks must hold its default: a value there means
    // the file and its inputs column disagree.
    if (!h.has_deadman && flag[kDeadman]) return bad(kDeadman, "the handle has no dead-man (inputs)");
    if (!h.has_grip && (v[kGrip] != 0.0 || v[kGripV] != 0.0))
      return bad(v[kGrip] != 0.0 ? kGrip : kGripV, "the handle has no grip (inputs)");
    if (!h.has_joystick && (v[kJoyX] != 0.0 || v[kJoyY] != 0.0 || flag[kSwitch]))
      return bad(v[kJoyX] != 0.0 ? kJoyX : v[kJoyY] != 0.0 ? kJoyY : kSwitch, "the handle has no joystick (inputs)");
    if (!h.has_clutch && !flag[kAttached]) return bad(kAttached, "the handle has no clutch (inputs)");
    h.deadman = flag[kDeadman];
    h.grip_position = v[kGrip];
    h.grip_velocity = v[kGripV];
    h.joystick = Eigen::Vector2d(v[kJoyX], v[kJoyY]);
    h.switch_on = flag[kSwitch];
    h.attached = flag[kAttached];
  }
  return {};
}

}  // namespace

std::string TrajectoryError::to_string() const {
  return file + ":" + std::to_string(line) + ": " + message;
}

std::string trajectory_csv_header(int end_effectors) {
  std::string h = "t_s";
  for (int k = 0; k < end_effectors; ++k)
    for (int c = 0; c < kColumns; ++c) h += "," + column_name(k, c);
  return h;
}

std::optional<TrajectoryError> parse_trajectory_csv(std::string_view text,
                                                    const std::string& file_name,
                                                    const DeviceLimits& limits, Trajectory* out) {
  auto fail = [&](int line, std::string msg) {
    return std::optional<TrajectoryError>(TrajectoryError{file_name, line, std::move(msg)});
  };
  Trajectory t;
  int version = 1;
  int fields_expected = 0;  // version 1: 5 or 9 once the first row fixed it; version 2: from the header
  int line_no = 0;
  bool first_content = true;
  std::size_t pos = 0;
  std::string_view f[kMaxFields];
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    const std::string_view line = trim(text.substr(pos, nl - pos));
    pos = nl + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') continue;
    if (first_content) {
      first_content = false;
      if (line.substr(0, kV2Prefix.size()) == kV2Prefix) {
        for (int n = 1; n <= kMaxEndEffectors && version == 1; ++n) {
          if (line != trajectory_csv_header(n)) continue;
          version = 2;
          t.end_effectors = n;
          fields_expected = 1 + n * kColumns;
        }
        if (version != 2)
          return fail(line_no, "not a trajectory header (expected " + trajectory_csv_header(1) +
                                   " with one group of " + std::to_string(kColumns) + " columns per end-effector)");
        if (t.end_effectors != limits.end_effectors)
          return fail(line_no, "the file has " + std::to_string(t.end_effectors) + " end-effector(s), the device " +
                                   std::to_string(limits.end_effectors));
        continue;
      }
      if (limits.end_effectors != 1)
        return fail(line_no, "a version 1 file has one end-effector, the device " +
                                 std::to_string(limits.end_effectors));
      if (line == kHeaderPos || line == kHeaderFull) {
        fields_expected = (line == kHeaderFull) ? 9 : 5;
        continue;
      }
    }
    TrajectorySample s;
    if (version == 2) {
      const int n = split(line, f, fields_expected);
      if (n < 0) return fail(line_no, "too many fields (expected " + std::to_string(fields_expected) + ")");
      if (n != fields_expected)
        return fail(line_no, "expected " + std::to_string(fields_expected) + " fields as in the header, got " +
                                 std::to_string(n));
      if (!parse_double(f[0], &s.t_s))
        return fail(line_no, "field t_s: not a finite number: '" + std::string(f[0]) + "'");
      if (!t.samples.empty() && !(s.t_s > t.samples.back().t_s))
        return fail(line_no, "time not strictly increasing (" + std::string(f[0]) + " after " +
                                 std::to_string(t.samples.back().t_s) + ")");
      if (std::string e = parse_v2_end_effectors(f + 1, t.end_effectors, limits, &s); !e.empty())
        return fail(line_no, std::move(e));
      t.samples.push_back(s);
      continue;
    }
    const int n = split(line, f, 10);
    if (n < 0) return fail(line_no, "too many fields (expected 5 or 9)");
    if (n != 5 && n != 9)
      return fail(line_no, "expected 5 fields (t_s,x,y,z,buttons) or 9 "
                           "(t_s,x,y,z,qw,qx,qy,qz,buttons), got " + std::to_string(n));
    if (fields_expected == 0) fields_expected = n;
    if (n != fields_expected)
      return fail(line_no, "expected " + std::to_string(fields_expected) +
                               " fields like the rows before, got " + std::to_string(n));
    static const char* const kNames[] = {"t_s", "x", "y", "z", "qw", "qx", "qy", "qz"};
    double v[8];
    for (int i = 0; i < n - 1; ++i) {
      if (!parse_double(f[i], &v[i]))
        return fail(line_no, std::string("field ") + kNames[i] + ": not a finite number: '" +
                                 std::string(f[i]) + "'");
    }
    EndEffectorSample& e = s.ee[0];
    if (!parse_u32(f[n - 1], &e.handle.buttons))
      return fail(line_no, "field buttons: not an unsigned 32-bit integer: '" +
                               std::string(f[n - 1]) + "'");
    s.t_s = v[0];
    e.position_H = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!t.samples.empty() && !(s.t_s > t.samples.back().t_s))
      return fail(line_no, "time not strictly increasing (" + std::string(f[0]) + " after " +
                               std::to_string(t.samples.back().t_s) + ")");
    if (!limits.ee[0].contains(e.position_H, kTrajectoryWorkspaceTolerance))
      return fail(line_no, "position outside the device workspace");
    if (n == 9) {
      double norm = 0.0;
      if (!unit_quaternion(v[4], v[5], v[6], v[7], &e.orientation_H, &norm))
        return fail(line_no, "orientation is not a unit quaternion (norm " + std::to_string(norm) + ")");
    }
    t.samples.push_back(s);
  }
  if (t.samples.empty()) return fail(line_no, "no samples");
  t.has_orientation = version == 2 || fields_expected == 9;
  t.has_twist = version == 2;
  *out = std::move(t);
  return std::nullopt;
}

std::optional<TrajectoryError> load_trajectory_csv(const std::string& path,
                                                   const DeviceLimits& limits, Trajectory* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return TrajectoryError{path, 0, "cannot open file"};
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  if (size < 0) return TrajectoryError{path, 0, "cannot read file"};
  if (static_cast<std::size_t>(size) > kMaxTrajectoryFileBytes)
    return TrajectoryError{path, 0, "file too large"};
  in.seekg(0);
  std::string text(static_cast<std::size_t>(size), '\0');
  if (!in.read(text.data(), size)) return TrajectoryError{path, 0, "cannot read file"};
  return parse_trajectory_csv(text, path, limits, out);
}

std::size_t format_trajectory_row(const TrajectorySample& s, char* buf, std::size_t size) {
  if (s.end_effectors < 1 || s.end_effectors > kMaxEndEffectors) return 0;
  CsvRowWriter w(buf, size);
  w.put(s.t_s);
  for (int k = 0; k < s.end_effectors; ++k) {
    const EndEffectorSample& e = s.ee[static_cast<std::size_t>(k)];
    const HandleInputs& h = e.handle;
    w.put_vector(e.position_H);
    w.put(e.orientation_H.w());
    w.put_vector(e.orientation_H.vec());
    w.put_vector(e.velocity_H);
    w.put_vector(e.angular_velocity_H);
    w.put(e.enabled ? 1 : 0);
    w.put(h.buttons);
    w.put(handle_input_bits(h));
    // Inputs the handle lacks are written as their defaults, as the parser
    // requires, whatever the device left in them.
    w.put(h.has_deadman && h.deadman ? 1 : 0);
    w.put(h.has_grip ? h.grip_position : 0.0);
    w.put(h.has_grip ? h.grip_velocity : 0.0);
    w.put(h.has_joystick ? h.joystick.x() : 0.0);
    w.put(h.has_joystick ? h.joystick.y() : 0.0);
    w.put(h.has_joystick && h.switch_on ? 1 : 0);
    w.put(!h.has_clutch || h.attached ? 1 : 0);
  }
  return w.finish();
}

}  // namespace hemm::device
