// The 6-DoF virtual coupling: gains designed from the sampled-data passivity
// condition and the device's limits, checked on a simulated sampled-data
// loop (continuous device, 1 kHz zero-order-hold controller, coupling, tool
// hitting a VPS wall) with a passivity observer at the device port.
#include <gtest/gtest.h>
#include <numbers>

#include <cmath>
#include <cstdio>

#include "common/haptics/vps/coupling.h"
#include "common/mesh/primitives.h"
#include "tests/common/haptics/vps/test_devices.h"

namespace hemm::vps {
namespace {

Eigen::Isometry3d at(const Eigen::Vector3d& p, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}

using test::lwr_like;
using test::omni_like;

TEST(VpsCoupling, DesignedGainsMeetThePassivityConditionAndTheForceBudget) {
  struct Case {
    const char* name;
    CouplingDeviceLimits dev;
    double mass;
    Eigen::Matrix3d inertia;
  };
  const Case cases[] = {
      {"omni, 30 g tool", omni_like(), 0.03, Eigen::Vector3d(2e-6, 3e-6, 4e-6).asDiagonal()},
      {"omni, 0.5 kg tool", omni_like(), 0.5, Eigen::Vector3d(2e-4, 3e-4, 4e-4).asDiagonal()},
      {"lwr, 0.3 kg tool", lwr_like(), 0.3, Eigen::Vector3d(2e-4, 3e-4, 5e-4).asDiagonal()},
      {"lwr, 2 kg tool", lwr_like(), 2.0, Eigen::Vector3d(0.01, 0.02, 0.02).asDiagonal()},
  };
  for (const Case& c : cases) {
    const CouplingDesign d = design_coupling(c.mass, c.inertia, c.dev);
    const CouplingParams& p = d.params;
    const double T = c.dev.dt;
    const double b = c.dev.max_stiffness * T / 2;  // no physical damping given: the rated stiffness's
    std::printf("%-18s K %7.1f N/m  B %6.3f N s/m  c %6.2f N s/m | K T/2 + B = %.3f <= %.3f | at 0.1 m/s: "
                "B v %.3f N, drag %.3f N (peak %.1f N) | K_rot %.3g B_rot %.3g\n",
                c.name, p.k_lin, p.b_lin, p.linear_damping, d.passivity_lhs, d.passivity_bound,
                p.b_lin * 0.1, (p.b_lin + p.linear_damping) * 0.1, c.dev.peak_force, p.k_rot, p.b_rot);
    // Colgate & Schenkel: b > K T / 2 + |B| (with the margin).
    EXPECT_NEAR(d.device_damping, b, 1e-12) << c.name;
    EXPECT_LE(p.k_lin * T / 2 + p.b_lin, 0.8 * b + 1e-12) << c.name;
    EXPECT_GT(p.k_lin, 0.0);
    EXPECT_GT(p.b_lin, 0.0);
    EXPECT_LE(p.k_lin, c.dev.max_stiffness) << c.name;
    // The rendered damping at 0.1 m/s stays within the force budget (10 % of
    // peak), and so does the free-motion drag (25 %).
    EXPECT_LE(p.b_lin * 0.1, 0.1 * c.dev.peak_force + 1e-12) << c.name;
    EXPECT_LE((p.b_lin + p.linear_damping) * 0.1, 0.25 * c.dev.peak_force + 1e-12) << c.name;
    // The tool's explicit springs stay discretely stable.
    EXPECT_LE(std::sqrt(p.k_lin / c.mass) * T, 0.5 + 1e-12);
    if (c.dev.renders_torque) {
      EXPECT_LE(p.k_rot * T / 2 + p.b_rot, 0.8 * c.dev.max_rot_stiffness * T / 2 + 1e-12) << c.name;
      EXPECT_LE(p.k_rot, c.dev.max_rot_stiffness);
      EXPECT_LE(p.b_rot * 1.0, 0.1 * c.dev.peak_torque + 1e-12);
    }
  }
  // The former rule (critical damping 2 sqrt(K m) on the device) breaks both
  // conditions on the Omni: that is what this design replaces.
  const CouplingDesign d = design_coupling(0.5, Eigen::Matrix3d::Identity() * 1e-3, omni_like());
  EXPECT_GT(2 * std::sqrt(d.params.k_lin * 0.5) * 0.1, omni_like().peak_force * 0.5);
}

// A SIMULATED sampled-data loop: device (mass m_d, physical damping b) and a
// hand (spring-damper to a scripted target) integrated at 20 kHz; every 1 ms
// the controller samples the device, steps the coupling with the tool's VPS
// contact against a slab, and holds the coupling's reaction force until the
// next sample. The passivity observer at the device port adds the energy the
// controller absorbed through the hold, sum -F_k . (x_{k+1} - x_k), to what
// the device's damping dissipated, integral b v^2: the sampled-data
// condition says this never goes negative (no net energy generation).
struct LoopResult {
  double min_net = 0.0;       // J, min over t of (port energy + physical dissipation)
  double port_final = 0.0;    // J
  double max_penetration = 0.0;
  double max_force = 0.0;     // N, on the device
  bool contact = false;
};

LoopResult run_loop(const CouplingParams& cpl, double device_mass, double device_damping, double hand_k,
                    double hand_b, double tap_hz) {
  // Wall: a slab whose top is at z = 0; tool: a 20 mm cube.
  static Voxmap wall;
  static PointShell tool;
  if (wall.top.empty()) {
    VoxmapParams vp;
    vp.voxel_size = 0.002;
    vp.layers_in = vp.layers_out = 6;
    mesh::TriangleMesh slab;
    mesh::append_mesh(&slab, mesh::make_box({0.05, 0.05, 0.02}, 2), at({0, 0, -0.02}));
    EXPECT_FALSE(build_voxmap(slab, vp, &wall, nullptr));
    PointShellParams pp;
    pp.voxel_size = 0.002;
    EXPECT_FALSE(build_pointshell(mesh::make_box({0.01, 0.01, 0.01}, 4), pp, Eigen::Vector3d::Zero(), &tool));
  }
  // Contact stiffness at the tool integration's limit for the 20 x 20 mm face.
  ContactParams cp;
  cp.stiffness = 0.8 * max_contact_stiffness(cpl) / 4e-4;
  const double T = cpl.dt;
  const int sub = 20;
  const double h = T / sub;
  LoopResult out;
  Eigen::Vector3d x(0.0004, -0.0003, 0.03), v = Eigen::Vector3d::Zero();  // device
  RigidBodyState tool_state;
  tool_state.position = x;
  Eigen::Vector3d F = Eigen::Vector3d::Zero();  // held device force
  PairState pair;
  init_pair_state(tool, &pair);
  double port = 0.0, dissipated = 0.0;
  // Hand target: down at 0.1 m/s to 3 mm past contact (the tool's bottom is
  // 10 mm below the device point), tapping in and out of contact at tap_hz
  // with 3 mm amplitude, then up and pressed down again at 0.3 m/s.
  auto target = [&](double t, Eigen::Vector3d* vt) {
    double z, vz;
    if (t < 0.23) {
      z = 0.03 - 0.1 * t;
      vz = -0.1;
    } else if (t < 1.23) {
      const double w = 2 * std::numbers::pi * tap_hz;
      z = 0.007 - 0.003 * std::sin(w * (t - 0.23));
      vz = -0.003 * w * std::cos(w * (t - 0.23));
    } else if (t < 1.4) {
      z = 0.007 + 0.3 * (t - 1.23);
      vz = 0.3;
    } else {
      z = std::max(0.004, 0.058 - 0.3 * (t - 1.4));
      vz = z > 0.004 ? -0.3 : 0.0;
    }
    *vt = Eigen::Vector3d(0.006 * std::cos(3 * t), 0, vz);
    return Eigen::Vector3d(0.0004 + 0.002 * std::sin(3 * t), -0.0003, z);
  };
  const int ticks = 2200;
  for (int k = 0; k < ticks; ++k) {
    // Controller: sample, contact, coupling, hold.
    PairResult r;
    evaluate_pair(wall, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), tool, tool_state.pose(), cp, &pair,
                  &r);
    out.contact = out.contact || r.contacts > 0;
    out.max_penetration = std::max(out.max_penetration, r.max_penetration);
    Wrench dw;
    step_virtual_coupling(cpl, at(x), v, Eigen::Vector3d::Zero(), r.on_shell, &tool_state, &dw);
    F = dw.force;
    out.max_force = std::max(out.max_force, F.norm());
    // Plant over one period under the held force.
    const Eigen::Vector3d x0 = x;
    for (int i = 0; i < sub; ++i) {
      const double t = k * T + i * h;
      Eigen::Vector3d vt;
      const Eigen::Vector3d xt = target(t, &vt);
      const Eigen::Vector3d f_hand = hand_k * (xt - x) + hand_b * (vt - v);
      // Semi-implicit in the damping (exact dissipation bookkeeping below).
      const Eigen::Vector3d v_new = (device_mass * v + h * (f_hand + F)) / (device_mass + h * device_damping);
      const Eigen::Vector3d v_mid = 0.5 * (v + v_new);
      dissipated += device_damping * v_new.dot(v_mid) * h;
      x += h * v_mid;
      v = v_new;
    }
    port += -F.dot(x - x0);
    out.min_net = std::min(out.min_net, port + dissipated);
  }
  out.port_final = port;
  return out;
}

TEST(VpsCoupling, SampledDataLoopGeneratesNoEnergyWithDesignedGains) {
  struct Case {
    const char* name;
    CouplingDeviceLimits dev;
    double tool_mass, device_mass, hand_k, hand_b;
  };
  const Case cases[] = {
      {"omni", omni_like(), 0.03, 0.05, 300.0, 2.0},
      {"lwr", lwr_like(), 0.3, 1.5, 3000.0, 20.0},
  };
  for (const Case& c : cases) {
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity() * c.tool_mass * 1e-4;
    const CouplingDesign d = design_coupling(c.tool_mass, I, c.dev);
    const double b = d.device_damping;
    for (double tap : {2.0, 8.0, 20.0}) {
      const LoopResult r = run_loop(d.params, c.device_mass, b, c.hand_k, c.hand_b, tap);
      std::printf("%s designed (K %.0f, B %.3f), tapping %4.1f Hz: min(port + b v^2) %+.3e J, port %+.3e J, "
                  "max penetration %.2f mm, max force %.2f N\n",
                  c.name, d.params.k_lin, d.params.b_lin, tap, r.min_net, r.port_final, 1e3 * r.max_penetration,
                  r.max_force);
      EXPECT_TRUE(r.contact) << c.name;
      EXPECT_GE(r.min_net, -1e-7) << c.name << " tapping " << tap << " Hz";
    }
    // Without the tool's drag the condition alone must carry it.
    CouplingParams no_drag = d.params;
    no_drag.linear_damping = 0.0;
    for (double tap : {2.0, 8.0, 20.0}) {
      const LoopResult r = run_loop(no_drag, c.device_mass, b, c.hand_k, c.hand_b, tap);
      std::printf("%s designed, no drag, tapping %4.1f Hz: min(port + b v^2) %+.3e J, port %+.3e J\n", c.name, tap,
                  r.min_net, r.port_final);
      EXPECT_GE(r.min_net, -1e-7) << c.name << " no drag, tapping " << tap << " Hz";
    }
    // The same loop with a coupling that breaks the condition (K T/2 = 3 b)
    // and no damping to hide it: the observer sees the energy the hold
    // generates. This is what the test above would catch.
    CouplingParams bad = d.params;
    bad.k_lin = 3 * (2 * b) / bad.dt;
    bad.b_lin = 0.0;
    bad.linear_damping = 0.0;
    const LoopResult r = run_loop(bad, c.device_mass, b, c.hand_k, c.hand_b, 20.0);
    std::printf("%s violating (K %.0f, B %.3f): min(port + b v^2) %+.3e J\n", c.name, bad.k_lin, bad.b_lin,
                r.min_net);
    EXPECT_LT(r.min_net, -1e-5) << c.name;
  }
}

TEST(VpsCoupling, FollowsTheDeviceAndOnlyLosesEnergy) {
  // Free space: a step of the device pose (5 cm, 0.5 rad). The tool converges
  // to it; with the device still, coupling + kinetic energy never grows.
  Eigen::Matrix3d I = Eigen::Vector3d(2e-4, 3e-4, 4e-4).asDiagonal();
  const CouplingParams p = design_coupling(0.4, I, lwr_like()).params;
  RigidBodyState st;
  const Eigen::Isometry3d dev =
      at({0.05, -0.02, 0.03}, Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 2).normalized()).toRotationMatrix());
  double prev = coupling_potential(p, st, dev) + kinetic_energy(p, st);
  Wrench dw, cw;
  for (int i = 0; i < 3000; ++i) {
    step_virtual_coupling(p, dev, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Wrench{}, &st, &dw, &cw);
    const double e = coupling_potential(p, st, dev) + kinetic_energy(p, st);
    ASSERT_LE(e, prev * (1 + 1e-9) + 1e-15) << "tick " << i;
    prev = e;
    // The device feels the reaction of what pulls the tool.
    EXPECT_NEAR((dw.force + cw.force).norm(), 0.0, 1e-12);
  }
  EXPECT_NEAR((st.position - dev.translation()).norm(), 0.0, 1e-6);
  EXPECT_NEAR(Eigen::AngleAxisd(st.orientation.toRotationMatrix() * dev.linear().transpose()).angle(), 0.0, 1e-4);
  // A constant contact force is balanced by the coupling spring: offset F / k.
  RigidBodyState s2;
  Wrench push;
  push.force = Eigen::Vector3d(0, 0, 3.0);
  for (int i = 0; i < 3000; ++i)
    step_virtual_coupling(p, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), push,
                          &s2, &dw);
  EXPECT_NEAR(s2.position.z(), 3.0 / p.k_lin, 1e-6);
  EXPECT_NEAR(dw.force.z(), 3.0, 1e-4);  // the user feels the contact through the coupling
}

}  // namespace
}  // namespace hemm::vps
