#include "robot_side/truth/truth_eval.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string_view>
#include <utility>

#include "common/math/frames.h"
#include "report.pb.h"

namespace hemm::robot {
namespace {

enum Col {
  kT,
  kRobotX,
  kRobotY,
  kRobotTheta,
  kGoalX,
  kGoalY,
  kGoalZ,
  kProxyX,
  kProxyY,
  kFwX,
  kFwY,
  kScale,
  kStamp,
  kTruthX,
  kTruthY,
  kTruthTheta,
  kHasTruth,
  kColCount
};

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> f;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    f.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return f;
}

template <class T>
bool parse_number(std::string_view s, T* v) {
  // from_chars rejects a leading '+' and surrounding blanks; the operator
  // writes neither, and accepting them would hide a corrupted file.
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return ec == std::errc() && p == s.data() + s.size() && !s.empty();
}

struct Sample {
  std::int64_t t_ns;
  math::Pose2 pose;
};

// T_true(t): linear in x, y, shortest angle in theta; clamped to the ends.
math::Pose2 interpolate(const std::vector<Sample>& s, std::int64_t t) {
  if (t <= s.front().t_ns) return s.front().pose;
  if (t >= s.back().t_ns) return s.back().pose;
  const auto hi = std::upper_bound(s.begin(), s.end(), t, [](std::int64_t v, const Sample& x) { return v < x.t_ns; });
  const Sample& b = *hi;
  const Sample& a = *(hi - 1);
  const double u = static_cast<double>(t - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  const double dth = math::wrap_angle(b.pose.theta - a.pose.theta);
  return {a.pose.x + u * (b.pose.x - a.pose.x), a.pose.y + u * (b.pose.y - a.pose.y),
          math::wrap_angle(a.pose.theta + u * dth)};
}


}  // namespace

const std::vector<std::string>& world_log_required_columns() {
  static const std::vector<std::string> names = {
      "t_ns",    "robot_x", "robot_y", "robot_theta",    "goal_x",  "goal_y",  "goal_z",      "proxy_x",  "proxy_y",
      "fw_x",    "fw_y",    "scale",   "state_stamp_ns", "truth_x", "truth_y", "truth_theta", "has_truth"};
  return names;
}

bool read_world_log(const std::string& path, WorldLog* out, std::string* error) {
  auto fail = [&](const std::string& msg) {
    if (error) *error = msg;
    return false;
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path + ": cannot open (missing or unreadable)");

  std::string line;
  if (!std::getline(in, line) || line.empty() || line == "\r") return fail(path + ": empty file (no header line)");
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const std::vector<std::string_view> header = split(line);
  const auto& names = world_log_required_columns();
  int index[kColCount];
  for (int c = 0; c < kColCount; ++c) {
    index[c] = -1;
    for (std::size_t h = 0; h < header.size(); ++h) {
      if (header[h] != names[c]) continue;
      if (index[c] >= 0) return fail(path + ":1: column '" + names[c] + "' appears twice in the header");
      index[c] = static_cast<int>(h);
    }
    if (index[c] < 0) return fail(path + ":1: missing column '" + names[c] + "' in the header");
  }

  WorldLog log;
  std::size_t line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    // getline hit end-of-file before a newline: the writer was cut off
    // mid-line (a number there may be cut short, so the row is not used).
    if (in.eof()) {
      if (!line.empty()) ++log.truncated_lines;
      break;
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    const std::vector<std::string_view> f = split(line);
    const std::string where = path + ":" + std::to_string(line_no);
    if (f.size() != header.size())
      return fail(where + ": " + std::to_string(f.size()) + " fields, the header has " +
                  std::to_string(header.size()));
    // Character column (1-based) of field i, for the error message.
    auto column_of = [&](int i) {
      std::size_t col = 1;
      for (int k = 0; k < i; ++k) col += f[k].size() + 1;
      return col;
    };
    double v[kColCount];
    std::int64_t t = 0, stamp = 0, has = 0;
    for (int c = 0; c < kColCount; ++c) {
      const std::string_view s = f[index[c]];
      bool ok;
      if (c == kT) ok = parse_number(s, &t);
      else if (c == kStamp) ok = parse_number(s, &stamp);
      else if (c == kHasTruth) ok = parse_number(s, &has) && (has == 0 || has == 1);
      else ok = parse_number(s, &v[c]);
      if (!ok)
        return fail(where + ":" + std::to_string(column_of(index[c])) + ": column '" + names[c] + "': " +
                    (c == kHasTruth ? "expected 0 or 1" : c == kT || c == kStamp ? "not an integer" : "not a number") +
                    ": '" + std::string(s) + "'");
    }
    if (!log.rows.empty() && t < log.rows.back().t_ns)
      return fail(where + ": t_ns " + std::to_string(t) + " goes back in time (previous " +
                  std::to_string(log.rows.back().t_ns) + ")");
    WorldLogRow r;
    r.t_ns = t;
    r.robot_x = v[kRobotX];
    r.robot_y = v[kRobotY];
    r.robot_theta = v[kRobotTheta];
    r.goal_x = v[kGoalX];
    r.goal_y = v[kGoalY];
    r.goal_z = v[kGoalZ];
    r.proxy_x = v[kProxyX];
    r.proxy_y = v[kProxyY];
    r.fw_x = v[kFwX];
    r.fw_y = v[kFwY];
    r.scale = v[kScale];
    r.state_stamp_ns = stamp;
    r.truth_x = v[kTruthX];
    r.truth_y = v[kTruthY];
    r.truth_theta = v[kTruthTheta];
    r.has_truth = has == 1;
    log.rows.push_back(r);
  }
  if (in.bad()) return fail(path + ": read error");
  *out = std::move(log);
  return true;
}

TruthReport evaluate_against_truth(const std::vector<WorldLogRow>& rows, const haptics::ExactScene& scene,
                                   const haptics::ProxyModel& proxy_model, const TruthOptions& options) {
  TruthReport rep;
  rep.rows = rows.size();
  if (rows.empty()) return rep;

  // The true poses the simulation sent, one per robot state.
  std::vector<Sample> samples;
  for (const WorldLogRow& r : rows) {
    if (!r.has_truth || r.state_stamp_ns < 0) continue;
    const math::Pose2 p{r.truth_x, r.truth_y, r.truth_theta};
    if (math::is_finite(p)) samples.push_back({r.state_stamp_ns, p});
  }
  std::stable_sort(samples.begin(), samples.end(), [](const Sample& a, const Sample& b) { return a.t_ns < b.t_ns; });
  samples.erase(std::unique(samples.begin(), samples.end(),
                            [](const Sample& a, const Sample& b) { return a.t_ns == b.t_ns; }),
                samples.end());
  rep.truth_samples = samples.size();
  for (std::size_t i = 1; i < samples.size(); ++i)
    rep.truth_max_gap_s = std::max(rep.truth_max_gap_s, 1e-9 * static_cast<double>(samples[i].t_ns - samples[i - 1].t_ns));

  const std::int64_t t0 = rows.front().t_ns;
  haptics::ProxyData d = haptics::make_proxy_data(proxy_model);
  double sum_sq = 0, contact_sum_sq = 0, sum_fr = 0, sum_ft = 0, sum_pose = 0;
  for (const WorldLogRow& r : rows) {
    const double t_s = static_cast<double>(r.t_ns - t0) / 1e9;  // correctly rounded: 0.02 s is 0.02
    const bool in_window = (!options.from_s || t_s >= *options.from_s) && (!options.to_s || t_s <= *options.to_s);
    if (in_window) ++rep.window_rows;
    const math::Pose2 pred{r.robot_x, r.robot_y, r.robot_theta};
    const Eigen::Vector3d goal_W(r.goal_x, r.goal_y, r.goal_z);
    const Eigen::Vector2d fw(r.fw_x, r.fw_y);
    if (!math::is_finite(pred) || !goal_W.allFinite() || !fw.allFinite() || !std::isfinite(r.scale) ||
        !(r.scale > 0)) {
      if (in_window) ++rep.skipped_invalid;
      continue;
    }
    if (samples.empty() || r.t_ns < samples.front().t_ns) {
      if (in_window) ++rep.skipped_before_truth;
      continue;
    }
    const math::Pose2 truth = interpolate(samples, r.t_ns);
    const bool held = r.t_ns > samples.back().t_ns;
    // The interaction point is fixed in R: carry it from the predicted pose to the true one.
    const Eigen::Vector3d p_R = math::apply(math::inverse(pred), goal_W);
    const Eigen::Vector3d p_true_W = math::apply(truth, p_R);
    if (!d.initialized) haptics::proxy_reset(d, p_true_W.head<2>());
    haptics::reference_tick(proxy_model, scene, d, p_true_W, r.scale);
    if (!in_window) continue;

    const Eigen::Vector2d f_rendered_R = math::rotate(math::inverse(pred), fw);
    const Eigen::Vector2d f_truth_R = math::rotate(math::inverse(truth), Eigen::Vector2d(d.force_W.head<2>()));
    const double df = (f_rendered_R - f_truth_R).norm();
    const double pose_err = std::hypot(pred.x - truth.x, pred.y - truth.y);
    ++rep.ticks;
    if (held) ++rep.held_after_truth;
    sum_sq += df * df;
    if (df > rep.max_n || rep.ticks == 1) {
      rep.max_n = df;
      rep.max_t_s = t_s;
    }
    const double fr = f_rendered_R.norm(), ft = f_truth_R.norm();
    if (fr > options.contact_threshold_n || ft > options.contact_threshold_n) {
      ++rep.contact_ticks;
      contact_sum_sq += df * df;
      rep.contact_max_n = std::max(rep.contact_max_n, df);
      sum_fr += fr;
      sum_ft += ft;
    }
    sum_pose += pose_err;
    rep.pose_error_max_m = std::max(rep.pose_error_max_m, pose_err);
    rep.heading_error_max_rad =
        std::max(rep.heading_error_max_rad, std::abs(math::wrap_angle(pred.theta - truth.theta)));
    if (options.per_tick) {
      TruthTick k;
      k.t_ns = r.t_ns;
      k.t_s = t_s;
      k.f_rendered_R = f_rendered_R;
      k.f_truth_R = f_truth_R;
      k.df = df;
      k.proxy_rendered_W = {r.proxy_x, r.proxy_y};
      k.proxy_true_W = d.proxy_W;
      k.true_x = truth.x;
      k.true_y = truth.y;
      k.true_theta = truth.theta;
      k.pose_error_m = pose_err;
      k.held = held;
      rep.per_tick.push_back(k);
    }
  }
  if (rep.ticks > 0) {
    const double n = static_cast<double>(rep.ticks);
    rep.rms_n = std::sqrt(sum_sq / n);
    rep.pose_error_mean_m = sum_pose / n;
  }
  if (rep.contact_ticks > 0) {
    const double n = static_cast<double>(rep.contact_ticks);
    rep.contact_rms_n = std::sqrt(contact_sum_sq / n);
    rep.mean_force_rendered_n = sum_fr / n;
    rep.mean_force_truth_n = sum_ft / n;
  }
  return rep;
}

report::Truth to_report(const TruthReport& r) {
  report::Truth j;
  j.set_rows(r.rows);
  j.set_window_rows(r.window_rows);
  j.set_ticks(r.ticks);
  j.set_skipped_before_truth(r.skipped_before_truth);
  j.set_skipped_invalid(r.skipped_invalid);
  j.set_held_after_truth(r.held_after_truth);
  j.set_truth_samples(r.truth_samples);
  j.set_truth_max_gap_s(r.truth_max_gap_s);
  j.set_contact_ticks(r.contact_ticks);
  // Left out when nothing was evaluated; contact statistics over no contact
  // ticks are 0 (contact_ticks says so), which keeps no-contact runs readable.
  if (r.ticks > 0) {
    j.set_rms_n(r.rms_n);
    j.set_max_n(r.max_n);
    j.set_max_t_s(r.max_t_s);
    j.set_contact_rms_n(r.contact_rms_n);
    j.set_contact_max_n(r.contact_max_n);
    j.set_mean_force_rendered_n(r.mean_force_rendered_n);
    j.set_mean_force_truth_n(r.mean_force_truth_n);
    j.set_pose_error_mean_m(r.pose_error_mean_m);
    j.set_pose_error_max_m(r.pose_error_max_m);
    j.set_heading_error_max_rad(r.heading_error_max_rad);
  }
  return j;
}

}  // namespace hemm::robot
