// The set-up hemm-operator's runners share (runners.h).
#include <csignal>
#include <iostream>

#include "operator/runners/runners.h"

namespace hemm::op::runner {

servo::ServoConfig servo_config(const config::OperatorConfig& cfg) {
  servo::ServoConfig c;
  c.period_ns = 1'000'000'000LL / cfg.servo().rate_hz();
  c.realtime = cfg.servo().realtime_priority();
  c.lock_memory = cfg.servo().realtime_priority();
  c.cpu = cfg.servo().cpu();
  c.simulated_hardware = cfg.servo().simulated_hardware() == "lock-step" ? device::HardwareMode::kLockStep
                                                                         : device::HardwareMode::kThreaded;
  return c;
}

bool setup_logging(const std::string& log_level) {
  if (net::setup_station_logging("operator", log_level)) return true;
  std::cerr << "hemm-operator: bad --log-level '" << log_level << "'\n";
  return false;
}

namespace {
std::atomic<bool> g_local_stop{false};
extern "C" void on_local_signal(int) { g_local_stop.store(true); }
}  // namespace

std::atomic<bool>* stop_local_run_on_signals() {
  std::signal(SIGINT, on_local_signal);
  std::signal(SIGTERM, on_local_signal);
  return &g_local_stop;
}

bool write_station_json(const std::string& path, const std::string& json) {
  std::string error;
  if (path.empty() || net::write_text_file(path, json, &error)) return true;
  std::cerr << "hemm-operator: --station-json: " << error << "\n";
  return false;
}

#ifdef HEMM_DEVICE_VIEW
std::unique_ptr<DeviceLiveView> attach_device_view(const view::ViewOptions& opts, DeviceSceneSetup setup,
                                                   DeviceViewTaps* taps) {
  if (!opts.enabled()) return nullptr;
  auto v = std::make_unique<DeviceLiveView>(opts, std::move(setup));
  DeviceLiveView* p = v.get();
  taps->ticks = &p->ticks();
  taps->started = [p](const servo::TimingStats& t) { p->start(&t); };
  taps->stopped = [p] { p->stop(); };
  return v;
}
#endif

}  // namespace hemm::op::runner
