#include "robot_side/truth/probe3_truth.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

#include "common/haptics/vps/voxmap.h"

namespace hemm::robot {

namespace {
constexpr int kProbe3WireExploration = 4;  // wire::MODE_EXPLORATION (proto/wire.proto)
}  // namespace

bool open_world_log_columns(const std::string& path, const std::vector<const char*>& need, const char* what,
                            std::ifstream* in, std::map<std::string, std::size_t>* col, std::string* error) {
  in->open(path);
  std::string line;
  if (!*in || !std::getline(*in, line)) {
    *error = "cannot read " + path;
    return false;
  }
  col->clear();
  std::stringstream ss(line);
  std::string n;
  for (std::size_t i = 0; std::getline(ss, n, ','); ++i) (*col)[n] = i;
  for (const char* c : need)
    if (!col->count(c)) {
      *error = path + ": no column " + c + " (not " + what + "?)";
      return false;
    }
  return true;
}

bool read_probe3_world_log(const std::string& path, std::vector<Probe3Tick>* out, std::string* error) {
  std::ifstream in;
  std::map<std::string, std::size_t> col;
  if (!open_world_log_columns(path,
                              {"t_ns", "mode", "goal_x", "goal_y", "goal_z", "fw_x", "fw_y", "fw_z", "proxy3_x",
                               "proxy3_y", "proxy3_z", "force_gain", "probe3_contact", "model_version"},
                              "an operator world log with the point probe", &in, &col, error))
    return false;
  std::string line;
  std::vector<Probe3Tick> rows;
  std::vector<double> v;
  double t0 = NAN;
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    // A last line without its newline was cut off by a killed writer: dropped.
    if (in.eof()) break;
    v.clear();
    std::stringstream ss(line);
    std::string f;
    while (std::getline(ss, f, ',')) {
      char* end = nullptr;
      errno = 0;
      const double x = std::strtod(f.c_str(), &end);
      if (f.empty() || end != f.c_str() + f.size() || errno != 0 || !std::isfinite(x)) {
        *error = path + ":" + std::to_string(line_no) + ": field " + std::to_string(v.size() + 1) + " '" + f +
                 "' is not a finite number";
        return false;
      }
      v.push_back(x);
    }
    if (v.size() != col.size()) {
      *error = path + ":" + std::to_string(line_no) + ": " + std::to_string(v.size()) + " fields, expected " +
               std::to_string(col.size());
      return false;
    }
    auto c = [&](const char* n) { return v[col.at(n)]; };
    Probe3Tick t;
    if (std::isnan(t0)) t0 = c("t_ns");
    t.t_s = (c("t_ns") - t0) * 1e-9;
    t.goal_W = Eigen::Vector3d(c("goal_x"), c("goal_y"), c("goal_z"));
    t.force_W = Eigen::Vector3d(c("fw_x"), c("fw_y"), c("fw_z"));
    t.proxy_W = Eigen::Vector3d(c("proxy3_x"), c("proxy3_y"), c("proxy3_z"));
    t.gain = c("force_gain");
    t.contact = c("probe3_contact") != 0;
    t.exploring = static_cast<int>(c("mode")) == kProbe3WireExploration;
    t.model = c("model_version") != 0;
    rows.push_back(t);
  }
  *out = std::move(rows);
  return true;
}

Probe3Truth evaluate_probe3(const std::vector<Probe3Tick>& ticks, const vps::PointProbeParams& p, double scale,
                            const vps::Voxmap& vm) {
  Probe3Truth r;
  const std::size_t n = ticks.size();
  r.force_W.assign(n, Eigen::Vector3d::Zero());
  r.proxy_W.assign(n, Eigen::Vector3d::Zero());
  r.contact.assign(n, 0);
  vps::PointProbeData d;
  double e2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Probe3Tick& k = ticks[i];
    if (k.exploring) {
      if (!d.initialized) vps::point_probe_reset(d, k.goal_W);
      vps::point_probe_tick(p, k.model ? &vm : nullptr, d, k.goal_W, scale);
      r.force_W[i] = k.gain * d.force_W;
      r.contact[i] = d.contact ? 1 : 0;
    }
    r.proxy_W[i] = d.proxy_W;
    r.true_force_peak = std::max(r.true_force_peak, r.force_W[i].norm());
    if (!k.contact && r.contact[i] == 0) continue;
    const double e = (k.force_W - r.force_W[i]).norm();
    ++r.contact_ticks;
    e2 += e * e;
    r.force_max = std::max(r.force_max, e);
  }
  if (r.contact_ticks > 0) r.force_rms = std::sqrt(e2 / static_cast<double>(r.contact_ticks));
  return r;
}

}  // namespace hemm::robot
