#include "operator/station/explore_route.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <numbers>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "operator/station/operator_task.h"

namespace hemm::op {

namespace {

std::vector<std::string> split_words(std::string_view line) {
  std::vector<std::string> w;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t b = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > b) w.emplace_back(line.substr(b, i - b));
  }
  return w;
}

bool parse_number(const std::string& s, double* out) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || errno != 0 || end != s.c_str() + s.size() || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

// Route and feature names: lower-case letters, digits and '-', starting with
// a letter or digit, at most 64 characters.
bool is_name(const std::string& s) {
  if (s.empty() || s.size() > 64 || s.front() == '-') return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-')) return false;
  return true;
}

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

// Appends key k to the route `name` of `routes` (a new route when none has
// that name; `seen`: per route the features met, in order): the rules every
// route shares (explore6 and explore3). nullopt, or the reason after `at`.
template <class Route, class Key>
std::optional<std::string> route_add_key(std::vector<Route>& routes, std::vector<std::vector<std::string>>& seen,
                                         const std::string& name, Key k, const std::string& at, const char* d) {
  std::size_t ri = 0;
  while (ri < routes.size() && routes[ri].name != name) ++ri;
  if (ri == routes.size()) {
    if (k.t_s != 0.0)
      return at + d + ": route " + name + "'s first key must be at t = 0 (the hand starts there)";
    routes.push_back({name, {}});
    seen.emplace_back();
  }
  Route& route = routes[ri];
  if (!route.keys.empty() && !(k.t_s > route.keys.back().t_s))
    return at + d + fmt(": t = %g s is not after the previous key's %g s", k.t_s, route.keys.back().t_s) + " (line " +
           std::to_string(route.keys.back().line) + ")";
  if (k.feature != "-") {
    std::vector<std::string>& s = seen[ri];
    if (s.empty() || s.back() != k.feature) {
      for (const std::string& f : s)
        if (f == k.feature)
          return at + d + ": feature '" + k.feature + "' of route " + name + " resumes after '" + s.back() +
                 "': a feature's keys must be consecutive";
      s.push_back(k.feature);
    }
  }
  route.keys.push_back(std::move(k));
  return std::nullopt;
}

// A route file's closing checks (explore6 or explore3: d).
template <class Route>
std::optional<std::string> routes_complete(const std::vector<Route>& routes,
                                           const std::vector<std::vector<std::string>>& seen, const std::string& at,
                                           const char* d) {
  for (std::size_t i = 0; i < routes.size(); ++i) {
    if (routes[i].keys.size() < 2) return at + d + " route " + routes[i].name + " needs at least two keys";
    if (seen[i].empty()) return at + d + " route " + routes[i].name + " names no feature (every key is '-')";
  }
  return std::nullopt;
}

template <class Route>
std::vector<RouteFeature> features_of(const Route& r) {
  std::vector<RouteFeature> f;
  for (const auto& k : r.keys) {
    if (k.feature == "-") continue;
    if (f.empty() || f.back().name != k.feature) f.push_back({k.feature, k.t_s, k.t_s});
    f.back().t1_s = k.t_s;
  }
  return f;
}

template <class Route>
std::string names_of(const std::vector<Route>& routes) {
  std::string s;
  for (const Route& r : routes) s += (s.empty() ? "" : ", ") + r.name;
  return s.empty() ? "none" : s;
}

}  // namespace

const ExploreRoute* SceneExploration::find(const std::string& name) const {
  for (const ExploreRoute& r : routes)
    if (r.name == name) return &r;
  return nullptr;
}

const ExploreRoute3* SceneExploration::find3(const std::string& name) const {
  for (const ExploreRoute3& r : routes3)
    if (r.name == name) return &r;
  return nullptr;
}

std::string SceneExploration::route_names() const { return names_of(routes); }
std::string SceneExploration::route3_names() const { return names_of(routes3); }

