// A two-arm ArmsState on the wire for the operator side's tests (the link,
// the replay): both arms at rest with their grasp frames at x_right / 0.6,
// y -/+0.25, z 0.9, the wrist reading 2 N down, the grippers 5 cm open.
#pragma once

#include <cstdint>

#include "common/mapping/depth_stream.h"
#include "wire.pb.h"

namespace hemm::test {

inline wire::ArmsState telemanip_test_state(double x_right) {
  wire::ArmsState s;
  s.set_stamp_ns(5);
  s.set_frame_epoch(3);
  for (std::uint32_t k = 0; k < 2; ++k) {
    wire::ArmState* a = s.add_arm();
    a->set_index(k);
    for (int j = 0; j < 7; ++j) {
      a->add_q(0.0);
      a->add_qd(0.0);
      a->add_tau(0.0);
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(k == 0 ? x_right : 0.6, k == 0 ? -0.25 : 0.25, 0.9);
    mapping::pose3_to_wire(T, a->mutable_t_a_g());
    a->mutable_v_a();
    a->mutable_omega_a();
    a->mutable_force_a()->set_z(-2.0);
    a->mutable_torque_a();
    wire::GripperState* g = s.add_gripper();
    g->set_index(k);
    g->set_opening_m(0.05);
  }
  return s;
}

}  // namespace hemm::test
