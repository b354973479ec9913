#include "operator/device/trajectory_csv.h"

#include <charconv>
#include <cmath>
#include <fstream>

namespace hemm::device {
namespace {

constexpr const char* kHeaderPos = "t_s,x,y,z,buttons";
constexpr const char* kHeaderFull = "t_s,x,y,z,qw,qx,qy,qz,buttons";

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

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::string TrajectoryError::to_string() const {
  return file + ":" + std::to_string(line) + ": " + message;
}

const char* trajectory_csv_header(bool with_orientation) {
  return with_orientation ? kHeaderFull : kHeaderPos;
}

std::optional<TrajectoryError> parse_trajectory_csv(std::string_view text,
                                                    const std::string& file_name,
                                                    const DeviceLimits& limits, Trajectory* out) {
  auto fail = [&](int line, std::string msg) {
    return std::optional<TrajectoryError>(TrajectoryError{file_name, line, std::move(msg)});
  };
  Trajectory t;
  int fields_expected = 0;  // 5 or 9 once the first row fixed it
  int line_no = 0;
  bool first_content = true;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t nl = text.find('\n', pos);
    if (nl == std::string_view::npos) nl = text.size();
    const std::string_view line = trim(text.substr(pos, nl - pos));
    pos = nl + 1;
    ++line_no;
    if (line.empty() || line.front() == '#') continue;
    if (first_content) {
      first_content = false;
      if (line == kHeaderPos || line == kHeaderFull) {
        fields_expected = (line == kHeaderFull) ? 9 : 5;
        continue;
      }
    }
    std::string_view f[10];
    int n = 0;
    std::size_t start = 0;
    while (true) {
      const std::size_t c = line.find(',', start);
      if (n == 10) return fail(line_no, "too many fields (expected 5 or 9)");
      f[n++] = trim(line.substr(start, c == std::string_view::npos ? c : c - start));
      if (c == std::string_view::npos) break;
      start = c + 1;
    }
    if (n != 5 && n != 9)
      return fail(line_no, "expected 5 fields (t_s,x,y,z,buttons) or 9 "
                           "(t_s,x,y,z,qw,qx,qy,qz,buttons), got " + std::to_string(n));
    if (fields_expected == 0) fields_expected = n;
    if (n != fields_expected)
      return fail(line_no, "expected " + std::to_string(fields_expected) +
                               " fields like the rows before, got " + std::to_string(n));
    TrajectorySample s;
    static const char* const kNames[] = {"t_s", "x", "y", "z", "qw", "qx", "qy", "qz"};
    double v[8];
    for (int i = 0; i < n - 1; ++i) {
      if (!parse_double(f[i], &v[i]))
        return fail(line_no, std::string("field ") + kNames[i] + ": not a finite number: '" +
                                 std::string(f[i]) + "'");
    }
    if (!parse_u32(f[n - 1], &s.buttons))
      return fail(line_no, "field buttons: not an unsigned 32-bit integer: '" +
                               std::string(f[n - 1]) + "'");
    s.t_s = v[0];
    s.position_H = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!t.samples.empty() && !(s.t_s > t.samples.back().t_s))
      return fail(line_no, "time not strictly increasing (" + std::string(f[0]) + " after " +
                               std::to_string(t.samples.back().t_s) + ")");
    if (!limits.contains(s.position_H, kTrajectoryWorkspaceTolerance))
      return fail(line_no, "position outside the device workspace");
    if (n == 9) {
      Eigen::Quaterniond q(v[4], v[5], v[6], v[7]);
      if (std::abs(q.norm() - 1.0) > 1e-3)
        return fail(line_no, "orientation is not a unit quaternion (norm " +
                                 std::to_string(q.norm()) + ")");
      q.normalize();
      s.orientation_H = q;
    }
    t.samples.push_back(s);
  }
  if (t.samples.empty()) return fail(line_no, "no samples");
  t.has_orientation = (fields_expected == 9);
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

std::size_t format_trajectory_row(const TrajectorySample& s, bool with_orientation, char* buf,
                                  std::size_t size) {
  char* p = buf;
  char* const end = buf + size;
  auto put_double = [&](double v, char sep) {
    if (p == nullptr) return;
    const auto r = std::to_chars(p, end, v);
    if (r.ec != std::errc() || r.ptr == end) {
      p = nullptr;
      return;
    }
    p = r.ptr;
    *p++ = sep;
  };
  put_double(s.t_s, ',');
  put_double(s.position_H.x(), ',');
  put_double(s.position_H.y(), ',');
  put_double(s.position_H.z(), ',');
  if (with_orientation) {
    put_double(s.orientation_H.w(), ',');
    put_double(s.orientation_H.x(), ',');
    put_double(s.orientation_H.y(), ',');
    put_double(s.orientation_H.z(), ',');
  }
  if (p == nullptr) return 0;
  const auto r = std::to_chars(p, end, s.buttons);
  if (r.ec != std::errc() || r.ptr == end) return 0;
  p = r.ptr;
  *p++ = '\n';
  return static_cast<std::size_t>(p - buf);
}

}  // namespace hemm::device
