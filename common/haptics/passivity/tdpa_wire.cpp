#include "common/haptics/passivity/tdpa_wire.h"

#include <cmath>

#include "config_operator.pb.h"
#include "config_robot.pb.h"
#include "wire.pb.h"

namespace hemm::haptics::tdpa {

void fill(wire::PassivityPort* out, std::uint32_t index, const ArmSide& s, PcMode mode) {
  out->Clear();
  out->set_index(index);
  for (int i = 0; i < 6; ++i) {
    out->add_energy_in_j(s.in_J[i]);
    out->add_energy_out_j(s.out_J[i]);
  }
  out->set_dissipated_j(s.dissipated_J.sum());
  out->set_pc_active_ticks(s.pc_active_ticks);
  out->set_pc_on(mode == PcMode::kControl);
}

bool read_energy_in(const wire::PassivityPort& in, Vec6* energy_in_J, std::string* error) {
  if (in.energy_in_j_size() != 6) {
    *error = "passivity port of arm " + std::to_string(in.index()) + ": " + std::to_string(in.energy_in_j_size()) +
             " input energies, not 6";
    return false;
  }
  Vec6 e;
  for (int i = 0; i < 6; ++i) {
    e[i] = in.energy_in_j(i);
    if (!std::isfinite(e[i]) || e[i] < 0.0) {
      *error = "passivity port of arm " + std::to_string(in.index()) + ": input energy " + std::to_string(i) +
               " is not a finite value >= 0";
      return false;
    }
  }
  *energy_in_J = e;
  return true;
}

ModeThresholds thresholds_from(const config::OperatorPassivityConfig& c) {
  ModeThresholds t;
  t.max_direct_rtt_s = 1e-3 * c.max_direct_rtt_ms();
  t.max_direct_loss = c.max_direct_loss();
  t.hysteresis = c.hysteresis();
  return t;
}

PcMode pc_mode_from(const config::OperatorPassivityConfig& c) {
  return c.controller() ? PcMode::kControl : PcMode::kObserveOnly;
}
PcMode pc_mode_from(const config::RobotPassivityConfig& c) {
  return c.controller() ? PcMode::kControl : PcMode::kObserveOnly;
}

}  // namespace hemm::haptics::tdpa
