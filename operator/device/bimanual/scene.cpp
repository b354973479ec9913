#include "operator/device/bimanual/scene.h"

#include "common/kinematics/arm7_mjcf.h"

namespace hemm::device::bimanual {

namespace hk = hemm::kinematics;
using hk::mjcf_numbers;

namespace {

std::string box_geom(const std::string& name, const Box& b, const std::string& rgba) {
  const Eigen::Vector3d c = 0.5 * (b.min_D + b.max_D), h = 0.5 * (b.max_D - b.min_D);
  return "<geom name=\"" + name + "\" type=\"box\" pos=\"" + mjcf_numbers({c.x(), c.y(), c.z()}) + "\" size=\"" +
         mjcf_numbers({h.x(), h.y(), h.z()}) + "\" contype=\"1\" conaffinity=\"6\" rgba=\"" + rgba + "\"/>\n";
}

std::string quat_attr(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  return mjcf_numbers({q.w(), q.x(), q.y(), q.z()});
}

std::string inertial(const hk::RigidBodyInertia& b) {
  const Eigen::Matrix3d& I = b.inertia;
  return "<inertial pos=\"" + mjcf_numbers({b.com.x(), b.com.y(), b.com.z()}) + "\" mass=\"" + mjcf_numbers({b.mass}) +
         "\" fullinertia=\"" + mjcf_numbers({I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2)}) + "\"/>\n";
}

std::string handle_body(const std::string& p, const HandleSpec& h, int contype, int conaffinity, double margin,
                        double timestep_s) {
  const Eigen::Vector3d e = h.T_J7_E.translation();
  std::string s = "<body name=\"" + p + "handle\">\n";
  // The spec's mass includes the grip lever, a body of its own here.
  hk::RigidBodyInertia body = h.inertia_J7;
  if (h.kind == HandleKind::kGripForce) body.mass -= h.grip_lever_mass;
  s += inertial(body);
  s += "<site name=\"" + p + "ft\" pos=\"0 0 0\" size=\"0.012\" rgba=\"0.2 0.6 0.2 1\"/>\n";
  s += "<site name=\"" + p + "ee\" pos=\"" + mjcf_numbers({e.x(), e.y(), e.z()}) + "\" quat=\"" +
       quat_attr(h.T_J7_E.linear()) + "\" size=\"0.01\"/>\n";
  s += "<geom name=\"" + p + "handle_geom\" type=\"capsule\" size=\"" + mjcf_numbers({h.capsule_radius}) +
       "\" fromto=\"" + mjcf_numbers({0.0, 0.0, h.capsule_radius, 0.0, 0.0, h.capsule_length}) + "\" contype=\"" +
       std::to_string(contype) + "\" conaffinity=\"" + std::to_string(conaffinity) + "\" margin=\"" +
       mjcf_numbers({margin}) + "\" gap=\"" + mjcf_numbers({margin}) + "\" mass=\"0\" rgba=\"0.3 0.3 0.35 1\"/>\n";
  if (h.kind == HandleKind::kGripForce) {
    // The lever under the forefinger: slides along -x of J7 towards the palm.
    const double m = h.grip_lever_mass;
    s += "<body name=\"" + p + "lever\" pos=\"" + mjcf_numbers({0.04, 0.0, e.z()}) + "\">\n";
    // Stiff end stops (MuJoCo's limits are soft by default).
    s += "<joint name=\"" + p + "grip\" type=\"slide\" axis=\"-1 0 0\" limited=\"true\" range=\"" +
         mjcf_numbers({0.0, h.grip_travel}) + "\" damping=\"0.05\" solreflimit=\"" + mjcf_numbers({2.0 * timestep_s, 1.0}) +
         "\" solimplimit=\"0.99 0.999 0.001\"/>\n";
    s += "<inertial pos=\"0 0 0\" mass=\"" + mjcf_numbers({m}) + "\" diaginertia=\"" +
         mjcf_numbers({1e-6, 1e-6, 1e-6}) + "\"/>\n";
    s += "<geom type=\"box\" size=\"0.005 0.01 0.02\" contype=\"0\" conaffinity=\"0\" mass=\"0\" rgba=\"0.8 0.5 0.1 1\"/>\n";
    s += "</body>\n";
  }
  s += "</body>\n";
  return s;
}

}  // namespace

std::string prefix(ArmSide s) { return s == ArmSide::kRight ? "r_" : "l_"; }

