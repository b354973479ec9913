#include "common/kinematics/arm7_mjcf.h"

#include <cstdio>

namespace hemm::kinematics {

std::string mjcf_numbers(std::initializer_list<double> values) {
  std::string out;
  char buf[40];
  for (double v : values) {
    std::snprintf(buf, sizeof buf, "%.17g", v);
    if (!out.empty()) out += ' ';
    out += buf;
  }
  return out;
}

std::string arm7_mjcf_chain(const Arm7Model& m, const Arm7MjcfOptions& o) {
  std::string s;
  for (int i = 0; i < kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const std::string n = std::to_string(i + 1);
    const Eigen::Vector3d& p = m.offset[k];
    const Eigen::Vector3d& a = m.axis[k];
    const RigidBodyInertia& l = m.link[k];
    const Eigen::Matrix3d& I = l.inertia;
    s += "<body name=\"" + o.prefix + "link" + n + "\" pos=\"" + mjcf_numbers({p.x(), p.y(), p.z()}) + "\">\n";
    s += " <joint name=\"" + o.prefix + "j" + n + "\" type=\"hinge\" pos=\"0 0 0\" axis=\"" +
         mjcf_numbers({a.x(), a.y(), a.z()}) + "\"";
    if (o.limited) s += " limited=\"true\" range=\"" + mjcf_numbers({m.q_min(i), m.q_max(i)}) + "\"";
    s += " damping=\"" + mjcf_numbers({o.damping(i)}) + "\" frictionloss=\"" + mjcf_numbers({o.frictionloss(i)}) +
         "\" armature=\"" + mjcf_numbers({m.armature(i)}) + "\"";
    if (!o.solreffriction.empty()) s += " solreffriction=\"" + o.solreffriction + "\"";
    if (!o.solimpfriction.empty()) s += " solimpfriction=\"" + o.solimpfriction + "\"";
    s += "/>\n";
    if (l.mass > 0.0) {
      s += " <inertial pos=\"" + mjcf_numbers({l.com.x(), l.com.y(), l.com.z()}) + "\" mass=\"" +
           mjcf_numbers({l.mass}) + "\" fullinertia=\"" +
           mjcf_numbers({I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2)}) + "\"/>\n";
    }
    const double r = o.link_radius(i);
    if (r > 0.0) {
      const std::string common = "\" contype=\"" + std::to_string(o.contype) + "\" conaffinity=\"" +
                                 std::to_string(o.conaffinity) + "\" margin=\"" + mjcf_numbers({o.margin}) +
                                 "\" gap=\"" + mjcf_numbers({o.margin}) + "\" rgba=\"" + o.rgba + "\" mass=\"0\"/>\n";
      if (i + 1 < kArm7Dof) {
        const Eigen::Vector3d& e = m.offset[k + 1];
        s += " <geom name=\"" + o.prefix + "geom" + n + "\" type=\"capsule\" size=\"" + mjcf_numbers({r}) +
             "\" fromto=\"" + mjcf_numbers({0.0, 0.0, 0.0, e.x(), e.y(), e.z()}) + common;
      } else {
        s += " <geom name=\"" + o.prefix + "geom" + n + "\" type=\"capsule\" size=\"" + mjcf_numbers({r}) +
             "\" fromto=\"0 0 -0.03 0 0 -0.01" + common;
      }
    }
    if (i + 1 == kArm7Elbow) s += " <site name=\"" + o.prefix + "elbow\" pos=\"0 0 0\" size=\"0.01\"/>\n";
    if (i + 1 == kArm7Flange) {
      s += " <site name=\"" + o.prefix + "flange\" pos=\"0 0 0\" size=\"0.01\"/>\n";
      s += o.flange_children;
    }
  }
  for (int i = 0; i < kArm7Dof; ++i) s += "</body>\n";
  return s;
}

}  // namespace hemm::kinematics