std::optional<std::string> parse_scene_exploration(std::string_view text, const std::string& source,
                                                   SceneExploration* out) {
  // The header comment: the first thing in the file but an XML declaration.
  std::size_t begin = 0;
  while (begin < text.size() && std::isspace(static_cast<unsigned char>(text[begin]))) ++begin;
  if (text.substr(begin, 5) == "<?xml") {
    const std::size_t e = text.find("?>", begin);
    if (e == std::string_view::npos) return source + ":1: unterminated XML declaration";
    begin = e + 2;
    while (begin < text.size() && std::isspace(static_cast<unsigned char>(text[begin]))) ++begin;
  }
  SceneExploration r;
  if (text.substr(begin, 4) != "<!--") {  // no header: no routes
    *out = std::move(r);
    return std::nullopt;
  }
  const std::size_t end = text.find("-->", begin + 4);
  int line = 1;
  for (std::size_t i = 0; i < begin; ++i) line += text[i] == '\n';
  if (end == std::string_view::npos) return source + ":" + std::to_string(line) + ": unterminated header comment";
  const std::string_view header = text.substr(begin + 4, end - begin - 4);

  bool has_start = false, has_region = false;
  int start_line = 0;
  // Per route: the features seen, to refuse one that resumes after another.
  std::vector<std::vector<std::string>> seen, seen3;
  std::size_t pos = 0;
  for (; pos <= header.size(); ++line) {
    std::size_t nl = header.find('\n', pos);
    if (nl == std::string_view::npos) nl = header.size();
    const std::vector<std::string> w = split_words(header.substr(pos, nl - pos));
    pos = nl + 1;
    if (w.empty() || w[0].rfind("explore", 0) != 0 || w[0].back() != ':') continue;  // prose
    const std::string at = source + ":" + std::to_string(line) + ": ";
    const std::string& d = w[0];
    std::vector<double> v;
    // The numbers of w[from, from + n) (then the caller's own words).
    auto numbers = [&](std::size_t from, std::size_t n, std::string* why) {
      v.clear();
      for (std::size_t i = from; i < from + n; ++i) {
        double x = 0;
        if (!parse_number(w[i], &x)) {
          *why = "'" + w[i] + "' is not a finite number";
          return false;
        }
        v.push_back(x);
      }
      return true;
    };
    std::string why;
    if (d == "explore-start:") {
      if (has_start) return at + "explore-start: given twice (first on line " + std::to_string(start_line) + ")";
      if (w.size() != 4) return at + "explore-start: expected X Y THETA (3 numbers), got " + std::to_string(w.size() - 1);
      if (!numbers(1, 3, &why)) return at + "explore-start: " + why;
      if (std::abs(v[0]) > kRouteMaxWorld_m || std::abs(v[1]) > kRouteMaxWorld_m || std::abs(v[2]) > 2 * std::numbers::pi)
        return at + "explore-start: x, y must be within 100 m, theta within 2 pi";
      r.start_W = {v[0], v[1], v[2]};
      has_start = true;
      start_line = line;
    } else if (d == "explore-region:") {
      if (has_region) return at + "explore-region: given twice";
      if (w.size() != 7)
        return at + "explore-region: expected XMIN YMIN ZMIN XMAX YMAX ZMAX (6 numbers), got " +
               std::to_string(w.size() - 1);
      if (!numbers(1, 6, &why)) return at + "explore-region: " + why;
      for (double x : v)
        if (std::abs(x) > kRouteMaxWorld_m) return at + "explore-region: corners must be within 100 m";
      for (int i = 0; i < 3; ++i)
        if (!(v[i] < v[i + 3])) return at + "explore-region: each minimum must be below its maximum";
      r.region_W = Eigen::AlignedBox3d(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
      has_region = true;
    } else if (d == "explore6:") {
      if (w.size() != 8)
        return at + "explore6: expected ROUTE T X Y Z TILT_X FEATURE (7 fields), got " + std::to_string(w.size() - 1);
      const std::string& name = w[1];
      if (!is_name(name)) return at + "explore6: route name '" + name + "': lower-case letters, digits and '-'";
      if (!numbers(2, 5, &why)) return at + "explore6: " + why;
      const std::string& feature = w[7];
      if (feature != "-" && !is_name(feature))
        return at + "explore6: feature '" + feature + "': lower-case letters, digits and '-', or '-' for a transit";
      RouteKey k;
      k.t_s = v[0];
      k.tip_R = Eigen::Vector3d(v[1], v[2], v[3]);
      k.tilt_x_rad = v[4];
      k.feature = feature;
      k.line = line;
      if (!(k.t_s >= 0 && k.t_s <= kRouteMaxTime_s)) return at + "explore6: T must be within [0, 3600] s";
      if (k.tip_R.norm() > kRouteMaxTip_m) return at + "explore6: the tip must be within 5 m of R's origin";
      if (std::abs(k.tilt_x_rad) > kRouteMaxTilt_rad) return at + "explore6: |TILT_X| must be at most pi/2";
      if (auto e = route_add_key(r.routes, seen, name, std::move(k), at, "explore6")) return e;
    } else if (d == "explore3:") {
      if (w.size() != 7)
        return at + "explore3: expected ROUTE T X Y Z FEATURE (6 fields), got " + std::to_string(w.size() - 1);
      const std::string& name = w[1];
      if (!is_name(name)) return at + "explore3: route name '" + name + "': lower-case letters, digits and '-'";
      if (!numbers(2, 4, &why)) return at + "explore3: " + why;
      const std::string& feature = w[6];
      if (feature != "-" && !is_name(feature))
        return at + "explore3: feature '" + feature + "': lower-case letters, digits and '-', or '-' for a transit";
      Route3Key k;
      k.t_s = v[0];
      k.p_W = Eigen::Vector3d(v[1], v[2], v[3]);
      k.feature = feature;
      k.line = line;
      if (!(k.t_s >= 0 && k.t_s <= kRouteMaxTime_s)) return at + "explore3: T must be within [0, 3600] s";
      if (k.p_W.cwiseAbs().maxCoeff() > kRouteMaxWorld_m) return at + "explore3: the point must be within 100 m";
      if (auto e = route_add_key(r.routes3, seen3, name, std::move(k), at, "explore3")) return e;
    } else {
      return at + "unknown directive '" + d + "' (explore-start:, explore-region:, explore6:, explore3:)";
    }
  }
  const std::string at = source + ": ";
  if (auto e = routes_complete(r.routes, seen, at, "explore6")) return e;
  if (auto e = routes_complete(r.routes3, seen3, at, "explore3")) return e;
  const bool any = !r.routes.empty() || !r.routes3.empty();
  if (any && !has_start) return at + "a scene with explore6 or explore3 routes needs explore-start: X Y THETA";
  if (any && !has_region) return at + "a scene with explore6 or explore3 routes needs explore-region: (6 numbers)";
  *out = std::move(r);
  return std::nullopt;
}

std::vector<RouteFeature> route_features(const ExploreRoute& r) { return features_of(r); }
std::vector<RouteFeature> route_features(const ExploreRoute3& r) { return features_of(r); }

std::optional<std::string> check_route_reach(const ExploreRoute& r, const Eigen::Vector3d& origin_R,
                                             const device::EndEffectorLimits& l, const std::string& source) {
  auto vec = [](const Eigen::Vector3d& p) { return fmt("(%.3f %.3f %.3f)", p.x(), p.y(), p.z()); };
  for (std::size_t i = 0; i < r.keys.size(); ++i) {
    const RouteKey& k = r.keys[i];
    const std::string at = source + ":" + std::to_string(k.line) + ": explore6 " + r.name + fmt(" at t = %g s: ", k.t_s);
    const Eigen::Vector3d p_H = k.tip_R - origin_R;
    if (!l.contains(p_H))
      return at + "the tip " + vec(k.tip_R) + " in R is out of the device's reach: " + vec(p_H) +
             " in H, outside its workspace box " + vec(l.workspace_min_H) + " to " + vec(l.workspace_max_H) +
             " (H's origin at " + vec(origin_R) + " in R)";
    if (i > 0 && l.max_linear_speed > 0) {
      const RouteKey& a = r.keys[i - 1];
      const double speed = (k.tip_R - a.tip_R).norm() / (k.t_s - a.t_s);
      if (speed > l.max_linear_speed)
        return at + fmt("the tip moves at %.2f m/s from the previous key, above the device's %.2f m/s", speed,
                        l.max_linear_speed);
    }
  }
  return std::nullopt;
}

Eigen::Vector3d route3_point_H(const Eigen::Vector3d& p_W, const math::Pose2& start_W, const math::ScaledMap& m) {
  const Eigen::Vector3d p_R = math::apply(math::inverse(start_W), p_W);
  return R_B_H().transpose() * math::unmap_point(m, p_R);
}

std::optional<std::string> check_route3_reach(const ExploreRoute3& r, const math::Pose2& start_W,
                                              const math::ScaledMap& m, const device::EndEffectorLimits& l,
                                              const std::string& source) {
  auto vec = [](const Eigen::Vector3d& p) { return fmt("(%.3f %.3f %.3f)", p.x(), p.y(), p.z()); };
  for (const Route3Key& k : r.keys) {
    const Eigen::Vector3d p_H = route3_point_H(k.p_W, start_W, m);
    if (!l.contains(p_H))
      return source + ":" + std::to_string(k.line) + ": explore3 " + r.name + fmt(" at t = %g s: ", k.t_s) +
             "the point " + vec(k.p_W) + " in W is out of the Omni's reach: " + vec(p_H) +
             " in H, outside its workspace box " + vec(l.workspace_min_H) + " to " + vec(l.workspace_max_H) +
             fmt(" (probe_3d: %.3f W m per device m, origin ", m.scale) + vec(m.origin_R) + " in R)";
  }
  return std::nullopt;
}

std::optional<std::string> load_scene_exploration(const std::string& path, SceneExploration* out) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return path + ": cannot read";
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) return path + ": cannot read";
  return parse_scene_exploration(ss.str(), path, out);
}

}  // namespace hemm::op
