// A believed ArmsState built by hand (the task scripts' and the task human's
// tests): both grasp frames where given, at rest, unloaded; a holding
// gripper reads 0.2 m open, the others closed.
#pragma once

#include <array>
#include <cstdint>

#include "common/mapping/depth_stream.h"
#include "wire.pb.h"

namespace hemm::test {

inline wire::ArmsState believed_arms_state(const std::array<Eigen::Isometry3d, 2>& G,
                                           std::array<bool, 2> holding = {false, false}) {
  wire::ArmsState s;
  for (std::uint32_t a = 0; a < 2; ++a) {
    wire::ArmState* arm = s.add_arm();
    arm->set_index(a);
    for (int j = 0; j < 7; ++j) {
      arm->add_q(0.0);
      arm->add_qd(0.0);
      arm->add_tau(0.0);
    }
    mapping::pose3_to_wire(G[a], arm->mutable_t_a_g());
    arm->mutable_v_a();
    arm->mutable_omega_a();
    arm->mutable_force_a();
    arm->mutable_torque_a();
    wire::GripperState* g = s.add_gripper();
    g->set_index(a);
    g->set_opening_m(holding[a] ? 0.2 : 0.0);
    g->set_holding(holding[a]);
    g->set_target_opening_m(0.0);
    g->set_target_force_n(10.0);
  }
  return s;
}

}  // namespace hemm::test
