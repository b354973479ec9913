// The SIMULATED bimanual interface in the servo loop against its local
// environment: no robot, no link (DeviceConfig.type "sim-bimanual").
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>

#include "operator/bimanual/bimanual_config.h"
#include "operator/bimanual/bimanual_session.h"
#include "operator/runners/runners.h"

namespace hemm::op::runner {

int run_bimanual(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  BimanualSessionOptions o;
  try {
    o.setup = bimanual_setup(cfg.device().bimanual());
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: bad config: device.bimanual: " << e.what() << "\n";
    return net::kExitUsage;
  }
  if (!a.bimanual_hands.empty()) o.setup.script = a.bimanual_hands;
  o.servo = servo_config(cfg);
  o.setup.sim.plant.control_period_s = static_cast<double>(o.servo.period_ns) * 1e-9;
  o.log_path = a.servo_log;
  o.duration_s = a.duration_s;
#ifdef HEMM_DEVICE_VIEW
  const std::unique_ptr<DeviceLiveView> live_view =
      attach_device_view(a.view_opts, bimanual_view_setup(o.setup), &o.view);
#endif
  std::atomic<bool>* stop = stop_local_run_on_signals();
  BimanualSessionSummary s;
  try {
    s = run_bimanual_session(o, stop, [](const servo::RealtimeStatus& rt) {
      for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
      spdlog::info("event=station_started device=sim-bimanual fifo={} memory_locked={}", rt.fifo, rt.memory_locked);
    });
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    spdlog::error("event=station_failed error=\"{}\"", e.what());
    return net::kExitUsage;
  }
  return finish_local_run(s, a.station_json);
}

}  // namespace hemm::op::runner
