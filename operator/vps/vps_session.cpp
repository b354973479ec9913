#include "operator/vps/vps_session.h"

#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "common/config/config.h"
#include "operator/device/bimanual/simulated_bimanual_device.h"
#include "report.pb.h"

namespace hemm::op {

VpsSessionSummary run_vps_session(device::HapticDevice& device, std::shared_ptr<const VpsLocalModel> model,
                                  const VpsSessionOptions& o, const std::atomic<bool>* stop,
                                  const std::function<void(const servo::RealtimeStatus&)>& on_start) {
  if (!(o.duration_s > 0) && stop == nullptr)
    throw std::invalid_argument("VPS session: needs a duration or a stop flag");
  VpsLogger log = make_vps_logger();
  if (!o.log_path.empty()) {
    if (auto err = log.start(o.log_path)) throw std::runtime_error("--log: " + *err);
  }
  VpsTaskParams tp = o.task;
  tp.period_s = static_cast<double>(o.servo.period_ns) * 1e-9;
  VpsServoTask task(model, device.limits(), tp, o.log_path.empty() ? nullptr : &log);
  if (o.view.ticks != nullptr)
    task.set_view(o.view.ticks, dynamic_cast<const device::bimanual::SimulatedBimanualDevice*>(&device));
  servo::ModelChannel channel;
  // The scene is static: published once for any other reader (a view).
  auto snap = std::make_unique<VpsModelSnapshot>();
  snap->model = model;
  snap->version = 1;
  channel.publish(std::move(snap));
  servo::ServoLoop loop(device, task, channel, o.servo);
  const servo::RealtimeStatus rt = loop.start();
  if (on_start) on_start(rt);
  if (o.view.started) o.view.started(loop.stats());
  const auto ticks =
      o.duration_s > 0 ? static_cast<std::uint64_t>(std::llround(o.duration_s / tp.period_s)) : ~std::uint64_t{0};
  while (loop.stats().ticks.load(std::memory_order_relaxed) < ticks &&
         !(stop != nullptr && stop->load(std::memory_order_relaxed)))
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  loop.stop();
  if (o.view.stopped) o.view.stopped();
  log.stop();
  VpsSessionSummary s;
  s.device = std::string(device.name());
  s.end_effectors = device.limits().end_effectors;
  s.objects = model->object_count;
  s.model_bytes = model->memory_bytes();
  s.timing = loop.summary();
  s.vps_compute = servo::summarize(task.vps_compute());
  s.stats = task.stats();
  s.budget.params.tick_ns = tp.tick_budget_ns;
  s.budget.params.margin_ns = tp.tick_margin_ns;
  s.budget.params.max_work = tp.budget;
  s.budget.calibration = task.calibration();
  s.budget.stats = task.budget_stats();
  for (int k = 0; k < s.objects; ++k) {
    const vps::CouplingDesign& d = task.coupling(k);
    s.coupling_k[k] = d.params.k_lin;
    s.coupling_b[k] = d.params.b_lin;
    s.coupling_k_rot[k] = d.params.k_rot;
    s.passivity_lhs[k] = d.passivity_lhs;
    s.passivity_bound[k] = d.passivity_bound;
    s.final_object_W[k] = task.object_pose(k).translation();
  }
  if (s.objects == 2) s.final_rel_01 = task.object_pose(1).inverse() * task.object_pose(0).translation();
  s.log_written = log.written();
  s.log_dropped = log.dropped();
  s.log_failed = log.write_failed();
  return s;
}

std::string to_string(const VpsSessionSummary& s) {
  std::ostringstream o;
  o << "vps session: device " << s.device << ", " << s.end_effectors << " end-effector(s), " << s.objects
    << " object(s), model " << s.model_bytes / 1000 << " kB\n";
  o << "  servo: " << servo::to_string(s.timing) << "\n";
  o << "  servo worst ticks: " << rt::worst_ticks_text(s.timing.worst) << "\n";
  o << "  vps work per tick: median " << s.vps_compute.median_us << " us, p99 " << s.vps_compute.p99_us << " us, max "
    << s.vps_compute.max_us << " us; max work " << s.stats.max_work << "\n";
  o << "  vps budget: " << to_string(s.budget) << "\n";
  const char* pair[3] = {"right-scene", "left-scene", "right-left"};
  o << "  max penetration:";
  for (int i = 0; i < 3; ++i) o << " " << pair[i] << " " << s.stats.max_penetration[i] * 1e3 << " mm";
  o << "\n";
  for (int k = 0; k < s.objects; ++k)
    o << "  ee " << k << ": coupling K " << s.coupling_k[k] << " N/m, B " << s.coupling_b[k] << " N s/m, K_rot "
      << s.coupling_k_rot[k] << " N m/rad (KT/2+B " << s.passivity_lhs[k] << " <= " << s.passivity_bound[k]
      << "); passivity observer: energy to the hand " << s.stats.energy_J[k] << " J at the end, max "
      << s.stats.max_energy_J[k] << " J; max |F| " << s.stats.max_force_N[k] << " N, |tau| "
      << s.stats.max_torque_Nm[k] << " N m; object at " << s.final_object_W[k].transpose() << "\n";
  if (s.objects == 2) o << "  object 0 in object 1's frame at the end: " << s.final_rel_01.transpose() * 1e3 << " mm\n";
  o << "  log: " << s.log_written << " written, " << s.log_dropped << " dropped" << (s.log_failed ? ", WRITE FAILED" : "")
    << "\n";
  return o.str();
}

report::VpsSession to_report(const VpsSessionSummary& s) {
  report::VpsSession r;
  auto arr = [](google::protobuf::RepeatedField<double>* out, const double* v, int n) { out->Add(v, v + n); };
  r.set_device(s.device);
  r.set_end_effectors(s.end_effectors);
  r.set_objects(s.objects);
  r.set_model_bytes(s.model_bytes);
  r.set_ticks(s.timing.ticks);
  r.set_misses(s.timing.misses);
  r.set_overruns(s.timing.overruns);
  r.set_period_median_us(s.timing.period.median_us);
  r.set_period_p99_us(s.timing.period.p99_us);
  r.set_compute_median_us(s.timing.compute.median_us);
  r.set_compute_p99_us(s.timing.compute.p99_us);
  r.set_vps_median_us(s.vps_compute.median_us);
  r.set_vps_p99_us(s.vps_compute.p99_us);
  r.set_vps_max_us(s.vps_compute.max_us);
  r.set_max_work(s.stats.max_work);
  arr(r.mutable_max_penetration_m(), s.stats.max_penetration, 3);
  arr(r.mutable_energy_j(), s.stats.energy_J, 2);
  arr(r.mutable_max_energy_j(), s.stats.max_energy_J, 2);
  arr(r.mutable_max_force_n(), s.stats.max_force_N, 2);
  arr(r.mutable_coupling_k(), s.coupling_k, 2);
  arr(r.mutable_coupling_b(), s.coupling_b, 2);
  arr(r.mutable_final_rel_01_m(), s.final_rel_01.data(), 3);
  arr(r.mutable_final_object0_w(), s.final_object_W[0].data(), 3);
  arr(r.mutable_final_object1_w(), s.final_object_W[1].data(), 3);
  r.set_log_written(s.log_written);
  r.set_log_dropped(s.log_dropped);
  r.set_log_failed(s.log_failed);
  to_report(s.budget, r.mutable_budget());
  servo::fill(r.mutable_timing(), s.timing);  // histograms, worst ticks, simulated hardware
  return r;
}

std::string to_json(const VpsSessionSummary& s) { return config::to_json(to_report(s)); }

SceneHands scene_hands(const std::string& scene) {
  if (scene == "peg-in-hole") return {[](double t) { return vps::peg_in_hole_hands(t); }, vps::kPegInHoleDuration};
  if (scene == "assembly") return {[](double t) { return vps::assembly_hands(t); }, vps::kAssemblyDuration};
  throw std::invalid_argument("scripted hands: unknown scene '" + scene + "'");
}

device::Trajectory scene_hands_trajectory(const std::string& scene, double rate_hz,
                                          const std::array<VpsEndEffectorParams, device::kMaxEndEffectors>& ee) {
  const SceneHands path = scene_hands(scene);
  if (!(rate_hz >= 10 && rate_hz <= 10000)) throw std::invalid_argument("scripted hands: rate must be in [10, 10000]");
  // Where each end-effector must be at time t (right: 0, left: 1).
  auto at = [&](double t) {
    const vps::BimanualPoses p = path.at(t);
    return std::array<Eigen::Isometry3d, 2>{end_effector_pose_H(ee[0], p.right), end_effector_pose_H(ee[1], p.left)};
  };
  const double h = 0.5 / rate_hz;
  device::Trajectory tr;
  tr.end_effectors = 2;
  tr.has_twist = true;
  const int n = static_cast<int>(std::floor(path.duration_s * rate_hz)) + 1;
  tr.samples.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const double t = i / rate_hz;
    const auto now = at(t), before = at(std::max(0.0, t - h)), after = at(t + h);
    device::TrajectorySample s;
    s.t_s = t;
    s.end_effectors = 2;
    for (std::size_t k = 0; k < 2; ++k) {
      device::EndEffectorSample& e = s.ee[k];
      const double span = t + h - std::max(0.0, t - h);
      e.position_H = now[k].translation();
      e.orientation_H = Eigen::Quaterniond(now[k].linear());
      e.velocity_H = (after[k].translation() - before[k].translation()) / span;
      const Eigen::AngleAxisd d(after[k].linear() * before[k].linear().transpose());
      e.angular_velocity_H = d.axis() * d.angle() / span;
    }
    tr.samples.push_back(s);
  }
  return tr;
}

}  // namespace hemm::op
