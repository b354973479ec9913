#include "operator/telemanip/gripper_tool.h"

#include <algorithm>
#include <cmath>

#include "common/haptics/vps/pointshell.h"
#include "common/mesh/primitives.h"

namespace hemm::op::telemanip {

namespace {

// A solid box's inertia about its centre.
Eigen::Matrix3d gripper_box_inertia(double m, const Eigen::Vector3d& h) {
  const Eigen::Vector3d s = 4.0 * h.cwiseProduct(h);  // full extents squared
  return (m / 12.0 * Eigen::Vector3d(s.y() + s.z(), s.x() + s.z(), s.x() + s.y())).asDiagonal();
}

// The pads' gap may not close to nothing: two coincident pad faces would put
// points of one finger inside the other.
constexpr double kGripperMinGap = 0.002;

}  // namespace

std::string validate(const GripperGeometry& g) {
  const bool sizes = g.palm_half.allFinite() && g.finger_half.allFinite() && (g.palm_half.array() > 0.0).all() &&
                     (g.finger_half.array() > 0.0).all() && g.palm_half.maxCoeff() < 0.5 && g.finger_half.maxCoeff() < 0.5;
  if (!sizes) return "gripper: box half extents must be in (0, 0.5) m";
  if (!(std::isfinite(g.palm_centre_z) && std::isfinite(g.finger_centre_z) && std::abs(g.palm_centre_z) < 1.0 &&
        std::abs(g.finger_centre_z) < 1.0))
    return "gripper: centres must be finite, within 1 m of G";
  if (!(g.palm_mass > 0.0 && g.finger_mass > 0.0 && g.palm_mass < 20.0 && g.finger_mass < 20.0))
    return "gripper: masses must be in (0, 20) kg";
  if (!(g.max_opening_m > 0.0 && g.max_opening_m < 1.0)) return "gripper: max opening must be in (0, 1) m";
  if (!(g.opening_step_m >= 0.005 && g.opening_step_m <= g.max_opening_m))
    return "gripper: opening step must be in [5 mm, max opening]";
  if (!(g.spacing >= 5e-4 && g.spacing <= 0.02) || g.levels < 1 || g.levels > 6)
    return "gripper: spacing must be in [0.5, 20] mm, levels in [1, 6]";
  return {};
}

mesh::TriangleMesh gripper_mesh(const GripperGeometry& g, double opening_m, bool fingers) {
  const double gap = std::max(opening_m, kGripperMinGap);
  mesh::TriangleMesh m;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.0, 0.0, g.palm_centre_z);
  mesh::append_mesh(&m, mesh::make_box(g.palm_half, 8), T);
  if (!fingers) return m;
  for (double side : {1.0, -1.0}) {  // finger a (+y) and b (-y), pads facing G
    T.translation() = Eigen::Vector3d(0.0, side * (0.5 * gap + g.finger_half.y()), g.finger_centre_z);
    mesh::append_mesh(&m, mesh::make_box(g.finger_half, 4), T);
  }
  return m;
}

std::string make_gripper_tool(const GripperGeometry& g, double opening_m, vps::ProbeTool* out, bool fingers) {
  if (std::string e = validate(g); !e.empty()) return e;
  if (!(opening_m >= 0.0 && opening_m <= g.max_opening_m)) return "gripper: opening outside [0, max opening]";
  const double gap = std::max(opening_m, kGripperMinGap);
  // Mass properties of the three solid boxes (parallel axes).
  const Eigen::Vector3d c_palm(0.0, 0.0, g.palm_centre_z);
  const Eigen::Vector3d c_a(0.0, 0.5 * gap + g.finger_half.y(), g.finger_centre_z);
  const Eigen::Vector3d c_b(0.0, -c_a.y(), g.finger_centre_z);
  const double mass = g.palm_mass + 2.0 * g.finger_mass;
  const Eigen::Vector3d com = (g.palm_mass * c_palm + g.finger_mass * (c_a + c_b)) / mass;
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  const auto add = [&](double m, const Eigen::Vector3d& h, const Eigen::Vector3d& c) {
    const Eigen::Vector3d r = c - com;
    I += gripper_box_inertia(m, h) + m * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
  };
  add(g.palm_mass, g.palm_half, c_palm);
  add(g.finger_mass, g.finger_half, c_a);
  add(g.finger_mass, g.finger_half, c_b);
  vps::PointShellParams sp;
  sp.voxel_size = g.spacing;
  sp.levels = g.levels;
  vps::ProbeTool t;
  if (auto e = vps::build_pointshell(gripper_mesh(g, opening_m, fingers), sp, com, &t.shell)) return "gripper: " + e->message;
  t.mass = mass;
  t.inertia_com = I;
  *out = std::move(t);
  return {};
}

int GripperToolSet::nearest(double opening) const noexcept {
  if (opening_m.empty()) return -1;
  if (!std::isfinite(opening)) return static_cast<int>(opening_m.size()) - 1;
  int best = 0;
  for (int i = 1; i < static_cast<int>(opening_m.size()); ++i)
    if (std::abs(opening_m[i] - opening) < std::abs(opening_m[best] - opening)) best = i;
  return best;
}

std::string make_gripper_tool_set(const GripperGeometry& g, GripperToolSet* out) {
  if (std::string e = validate(g); !e.empty()) return e;
  GripperToolSet s;
  for (double o = 0.0; o < g.max_opening_m - 1e-9; o += g.opening_step_m) s.opening_m.push_back(o);
  s.opening_m.push_back(g.max_opening_m);
  s.tools.resize(s.opening_m.size());
  for (std::size_t i = 0; i < s.opening_m.size(); ++i)
    if (std::string e = make_gripper_tool(g, s.opening_m[i], &s.tools[i]); !e.empty()) return e;
  if (std::string e = make_gripper_tool(g, 0.5 * g.max_opening_m, &s.palm, false); !e.empty()) return e;
  *out = std::move(s);
  return {};
}

}  // namespace hemm::op::telemanip
