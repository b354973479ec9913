#include "operator/view/device_view_record.h"

#include <algorithm>

#include "operator/device/bimanual/simulated_bimanual_device.h"

namespace hemm::op {

namespace hb = hemm::device::bimanual;

void fill_device_view(const device::DeviceSample& in, const servo::TickOutput& out,
                      const hb::SimulatedBimanualDevice* arms, std::uint64_t tick, DeviceViewRecord& r) noexcept {
  r.t_ns = in.t_ns;
  r.tick = tick;
  r.end_effectors = std::clamp(in.end_effectors, 0, device::kMaxEndEffectors);
  for (std::size_t k = 0; k < static_cast<std::size_t>(r.end_effectors); ++k) {
    r.position_H[k] = in.ee[k].position_H;
    r.orientation_H[k] = in.ee[k].orientation_H;
    r.enabled[k] = in.ee[k].enabled;
    r.force_H[k] = out.command.ee[k].force_H;
    r.torque_H[k] = out.command.ee[k].torque_H;
  }
  r.has_arms = arms != nullptr;
  if (arms != nullptr)
    for (int a = 0; a < hb::kArms; ++a) r.q[static_cast<std::size_t>(a)] = arms->reading(static_cast<hb::ArmSide>(a)).q;
}

}  // namespace hemm::op
