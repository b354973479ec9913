#include "operator/device/simulated_omni.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "common/clock/steady_clock.h"

namespace hemm::device {

const char* check_model(const SimulatedOmniModel& m) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!pos(m.device_mass) || !nonneg(m.hand_mass)) return "masses must be finite, device_mass > 0";
  if (!nonneg(m.device_damping) || !nonneg(m.hand_damping) || !nonneg(m.end_stop_damping))
    return "damping must be finite and >= 0";
  if (!nonneg(m.hand_stiffness) || !pos(m.end_stop_stiffness))
    return "stiffness must be finite, end_stop_stiffness > 0";
  if (!pos(m.dt_s) || m.substeps < 1 || m.substeps > 1000) return "dt_s > 0, 1 <= substeps <= 1000";
  if (!pos(m.thermal_time_constant_s)) return "thermal_time_constant_s must be > 0";
  if (m.limits.renders_torque) return "the Omni renders no torque";
  return check_limits(m.limits);
}

Eigen::Vector3d limit_force(const SimulatedOmniModel& m, SimulatedOmniData& d,
                            const Eigen::Vector3d& force_cmd_H) {
  Eigen::Vector3d f = force_cmd_H;
  if (!f.allFinite()) {
    f.setZero();
    ++d.nonfinite_commands;
  }
  // Exact discretisation of the first-order thermal filter over one period:
  // E' = a E + (1 - a) |F|^2. Keeping E' <= Fc^2 bounds |F|^2 by the budget.
  const double a = std::exp(-m.dt_s / m.thermal_time_constant_s);
  const double fc2 = m.limits.max_continuous_force * m.limits.max_continuous_force;
  const double budget2 = std::max(0.0, (fc2 - a * d.mean_square_force) / (1.0 - a));
  const double peak2 = m.limits.peak_force * m.limits.peak_force;
  const double allowed2 = std::min(budget2, peak2);
  const double n2 = f.squaredNorm();
  if (n2 > allowed2) f *= std::sqrt(allowed2 / n2);
  d.mean_square_force = a * d.mean_square_force + (1.0 - a) * f.squaredNorm();
  return f;
}

void simulated_omni_step(const SimulatedOmniModel& m, SimulatedOmniData& d,
                         const HandTarget& target, const Eigen::Vector3d& force_cmd_H) {
  d.applied_force_H = limit_force(m, d, force_cmd_H);
  const double h = m.dt_s / m.substeps;
  const double inv_mass = 1.0 / m.total_mass();
  const double b = m.hand_damping + m.device_damping;
  const Eigen::Vector3d& lo = m.limits.workspace_min_H;
  const Eigen::Vector3d& hi = m.limits.workspace_max_H;
  for (int s = 0; s < m.substeps; ++s) {
    Eigen::Vector3d f =
        m.hand_stiffness * (target.position_H - d.position_H) - b * d.velocity_H + d.applied_force_H;
    for (int i = 0; i < 3; ++i) {
      // One-sided: the stop pushes back into the box and never pulls.
      if (d.position_H[i] > hi[i]) {
        const double stop = -m.end_stop_stiffness * (d.position_H[i] - hi[i]) -
                            m.end_stop_damping * d.velocity_H[i];
        f[i] += std::min(stop, 0.0);
      } else if (d.position_H[i] < lo[i]) {
        const double stop = m.end_stop_stiffness * (lo[i] - d.position_H[i]) -
                            m.end_stop_damping * d.velocity_H[i];
        f[i] += std::max(stop, 0.0);
      }
    }
    d.velocity_H += (h * inv_mass) * f;  // velocity first: semi-implicit Euler
    d.position_H += h * d.velocity_H;
  }
  d.orientation_H = target.orientation_H;
  d.buttons = target.buttons;
  d.deadman = target.deadman;
  d.t_s += m.dt_s;
  ++d.steps;
}

