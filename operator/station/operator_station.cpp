#include "operator/station/operator_station.h"

#include <cinttypes>
#include <cstdio>
#include <future>
#include <sstream>
#include <stdexcept>

#include "operator/device/replay_device.h"
#include "operator/device/simulated_omni.h"
#include "operator/device/trajectory_csv.h"
#include "operator/station/demo_scripts.h"

namespace hemm::op {
namespace {
std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

std::string to_string(const OperatorStationSummary& s) {
  std::ostringstream o;
  o << "servo: " << servo::to_string(s.timing) << "\n"
    << "model: scans_in=" << s.model.scans_in << " scans_rejected=" << s.model.scans_rejected
    << " scans_dropped=" << s.model.scans_dropped << " states_in=" << s.model.states_in
    << " states_rejected=" << s.model.states_rejected << " snapshots=" << s.model.snapshots << "\n"
    << "commands: sent=" << s.commands.commands_sent << " failures=" << s.commands.send_failures
    << " mode_changes=" << s.commands.mode_changes_sent << " stale=" << s.commands.stale
    << " mode_switches=" << s.mode_switches << "\n"
    << "logs: servo written=" << s.servo_log_written << " dropped=" << s.servo_log_dropped
    << " world written=" << s.world_log_written << " dropped=" << s.world_log_dropped << "\n";
  return o.str();
}

bool write_map_csv(const mapping::LocalMap& map, const std::string& path, std::string* error) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    if (error) *error = "cannot open " + path + " for writing";
    return false;
  }
  std::fprintf(f, "ax,ay,bx,by,nx,ny,stamp_ns,kind\n");
  for (const auto& s : map.segments)
    std::fprintf(f, "%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%" PRId64 ",%d\n", s.a.x(), s.a.y(), s.b.x(), s.b.y(),
                 s.normal.x(), s.normal.y(), s.stamp_ns, static_cast<int>(s.kind));
  const bool ok = std::fclose(f) == 0;
  if (!ok && error) *error = "write failed: " + path;
  return ok;
}

OperatorStation::OperatorStation(asio::io_context& io, OperatorClient& client, const OperatorStationOptions& o)
    : io_(io), client_(client), o_(o), link_timer_(io) {
  OperatorTaskParams tp = o.task;
  if (o.device == "sim-omni" && o.hand) {
    device_ = std::make_unique<device::SimulatedOmni>(device::SimulatedOmniModel{}, o.hand);
  } else if (o.device == "sim-omni") {
    DemoScript d = make_demo_script(o.script);
    if (!d.hand) throw std::invalid_argument("unknown --script '" + o.script + "'");
    tp.initial_mode = d.mode;
    device_ = std::make_unique<device::SimulatedOmni>(device::SimulatedOmniModel{}, d.hand);
  } else if (o.device == "replay") {
    device::Trajectory traj;
    if (auto e = device::load_trajectory_csv(o.replay_file, device::phantom_omni_limits(), &traj))
      throw std::runtime_error("replay file: " + e->to_string());
    device_ = std::make_unique<device::ReplayDevice>(std::move(traj), device::phantom_omni_limits());
  } else {
    throw std::invalid_argument("unknown device type '" + o.device + "' (sim-omni or replay)");
  }
  if (!(o.stats_period_s > 0)) throw std::invalid_argument("stats_period_s must be positive");
  model_ = std::make_unique<ModelThread>(channel_, o.model);
  if (!o.log_path.empty()) {
    servo_log_ = std::make_unique<servo::ServoLogger>(16384, servo::servo_log_header(), &servo::format_servo_log_record);
    world_log_ = std::make_unique<StationLogger>(16384, station_log_header(), &format_station_log_record);
  }
  task_ = std::make_unique<OperatorServoTask>(tp, world_log_.get());
  loop_ = std::make_unique<servo::ServoLoop>(*device_, *task_, channel_, o.servo, servo_log_.get());
  sender_ = std::make_unique<CommandSender>(
      io_, task_->setpoints(), [this](const wire::StreamMessage& m) { return client_.streams().send(m); },
      [this](const wire::SessionFrame& f) { client_.send_session_frame(f); }, model_.get(),
      CommandSenderParams{o.command_rate_hz, 100'000'000}, [] { return steady_now_ns(); });
}

