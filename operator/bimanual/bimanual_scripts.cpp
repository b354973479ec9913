#include "operator/bimanual/bimanual_scripts.h"

#include <stdexcept>

namespace hemm::op {

namespace hb = hemm::device::bimanual;
using Eigen::Vector3d;

std::vector<std::string> bimanual_script_names() { return {"features", "idle"}; }

BimanualHands make_bimanual_hands(const std::string& name, const hb::SimulationConfig& sim) {
  hb::BimanualSimulation probe(sim);  // where the hands rest at the start
  const auto rest = probe.resting_targets();
  BimanualHands out;
  if (name == "idle") {
    for (int a = 0; a < hb::kArms; ++a)
      out.hands[static_cast<std::size_t>(a)] =
          std::make_shared<hb::HumanKeyScript>(std::vector<hb::HumanKey>{{0.0, rest[static_cast<std::size_t>(a)]}});
    out.duration_s = 1.0;
    return out;
  }
  if (name != "features") throw std::invalid_argument("unknown bimanual script '" + name + "'");
  for (int a = 0; a < hb::kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const double inward = a == 0 ? 1.0 : -1.0;  // towards the other hand
    const hb::HandleKind handle = sim.plant.handles[k];
    const hb::HumanTarget r = rest[k];
    std::vector<hb::HumanKey> keys;
    keys.reserve(20);
    auto key = [&](double t, const Vector3d& d, double yaw = 0.0) {
      hb::HumanTarget g = r;
      g.position_D = r.position_D + d;
      g.orientation_D = Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Vector3d::UnitZ())) * r.orientation_D;
      keys.push_back({t, g});
      return &keys.back().target;
    };
    key(0.0, Vector3d::Zero());
    key(1.5, Vector3d::Zero());
    key(2.5, Vector3d(0, 0, -0.12));  // through the plane 5 cm below
    key(3.0, Vector3d(0, 0, -0.12));
    key(4.0, Vector3d::Zero());
    key(6.0, Vector3d(0, inward * 0.35, 0));  // across the midline
    key(6.5, Vector3d(0, inward * 0.35, 0));
    key(7.5, Vector3d::Zero());
    key(8.5, Vector3d::Zero(), 0.6);
    key(9.5, Vector3d::Zero());
    hb::HumanTarget* g = key(10.5, Vector3d::Zero());
    g->finger_position = 0.02;
    g->joystick = Eigen::Vector2d(0.6, -0.4);
    g->buttons = 1;
    g->switch_on = true;
    key(11.0, Vector3d::Zero())->deadman = handle != hb::HandleKind::kJoystick;  // released
    key(11.5, Vector3d::Zero());                                               // pressed again
    key(12.5, Vector3d::Zero());
    if (handle == hb::HandleKind::kMagneticClutch) key(14.0, Vector3d::Zero())->push_force_D = Vector3d(-250, 0, 0);
    else key(14.0, Vector3d::Zero());
    out.hands[k] = std::make_shared<hb::HumanKeyScript>(std::move(keys));
  }
  out.duration_s = 14.0;
  return out;
}

}  // namespace hemm::op
