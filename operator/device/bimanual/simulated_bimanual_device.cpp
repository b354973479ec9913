#include "operator/device/bimanual/simulated_bimanual_device.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/clock/steady_clock.h"

namespace hemm::device::bimanual {

DeviceLimits bimanual_limits(const SimulationConfig& c) {
  DeviceLimits d;
  d.end_effectors = kArms;
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmControlParams& p = c.control[k];
    const HandleSpec h = handle_spec(c.plant.handles[k]);
    EndEffectorLimits& l = d.ee[k];
    l.workspace_min_H = p.workspace_D.min_D;
    l.workspace_max_H = p.workspace_D.max_D;
    // The drives' torque limits are their continuous ratings: no separate
    // thermal budget on top of the joint-torque saturation.
    l.peak_force = p.peak_force;
    l.max_continuous_force = p.peak_force;
    // Stable walls with ~1-2 kg felt (feed-forward on) at 1 kHz; ASSUMED
    // design values, not the real device's published numbers.
    l.max_stiffness = 5000.0;
    l.renders_torque = true;
    l.peak_torque = p.peak_torque;
    l.max_rotational_stiffness = 20.0;
    l.peak_grip_force = h.kind == HandleKind::kGripForce ? h.grip_max_force : 0.0;
    l.max_linear_speed = p.max_linear_speed;
  }
  return d;
}

SimulatedBimanualDevice::SimulatedBimanualDevice(const SimulationConfig& config,
                                                 std::array<std::shared_ptr<const HumanScript>, kArms> hands)
    : sim_(config),
      hands_(std::move(hands)),
      limits_(bimanual_limits(config)),
      min_arm_arm_m_(std::numeric_limits<double>::infinity()),
      min_arm_table_m_(std::numeric_limits<double>::infinity()),
      plant_min_arm_arm_m_(std::numeric_limits<double>::infinity()),
      plant_min_arm_table_m_(std::numeric_limits<double>::infinity()) {
  for (const auto& h : hands_) {
    if (!h) throw std::invalid_argument("SimulatedBimanualDevice: null hand script");
  }
  if (const char* e = check_limits(limits_)) throw std::invalid_argument(std::string("SimulatedBimanualDevice: ") + e);
}

const ArmReading& SimulatedBimanualDevice::reading(ArmSide s) const noexcept {
  return threaded_ ? readings_[static_cast<std::size_t>(index(s))] : sim_.reading(s);
}

void SimulatedBimanualDevice::read(DeviceSample& out) noexcept {
  out.measured_ns = 0;
  if (threaded_) {
    const Sample* fresh = samples_.take();
    if (fresh != nullptr) {
      readings_ = fresh->readings;
      sim_.sense(readings_);  // the backend's forward kinematics of the new readings
    }
    const Sample* s = fresh != nullptr ? fresh : samples_.latest();  // never null: start() published one
    out.measured_ns = s->t_ns;
    hardware_->stats().sample_age.record(steady_now_ns() - s->t_ns);
  }
  out.end_effectors = kArms;
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmSide side = static_cast<ArmSide>(a);
    const EndEffectorState& s = sim_.end_effector(side);
    const ArmReading& r = reading(side);
    EndEffectorSample& e = out.ee[k];
    e.position_H = s.T_D_E.translation();
    e.orientation_H = Eigen::Quaterniond(s.T_D_E.linear()).normalized();
    e.velocity_H = s.velocity_D;
    e.angular_velocity_H = s.angular_velocity_D;
    e.enabled = r.powered;
    HandleInputs& in = e.handle;
    in = HandleInputs{};
    const HandleKind kind = sim_.config().plant.handles[k];
    in.buttons = r.buttons;
    in.has_deadman = has_input(kind, HandleInput::kDeadman);
    in.deadman = in.has_deadman && r.deadman_closed;
    in.has_grip = has_input(kind, HandleInput::kGrip);
    if (in.has_grip) {
      in.grip_position = r.grip_position;
      in.grip_velocity = r.grip_velocity;
    }
    in.has_joystick = has_input(kind, HandleInput::kJoystickAxes);
    if (in.has_joystick) {
      in.joystick = r.joystick;
      in.switch_on = r.switch_on;
    }
    in.has_clutch = has_input(kind, HandleInput::kClutch);
    in.attached = !in.has_clutch || r.attached;
  }
}

