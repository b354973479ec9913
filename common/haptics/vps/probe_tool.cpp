#include "common/haptics/vps/probe_tool.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace hemm::vps {

std::string validate(const ProbeToolGeometry& g) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0; };
  if (!pos(g.tip_radius) || !pos(g.rod_radius) || !pos(g.rod_length) || !pos(g.tip_mass) || !pos(g.rod_mass) ||
      !pos(g.spacing))
    return "radii, length, masses and spacing must be finite and positive";
  if (g.rod_radius >= g.tip_radius) return "the rod must be thinner than the rounded tip";
  if (g.rod_length <= g.tip_radius || g.rod_length > 2.0) return "rod_length must be in (tip_radius, 2] m";
  if (g.spacing > 0.5 * g.rod_radius) return "spacing must be at most half the rod radius";
  if (g.levels < 1 || g.levels > kMaxShellLevels) return "levels must be in [1, 6]";
  return {};
}

std::optional<VpsError> make_probe_tool(const ProbeToolGeometry& g, ProbeTool* out) {
  if (std::string e = validate(g); !e.empty()) return VpsError{"probe tool: " + e};
  const double a = g.tip_radius, r = g.rod_radius, L = g.rod_length, h = g.spacing;
  const double pi = std::numbers::pi;
  const double z_j = std::sqrt(a * a - r * r);  // where the rod's surface meets the tip sphere
  std::vector<Eigen::Vector3d> pts, nrm;
  std::vector<double> w;
  // Tip sphere below the junction: equal-area (Fibonacci) points on the zone
  // z in [-a, z_j], whose area is 2 pi a (z_j + a).
  const double zone = 2 * pi * a * (z_j + a);
  const int ns = std::max(8, static_cast<int>(std::lround(zone / (h * h))));
  const double golden = pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < ns; ++i) {
    const double z = -a + (z_j + a) * (i + 0.5) / ns;
    const double rho = std::sqrt(std::max(0.0, a * a - z * z));
    const Eigen::Vector3d p(rho * std::cos(golden * i), rho * std::sin(golden * i), z);
    pts.push_back(p);
    nrm.push_back(-p.normalized());
    w.push_back(zone / ns);
  }
  // Rod side: rings from the junction to the end, alternate rings turned by half a step.
  const int nz = std::max(1, static_cast<int>(std::ceil((L - z_j) / h)));
  const double dz = (L - z_j) / nz;
  const int nt = std::max(6, static_cast<int>(std::lround(2 * pi * r / h)));
  for (int k = 0; k < nz; ++k) {
    const double z = z_j + (k + 0.5) * dz;
    for (int j = 0; j < nt; ++j) {
      const double t = 2 * pi * (j + 0.5 * (k % 2)) / nt;
      pts.emplace_back(r * std::cos(t), r * std::sin(t), z);
      nrm.emplace_back(-std::cos(t), -std::sin(t), 0.0);
      w.push_back(2 * pi * r * dz / nt);
    }
  }
  // End disc.
  const int nr = std::max(1, static_cast<int>(std::ceil(r / h)));
  const double dr = r / nr;
  for (int k = 0; k < nr; ++k) {
    const double rho = (k + 0.5) * dr;
    const int n = std::max(1, static_cast<int>(std::lround(2 * pi * rho / h)));
    for (int j = 0; j < n; ++j) {
      const double t = 2 * pi * (j + 0.5) / n;
      pts.emplace_back(rho * std::cos(t), rho * std::sin(t), L);
      nrm.emplace_back(0.0, 0.0, -1.0);
      w.push_back(2 * pi * rho * dr / n);
    }
  }
  // Mass: a solid sphere at the tip, a solid cylinder from the junction to the end.
  const double mt = g.tip_mass, mr = g.rod_mass, l = L - z_j, zc = 0.5 * (z_j + L);
  const double z_com = mr * zc / (mt + mr);
  const double i_perp = 0.4 * mt * a * a + mt * z_com * z_com + mr * (3 * r * r + l * l) / 12.0 +
                        mr * (zc - z_com) * (zc - z_com);
  const double i_axial = 0.4 * mt * a * a + 0.5 * mr * r * r;
  out->mass = mt + mr;
  out->inertia_com = Eigen::Vector3d(i_perp, i_perp, i_axial).asDiagonal();
  return build_pointshell_from_points(pts, nrm, w, h, g.levels, 8, Eigen::Vector3d(0, 0, z_com), &out->shell);
}

