// The VPS scene of the config's `vps` block with the device in the servo
// loop: no robot, no link.
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>
#include <stdexcept>

#include "operator/runners/runners.h"
#include "operator/vps/vps_config.h"
#include "operator/vps/vps_session.h"
#ifdef HEMM_DEVICE_VIEW
#include "operator/device/bimanual/simulated_bimanual_device.h"
#endif

namespace hemm::op::runner {

int run_vps(const config::OperatorConfig& cfg, const OperatorArgs& a) {
  VpsSessionOptions o;
  std::unique_ptr<device::HapticDevice> dev;
  std::shared_ptr<VpsLocalModel> model;
  try {
    const VpsSetup setup = vps_setup(cfg, a.config_path);
    dev = make_vps_device(cfg, a.replay_file);
    o.task = setup.task;
    VpsLoadReport report;
    model = load_vps_model(setup.model, &report);
    for (const auto& l : report.lines) spdlog::info("event=vps_model {}", l);
    for (const auto& w : report.warnings) spdlog::warn("event=vps_model warning=\"{}\"", w);
  } catch (const std::invalid_argument& e) {
    std::cerr << "hemm-operator: bad config: " << e.what() << "\n";
    return net::kExitUsage;
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    return net::kExitUsage;
  }
  o.servo = servo_config(cfg);
  o.log_path = a.servo_log;
  o.duration_s = a.duration_s;
#ifdef HEMM_DEVICE_VIEW
  const auto* arms = dynamic_cast<const device::bimanual::SimulatedBimanualDevice*>(dev.get());
  const std::unique_ptr<DeviceLiveView> live_view = attach_device_view(
      a.view_opts,
      vps_view_setup(*model, o.task, dev->limits().end_effectors,
                     arms != nullptr ? &arms->simulation().config() : nullptr, std::string(dev->name())),
      &o.view);
#endif
  // Scripted hands end: by default the run covers their path and a hold.
  if (o.duration_s <= 0) o.duration_s = vps_default_duration_s(cfg);
  std::atomic<bool>* stop = stop_local_run_on_signals();
  VpsSessionSummary s;
  try {
    s = run_vps_session(*dev, model, o, stop, [&](const servo::RealtimeStatus& rt) {
      for (const auto& w : rt.warnings) spdlog::warn("event=servo_realtime warning=\"{}\"", w);
      spdlog::info("event=station_started device={} vps_objects={} fifo={}", dev->name(), model->object_count,
                   rt.fifo);
    });
  } catch (const std::exception& e) {
    std::cerr << "hemm-operator: " << e.what() << "\n";
    return net::kExitUsage;
  }
  return finish_local_run(s, a.station_json);
}

}  // namespace hemm::op::runner