SimulatedOmni::SimulatedOmni(const SimulatedOmniModel& model,
                             std::shared_ptr<const HandScript> script)
    : model_(model), script_(std::move(script)) {
  if (const char* why = check_model(model_))
    throw std::invalid_argument(std::string("SimulatedOmni: ") + why);
  if (!script_) throw std::invalid_argument("SimulatedOmni: null hand script");
  limits_.end_effectors = 1;
  limits_.ee[0] = model_.limits;
  const HandTarget t0 = script_->at(0.0);
  data_.position_H = t0.position_H;
  data_.orientation_H = t0.orientation_H;
  data_.buttons = t0.buttons;
  data_.deadman = t0.deadman;
}

void SimulatedOmni::read(DeviceSample& out) noexcept {
  const SimulatedOmniData* d = &data_;
  out.measured_ns = 0;
  if (threaded_) {
    const Sample* s = samples_.take();
    if (s == nullptr) s = samples_.latest();  // never null: start() published one
    d = &s->data;
    out.measured_ns = s->t_ns;
    hardware_->stats().sample_age.record(steady_now_ns() - s->t_ns);
  }
  out.end_effectors = 1;
  EndEffectorSample& e = out.ee[0];
  e.position_H = d->position_H;
  e.orientation_H = d->orientation_H;
  e.velocity_H = d->velocity_H;
  e.angular_velocity_H.setZero();
  e.handle = HandleInputs{};
  e.handle.buttons = d->buttons;
  e.handle.has_deadman = true;
  e.handle.deadman = d->deadman;
  e.enabled = true;
}

Eigen::Vector3d SimulatedOmni::accepted_force(const EndEffectorCommand& c, std::uint64_t* nonfinite,
                                              std::uint64_t* ignored_grip) const noexcept {
  if (!wrench_is_finite(c)) {
    ++*nonfinite;
    return Eigen::Vector3d::Zero();
  }
  if (c.grip_force != 0.0) ++*ignored_grip;
  return c.force_H;
}

void SimulatedOmni::write(const DeviceCommand& cmd) noexcept {
  if (threaded_) {
    Command& c = commands_.back();
    c.force_H = accepted_force(cmd.ee[0], &refused_nonfinite_, &refused_grip_);
    c.t_ns = steady_now_ns();
    commands_.publish();
    return;
  }
  const Eigen::Vector3d force_H =
      accepted_force(cmd.ee[0], &data_.nonfinite_commands, &data_.ignored_grip_commands);
  // The target at the end of the period: the hand reacts within the step.
  simulated_omni_step(model_, data_, script_->at(data_.t_s + model_.dt_s), force_H);
}

void SimulatedOmni::hardware_step() noexcept {
  const Command* c = commands_.take();
  hardware_->stats().took_command(c != nullptr);
  if (c != nullptr) held_ = *c;
  simulated_omni_step(model_, data_, script_->at(data_.t_s + model_.dt_s), held_.force_H);
  Sample& s = samples_.back();
  s.data = data_;
  s.t_ns = steady_now_ns();
  samples_.publish();
}

void SimulatedOmni::start(const HardwareStart& how, std::vector<std::string>* warnings) {
  if (how.mode != HardwareMode::kThreaded || threaded_) return;
  if (!hardware_) hardware_ = std::make_unique<SimulatedHardwareThread>();
  // The first sample before the thread runs: read() always has one. The
  // force in effect starts at zero, as after power-up.
  samples_.publish(Sample{steady_now_ns(), data_});
  commands_.take();  // a command left from an earlier run is not in force
  held_ = Command{};
  threaded_ = true;
  try {
    const rt::RealtimeStatus st =
        hardware_->start(static_cast<std::int64_t>(model_.dt_s * 1e9 + 0.5), how.realtime, "omni-hand",
                         [this](std::int64_t) { hardware_step(); });
    if (warnings != nullptr)
      for (const std::string& w : st.warnings) warnings->push_back("simulated Omni hardware thread: " + w);
  } catch (...) {
    threaded_ = false;
    throw;
  }
}

void SimulatedOmni::stop() noexcept {
  if (!threaded_) return;
  hardware_->stop();
  threaded_ = false;
  data_.nonfinite_commands += refused_nonfinite_;
  data_.ignored_grip_commands += refused_grip_;
  refused_nonfinite_ = refused_grip_ = 0;
}

}  // namespace hemm::device
