// Built-in SIMULATED operator hand scripts for the demo (hemm-operator
// --script NAME) and the tests. Positions are in the device frame H (x right,
// y up, z towards the user; forward = -z). They assume the task's default maps
// (exploration_range 4 m, navigation look-ahead 2 m: 50 and 25 world metres
// per device metre) and the robot at deploy/scenes/home.xml's robot_start
// (0, 0, heading 0).
//  - "idle": the hand holds the stylus at the centre; exploration mode.
//  - "nav-to-wall": navigation mode; after 1 s the hand pushes the stylus
//    forward to 25 mm (past the dead band: ~0.44 m/s) and keeps pushing, so
//    the robot drives +x at the end of the y = 0 wall (x = 3.0): the proxy
//    meets it, the force rises and the command falls into the dead band.
//  - "probe-cylinder": exploration mode, robot still; the probe goes to
//    (1.42, -0.8) in W and sweeps along x = 1.42 to y = -1.6 and back,
//    through the bin at (1.5, -1.2), r = 0.15, 8 cm off its centre line: the
//    proxy meets the bin's near (seen) face and slides round it.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/math/workspace_maps.h"
#include "operator/device/hand_script.h"

namespace hemm::op {

struct DemoScript {
  std::shared_ptr<const device::HandScript> hand;
  math::Mode mode = math::Mode::kExploration;
  double duration_s = 0.0;  // natural length of the script (0: none)
};

// Null hand if the name is unknown.
DemoScript make_demo_script(std::string_view name);
std::vector<std::string> demo_script_names();

}  // namespace hemm::op
