// Scripted SIMULATED hands for the bimanual station (hemm-operator with the
// sim-bimanual device): "idle" holds both hands still; "features" shows each
// feature of the device in turn (14 s):
//   0-1.5 s   hold: the null-space force swings each elbow outwards
//   1.5-4 s   both hands press down through their planes and come back
//   4-7.5 s   the hands drive towards each other across the midline:
//             collision avoidance keeps the arms apart
//   7.5-9.5 s each hand turns 0.6 rad about the vertical against the
//             orientation spring (torque rendering) and back
//   9.5-11 s  grip handle: the forefinger closes on the virtual object;
//             joystick handle: axes, button 1 and the switch
//   11-11.5 s joystick handle: the dead-man is released (brakes), then
//             pressed again (the arm resumes)
//   12.5-14 s magnetic clutch: the hand pulls away until the clutch comes
//             off (brakes; that arm stays stopped)
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "operator/device/bimanual/human.h"
#include "operator/device/bimanual/simulation.h"

namespace hemm::op {

std::vector<std::string> bimanual_script_names();

struct BimanualHands {
  std::array<std::shared_ptr<const device::bimanual::HumanScript>, device::bimanual::kArms> hands;
  double duration_s = 0.0;  // when the script has shown everything
};

// The hands of script `name`, starting where the simulation's hands rest.
// Throws std::invalid_argument on an unknown name.
BimanualHands make_bimanual_hands(const std::string& name, const device::bimanual::SimulationConfig& sim);

}  // namespace hemm::op