void SimulatedBimanualDevice::write(const DeviceCommand& cmd_in) noexcept {
  ++counters_.writes;
  DeviceCommand cmd = cmd_in;
  counters_.nonfinite_commands += static_cast<std::uint64_t>(zero_nonfinite_wrenches(cmd, kArms));
  std::array<kinematics::Wrench6, kArms> w;
  std::array<double, kArms> grip{};
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    EndEffectorCommand& c = cmd.ee[k];
    const EndEffectorLimits& l = limits_.ee[k];
    if (c.grip_force != 0.0 && l.peak_grip_force <= 0.0) ++counters_.missing_input_commands;
    const EndEffectorCommand before = c;
    clamp_to_peak(c, l);
    if (before.force_H != c.force_H || before.torque_H != c.torque_H) ++counters_.limited_commands;
    const bool enabled = reading(static_cast<ArmSide>(a)).powered;
    if (!enabled && (c.force_H.squaredNorm() + c.torque_H.squaredNorm() + c.grip_force * c.grip_force > 0.0)) {
      ++counters_.disabled_commands;
      c = EndEffectorCommand{};
    }
    w[k] << c.force_H, c.torque_H;
    grip[k] = c.grip_force;
  }
  const CollisionResult& col = sim_.controller().collisions();
  if (threaded_) {
    Command& c = commands_.back();
    sim_.control(readings_, w, grip, c.act);
    c.t_ns = steady_now_ns();
    commands_.publish();
    count_limits(readings_);
    min_arm_arm_m_ = std::min(min_arm_arm_m_, col.min_arm_arm_m);
    min_arm_table_m_ = std::min(min_arm_table_m_, col.min_arm_table_m);
    return;
  }
  // The hands move to where they want to be at the end of this period.
  const double t = sim_.time_s() + sim_.config().plant.control_period_s;
  sim_.step(w, grip, {hands_[0]->at(t), hands_[1]->at(t)});
  count_limits(sim_.readings());
  const PlantTruth& truth = sim_.truth();
  min_arm_arm_m_ = std::min({min_arm_arm_m_, truth.min_arm_arm_m, col.min_arm_arm_m});
  min_arm_table_m_ = std::min({min_arm_table_m_, truth.min_arm_table_m, col.min_arm_table_m});
}

void SimulatedBimanualDevice::count_limits(const ArmReadings& r) noexcept {
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    const ArmOutput& o = sim_.output(static_cast<ArmSide>(a));
    const double joint = o.tau_limits.norm(), wall = o.w_limits_D.head<3>().norm(), col = o.tau_collision.norm();
    counters_.joint_limit_writes[k] += joint > 0.5 ? 1u : 0u;
    counters_.wall_writes[k] += wall > 1.0 ? 1u : 0u;
    counters_.collision_writes[k] += col > 0.5 ? 1u : 0u;
    counters_.stretched_writes[k] += std::abs(r[k].q(3)) < 0.1 ? 1u : 0u;
    counters_.peak_joint_limit_nm[k] = std::max(counters_.peak_joint_limit_nm[k], joint);
    counters_.peak_wall_n[k] = std::max(counters_.peak_wall_n[k], wall);
    counters_.peak_collision_nm[k] = std::max(counters_.peak_collision_nm[k], col);
  }
}

void SimulatedBimanualDevice::hardware_step() noexcept {
  const Command* c = commands_.take();
  hardware_->stats().took_command(c != nullptr);
  if (c != nullptr) held_ = c->act;
  const double t = sim_.time_s() + sim_.config().plant.control_period_s;
  sim_.plant().step(held_, {hands_[0]->at(t), hands_[1]->at(t)});
  const PlantTruth& truth = sim_.truth();
  plant_min_arm_arm_m_ = std::min(plant_min_arm_arm_m_, truth.min_arm_arm_m);
  plant_min_arm_table_m_ = std::min(plant_min_arm_table_m_, truth.min_arm_table_m);
  Sample& s = samples_.back();
  s.readings = sim_.readings();
  s.t_ns = steady_now_ns();
  samples_.publish();
}

void SimulatedBimanualDevice::start(const HardwareStart& how, std::vector<std::string>* warnings) {
  if (how.mode != HardwareMode::kThreaded || threaded_) return;
  if (!hardware_) hardware_ = std::make_unique<SimulatedHardwareThread>();
  // Before the plant's thread runs: the backend holds the plant's readings,
  // read() has a first sample, and the torques in force are the
  // controllers' for those readings with nothing rendered (the arms hold
  // their weight until the first write).
  readings_ = sim_.readings();
  samples_.publish(Sample{steady_now_ns(), readings_});
  commands_.take();  // a command left from an earlier run is not in force
  sim_.control(readings_, {kinematics::Wrench6::Zero(), kinematics::Wrench6::Zero()}, {0.0, 0.0}, held_);
  threaded_ = true;
  try {
    const rt::RealtimeStatus st = hardware_->start(
        static_cast<std::int64_t>(sim_.config().plant.control_period_s * 1e9 + 0.5), how.realtime,
        "bimanual-plant", [this](std::int64_t) { hardware_step(); });
    if (warnings != nullptr)
      for (const std::string& w : st.warnings) warnings->push_back("simulated bimanual plant thread: " + w);
  } catch (...) {
    threaded_ = false;
    throw;
  }
}

void SimulatedBimanualDevice::stop() noexcept {
  if (!threaded_) return;
  hardware_->stop();
  threaded_ = false;
  min_arm_arm_m_ = std::min(min_arm_arm_m_, plant_min_arm_arm_m_);
  min_arm_table_m_ = std::min(min_arm_table_m_, plant_min_arm_table_m_);
  // Lock-step from here on: the backend's view from the plant's last readings.
  sim_.sense(sim_.readings());
}

}  // namespace hemm::device::bimanual