std::string bimanual_scene_mjcf(const SceneSpec& sp) {
  std::string s = "<mujoco model=\"bimanual\">\n<compiler angle=\"radian\"/>\n";
  s += "<option timestep=\"" + mjcf_numbers({sp.timestep_s}) + "\" gravity=\"" +
       mjcf_numbers({sp.rig.gravity_D.x(), sp.rig.gravity_D.y(), sp.rig.gravity_D.z()}) + "\"/>\n";
  s += "<visual><global offwidth=\"1280\" offheight=\"960\"/></visual>\n<worldbody>\n";
  s += "<light pos=\"-1 0 2.5\" dir=\"0.3 0 -1\"/>\n";
  s += box_geom("table", sp.rig.table, "0.55 0.45 0.35 1");
  s += box_geom("column", sp.rig.column, "0.4 0.4 0.45 1");
  for (ArmSide side : {ArmSide::kRight, ArmSide::kLeft}) {
    const auto a = static_cast<std::size_t>(index(side));
    const std::string p = prefix(side);
    const int contype = side == ArmSide::kRight ? 2 : 4;
    const int conaffinity = side == ArmSide::kRight ? 5 : 3;
    const Eigen::Isometry3d& T = sp.rig.T_D_A[a];
    s += "<body name=\"" + p + "base\" pos=\"" + mjcf_numbers({T.translation().x(), T.translation().y(), T.translation().z()}) +
         "\" quat=\"" + quat_attr(T.linear()) + "\">\n";
    // Link 0, fixed to the column: visual only.
    s += "<geom type=\"cylinder\" size=\"0.07 0.051\" pos=\"0 0 0.051\" contype=\"0\" conaffinity=\"0\" "
         "rgba=\"0.5 0.5 0.55 1\"/>\n";
    hk::Arm7MjcfOptions o;
    o.prefix = p;
    o.damping = sp.viscous_friction;
    o.frictionloss = sp.coulomb_friction;
    o.link_radius = sp.rig.link_radius;
    o.contype = contype;
    o.conaffinity = conaffinity;
    o.margin = sp.proximity_margin_m;
    o.solreffriction = mjcf_numbers({2.0 * sp.timestep_s, 1.0});
    o.solimpfriction = "0.9999 0.9999 0.001";
    o.flange_children = handle_body(p, sp.handles[a], contype, conaffinity, sp.proximity_margin_m, sp.timestep_s);
    s += hk::arm7_mjcf_chain(sp.arms[a], o);
    s += "</body>\n";
  }
  // The simulated hands: free bodies, placed by the plant at start.
  for (ArmSide side : {ArmSide::kRight, ArmSide::kLeft}) {
    const auto a = static_cast<std::size_t>(index(side));
    const std::string p = prefix(side);
    const HumanModel& h = sp.humans[a];
    s += "<body name=\"" + p + "hand\" pos=\"0 0 1\">\n<freejoint name=\"" + p + "hand_free\"/>\n";
    s += "<inertial pos=\"0 0 0\" mass=\"" + mjcf_numbers({h.hand_mass}) + "\" diaginertia=\"" +
         mjcf_numbers({h.hand_inertia.x(), h.hand_inertia.y(), h.hand_inertia.z()}) + "\"/>\n";
    s += "<geom type=\"ellipsoid\" size=\"0.045 0.05 0.025\" contype=\"0\" conaffinity=\"0\" mass=\"0\" "
         "rgba=\"0.9 0.7 0.6 0.6\"/>\n</body>\n";
  }
  s += "</worldbody>\n<contact>\n";
  // Links 1-2 sit at the column by design (link 1's end is 3.7 cm from its
  // face) and cannot reach the table: not contacts to report.
  for (ArmSide side : {ArmSide::kRight, ArmSide::kLeft}) {
    for (int i = 1; i <= 2; ++i)
      s += "<exclude body1=\"world\" body2=\"" + prefix(side) + "link" + std::to_string(i) + "\"/>\n";
  }
  s += "</contact>\n<sensor>\n";
  for (ArmSide side : {ArmSide::kRight, ArmSide::kLeft}) {
    const std::string p = prefix(side);
    s += "<force name=\"" + p + "ft_force\" site=\"" + p + "ft\"/>\n<torque name=\"" + p + "ft_torque\" site=\"" + p +
         "ft\"/>\n";
  }
  s += "</sensor>\n</mujoco>\n";
  return s;
}

}  // namespace hemm::device::bimanual