OperatorStation::~OperatorStation() { stop(); }

servo::RealtimeStatus OperatorStation::start() {
  if (started_) throw std::logic_error("OperatorStation already started");
  started_ = true;
  client_.streams().on(wire::StreamMessage::kRobotState,
                       [this](const net::DatagramHeader&, int64_t, const wire::StreamMessage& m) {
                         model_->submit_state(m.robot_state());
                       });
  client_.streams().on(wire::StreamMessage::kRangeScan,
                       [this](const net::DatagramHeader&, int64_t, const wire::StreamMessage& m) {
                         model_->submit_scan(std::make_shared<const wire::RangeScan>(m.range_scan()));
                       });
  if (servo_log_) {
    if (auto e = servo_log_->start(o_.log_path)) throw std::runtime_error(*e);
    if (auto e = world_log_->start(o_.log_path + ".world.csv")) throw std::runtime_error(*e);
  }
  model_->step(steady_now_ns());  // a first snapshot before the servo starts
  model_->start();
  const servo::RealtimeStatus rt = loop_->start();
  asio::post(io_, [this] {
    sender_->start();
    poll_link();
  });
  return rt;
}

void OperatorStation::poll_link() {
  if (stopped_) return;
  const net::LinkStatistics st = client_.statistics();
  if (st.clock.valid) {
    model_->set_clock_offset(st.clock.offset_ns);
    model_->set_command_delay(st.clock.rtt_median_ns / 2);
    loop_->set_link_stats(st.clock.rtt_last_ns, st.clock.offset_ns);
  }
  link_timer_.expires_after(std::chrono::nanoseconds(static_cast<std::int64_t>(o_.stats_period_s * 1e9)));
  link_timer_.async_wait([this](const asio::error_code& ec) {
    if (!ec) poll_link();
  });
}

void OperatorStation::stop() {
  if (!started_ || stopped_) return;
  stopped_ = true;
  loop_->stop();
  model_->stop();
  // The sender and the link timer live on the io thread: cancel them there if
  // it still runs, else here (nothing else touches them then).
  auto detach = [this] {
    sender_->stop();
    link_timer_.cancel();
    client_.streams().on(wire::StreamMessage::kRobotState, nullptr);
    client_.streams().on(wire::StreamMessage::kRangeScan, nullptr);
  };
  if (io_.stopped() || io_.get_executor().running_in_this_thread()) {
    detach();
  } else {
    auto done = std::make_shared<std::promise<void>>();
    auto fut = done->get_future();
    asio::post(io_, [detach, done] {
      detach();
      done->set_value();
    });
    // If the io thread does not run handlers within 2 s it is not running:
    // then nothing else touches these objects and detaching here is safe.
    if (fut.wait_for(std::chrono::seconds(2)) != std::future_status::ready) detach();
  }
  if (servo_log_) {
    servo_log_->stop();
    world_log_->stop();
    std::string err;
    write_map_csv(model_->map(), o_.log_path + ".map.csv", &err);
  }
}

OperatorStationSummary OperatorStation::summary() const {
  OperatorStationSummary s;
  s.timing = loop_->summary();
  s.model = model_->stats();
  s.commands = sender_->stats();
  s.mode_switches = task_->mode_switches();
  if (servo_log_) {
    s.servo_log_written = servo_log_->written();
    s.servo_log_dropped = servo_log_->dropped();
    s.world_log_written = world_log_->written();
    s.world_log_dropped = world_log_->dropped();
  }
  return s;
}

}  // namespace hemm::op
