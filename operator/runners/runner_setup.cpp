// The set-up hemm-operator's runners share (runners.h).
#include <csignal>
#include <iostream>

#include "operator/client/operator_client.h"
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

OperatorClientOptions client_options(const config::OperatorConfig& cfg, const OperatorArgs& a,
                                     const std::string& robot_address, const net::Key& key) {
  OperatorClientOptions o;
  const auto& link = cfg.link();
  net::apply_link_config(link, key, &o);
  o.robot_address = robot_address;
  o.session_port =
      static_cast<uint16_t>(a.session_port >= 0 ? a.session_port : static_cast<int>(cfg.net().session_port()));
  o.stream_port =
      static_cast<uint16_t>(a.stream_port >= 0 ? a.stream_port : static_cast<int>(cfg.net().stream_port()));
  o.bind_address = cfg.net().bind_address();
  o.local_stream_port = static_cast<uint16_t>(cfg.net().local_stream_port());
  o.want_control = cfg.net().want_control();
  if (a.test_version != 0) o.protocol_version = a.test_version;
  o.connect_timeout_ms = link.connect_timeout_ms();
  o.reconnect_for_ms = link.reconnect_for_ms();
  o.connect_for_ms = link.connect_for_ms();
  return o;
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
