// Test helper: one Arm7Model as a MuJoCo model (through arm7_mjcf_chain), the
// independent reference for the arm's kinematics and dynamics.
#pragma once

#include <stdexcept>
#include <string>

#include <mujoco/mujoco.h>

#include "common/kinematics/arm7.h"
#include "common/kinematics/arm7_mjcf.h"
#include "common/sim/mujoco_owner.h"

namespace hemm::test {

struct MjArm7 {
  sim::MjModelPtr m;
  sim::MjDataPtr d;
  int link[kinematics::kArm7Dof] = {};

  void set(const kinematics::Arm7Vector& q, const kinematics::Arm7Vector& qd) {
    for (int i = 0; i < kinematics::kArm7Dof; ++i) {
      d->qpos[m->jnt_qposadr[i]] = q(i);
      d->qvel[m->jnt_dofadr[i]] = qd(i);
    }
    mj_forward(m.get(), d.get());
  }
};

// The arm with frame A at `base_pos` / `base_quat` (w x y z) in the world,
// gravity (0, 0, -9.81) in the world, and `extra` inside link 7.
inline MjArm7 make_mj_arm7(const kinematics::Arm7Model& model, const std::string& base_pos = "0 0 0",
                           const std::string& base_quat = "1 0 0 0", const std::string& extra = "",
                           kinematics::Arm7MjcfOptions options = {}) {
  options.flange_children += extra;
  const std::string xml = "<mujoco><compiler angle=\"radian\"/><option gravity=\"0 0 -9.81\"/><worldbody>"
                          "<body name=\"base\" pos=\"" + base_pos + "\" quat=\"" + base_quat + "\">\n" +
                          kinematics::arm7_mjcf_chain(model, options) + "</body></worldbody></mujoco>";
  MjArm7 a;
  a.m = sim::load_model_xml("model.xml", xml);
  a.d = sim::make_data(a.m.get());
  for (int i = 0; i < kinematics::kArm7Dof; ++i) {
    a.link[i] = mj_name2id(a.m.get(), mjOBJ_BODY, (options.prefix + "link" + std::to_string(i + 1)).c_str());
    if (a.link[i] < 0) throw std::runtime_error("missing link body");
  }
  return a;
}

}  // namespace hemm::test