void init_tool_state(const ProbeTool& tool, ToolState* s) {
  init_pair_state(tool.shell, &s->pair);
  s->body = RigidBodyState{};
  s->voxmap = nullptr;
  s->started = false;
  s->contact = PairResult{};
  s->device = Wrench{};
  s->voxmap_changes = 0;
  s->ticks = 0;
}

Eigen::Isometry3d tool_pose_W(const ProbeTool& tool, const ToolState& s) {
  return s.body.pose() * Eigen::Translation3d(-tool.shell.reference_point);
}

void probe_tool_tick(const ToolParams& p, const ProbeTool& tool, const Voxmap* vm, const Eigen::Isometry3d& T_W_goal,
                     ToolState* s) noexcept {
  ++s->ticks;
  if (!T_W_goal.matrix().allFinite()) {  // a bad reading: the tool stays, nothing displayed
    s->device = Wrench{};
    s->contact = PairResult{};
    return;
  }
  const Eigen::Vector3d& ref = tool.shell.reference_point;
  // The coupling pulls the tool's centre of mass towards where the goal puts it.
  Eigen::Isometry3d T_W_D = T_W_goal;
  T_W_D.translation() = T_W_goal * ref;
  Eigen::Vector3d v_D = Eigen::Vector3d::Zero(), w_D = Eigen::Vector3d::Zero();
  if (s->started) {
    const double inv_dt = 1.0 / p.coupling.dt;
    v_D = (T_W_D.translation() - s->goal_prev * ref) * inv_dt;
    const Eigen::AngleAxisd turn(T_W_goal.linear() * s->goal_prev.linear().transpose());
    w_D = turn.axis() * (turn.angle() * inv_dt);
  }
  s->goal_prev = T_W_goal;
  if (vm == nullptr || !s->started) {
    // No model yet (or the first tick): the tool is where the hand holds it, at rest.
    s->body = RigidBodyState{};
    s->body.position = T_W_D.translation();
    s->body.orientation = Eigen::Quaterniond(T_W_D.linear()).normalized();
    s->started = true;
    s->device = Wrench{};
    s->contact = PairResult{};
    if (vm == nullptr) {
      s->voxmap = nullptr;  // the pair state is stale when a voxmap comes (back)
      return;
    }
  }
  if (vm != s->voxmap) {  // a new snapshot: what the pair remembers belongs to the old voxmap
    reset_pair_state(&s->pair);
    s->voxmap = vm;
    ++s->voxmap_changes;
  }
  evaluate_pair_budgeted(*vm, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), tool.shell,
                         tool_pose_W(tool, *s), p.contact, p.budget, &s->pair, &s->contact);
  step_virtual_coupling(p.coupling, T_W_D, v_D, w_D, s->contact.on_shell, &s->body, &s->device);
}

void replay_tool_path(const ToolParams& p, const ProbeTool& tool, const Voxmap& vm,
                      const std::vector<Eigen::Isometry3d>& goals, const std::vector<double>& gain,
                      const std::vector<std::uint8_t>& has_model, ToolReplay* out) {
  ToolState s;
  init_tool_state(tool, &s);
  out->wrench.assign(goals.size(), Wrench{});
  out->tool_W.assign(goals.size(), Eigen::Vector3d::Zero());
  out->contacts.assign(goals.size(), 0);
  for (std::size_t i = 0; i < goals.size(); ++i) {
    const bool model = i >= has_model.size() || has_model[i] != 0;
    probe_tool_tick(p, tool, model ? &vm : nullptr, goals[i], &s);
    const double g = i < gain.size() ? gain[i] : 1.0;
    out->wrench[i].force = g * s.device.force;
    out->wrench[i].torque = g * s.device.torque;
    out->tool_W[i] = tool_pose_W(tool, s).translation();
    out->contacts[i] = s.contact.contacts;
  }
}

}  // namespace hemm::vps
