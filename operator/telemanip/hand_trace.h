// The operator's side of a telemanipulation run, hand by hand (hemm-operator
// --hand-trace FILE.csv): what each hand commanded, what the operator
// believed of the remote arm, and what the hand was given to feel - the
// whole wrench to the device and the held object's share of it - beside
// the wrist force the robot measured (as believed, late by the link). With
// hemm-robot --truth-trace (SIMULATION ONLY) it tells where a run's forces
// came from on both sides; deploy/plots/plot_telemanip.py draws them.
//
// The servo tick fills one HandTraceSample (a value, no allocation) and
// publishes it into a mailbox; the network thread samples the newest every
// period and keeps the rows; they are written at exit. Forces are in A at
// G, per hand: the device's force divided by the translation scale and
// turned out of D (F_A = R_A_D F_D / s), so they compare with the wrist's.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace hemm::op::telemanip {

struct HandTraceArm {
  bool pressed = false;   // the dead-man that gates this arm
  bool clutched = false;  // indexing: the mapping re-anchors
  bool holding = false;   // the remote gripper says it holds (believed)
  Eigen::Vector3d commanded_A = Eigen::Vector3d::Zero();  // the commanded G
  Eigen::Vector3d remote_A = Eigen::Vector3d::Zero();     // the believed remote G
  Eigen::Vector3d felt_A = Eigen::Vector3d::Zero();       // the hand's whole force, as in A
  Eigen::Vector3d held_A = Eigen::Vector3d::Zero();       // its held-object share (weight, two-hand coupling)
  Eigen::Vector3d remote_force_A = Eigen::Vector3d::Zero();  // the wrist's measured environment force (believed)
  double commanded_opening_m = 0.0;
  double remote_opening_m = 0.0;
};

struct HandTraceSample {
  std::int64_t t_ns = 0;         // the servo tick's steady clock
  std::int64_t remote_ns = 0;    // the believed state's stamp (the robot's clock; 0: none yet)
  bool direct = false;           // the direct force-feedback mode
  double squeeze_n = 0.0;        // the two-hand coupling's squeeze (positive: pressed together)
  std::array<HandTraceArm, 2> arm{};
};

// The rows as CSV, a header first: t_s (from the first row), clock_s (the
// steady clock; on one host the robot's truth trace's clock_s), remote_clock_s,
// mode, squeeze_N, then per arm (right_, left_) pressed, clutched, holding,
// cmd_{x,y,z}, remote_{x,y,z}, felt_{x,y,z}, held_{x,y,z},
// remote_force_{x,y,z}, cmd_opening_m, remote_opening_m.
std::string hand_trace_csv(const std::vector<HandTraceSample>& rows);

}  // namespace hemm::op::telemanip
