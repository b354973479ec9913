#include "operator/vps/vps_task.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/clock/steady_clock.h"

namespace hemm::op {

namespace {

Eigen::Isometry3d pose_of(const device::EndEffectorSample& s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = s.orientation_H.normalized().toRotationMatrix();
  T.translation() = s.position_H;
  return T;
}

bool finite_sample(const device::EndEffectorSample& s) {
  return s.position_H.allFinite() && s.orientation_H.coeffs().allFinite() && s.orientation_H.norm() > 0.5 &&
         s.velocity_H.allFinite() && s.angular_velocity_H.allFinite();
}

}  // namespace

const char* vps_log_header() {
  return "t_ns,ees,"
         "dev0_x,dev0_y,dev0_z,obj0_x,obj0_y,obj0_z,f0_x,f0_y,f0_z,tau0_x,tau0_y,tau0_z,energy0,"
         "dev1_x,dev1_y,dev1_z,obj1_x,obj1_y,obj1_z,f1_x,f1_y,f1_z,tau1_x,tau1_y,tau1_z,energy1,"
         "contacts_rs,contacts_ls,contacts_rl,pen_rs,pen_ls,pen_rl,rel_x,rel_y,rel_z,vps_ns,work,levels";
}

std::size_t format_vps_log_record(const VpsLogRecord& r, char* buf, std::size_t size) {
  int n = std::snprintf(buf, size, "%lld,%d", static_cast<long long>(r.t_ns), r.end_effectors);
  auto add = [&](const char* fmt, auto... v) {
    if (n < 0 || static_cast<std::size_t>(n) >= size) return;
    n += std::snprintf(buf + n, size - static_cast<std::size_t>(n), fmt, v...);
  };
  for (int k = 0; k < 2; ++k) {
    for (const double* a : {r.device_W[k], r.object_W[k], r.force_H[k], r.torque_H[k]})
      add(",%.9g,%.9g,%.9g", a[0], a[1], a[2]);
    add(",%.9g", r.energy_J[k]);
  }
  add(",%d,%d,%d", r.contacts[0], r.contacts[1], r.contacts[2]);
  add(",%.6g,%.6g,%.6g", r.max_penetration[0], r.max_penetration[1], r.max_penetration[2]);
  add(",%.9g,%.9g,%.9g", r.rel_01[0], r.rel_01[1], r.rel_01[2]);
  add(",%lld,%lld,%d\n", static_cast<long long>(r.vps_ns), static_cast<long long>(r.work), r.levels);
  if (n < 0 || static_cast<std::size_t>(n) >= size) return 0;
  return static_cast<std::size_t>(n);
}

device::DeviceLimits scripted_hands_limits(int end_effectors) { return device::rigid_hand_limits(end_effectors); }

VpsServoTask::VpsServoTask(std::shared_ptr<const VpsLocalModel> model, const device::DeviceLimits& limits,
                           const VpsTaskParams& params, VpsLogger* log)
    : model_(std::move(model)), p_(params), log_(log) {
  if (!model_) throw std::invalid_argument("VPS task: no model");
  if (const char* bad = device::check_limits(limits)) throw std::invalid_argument(std::string("VPS task: ") + bad);
  objects_ = model_->object_count;
  if (objects_ < 1 || objects_ > limits.end_effectors)
    throw std::invalid_argument("VPS task: the model has " + std::to_string(objects_) + " objects for " +
                                std::to_string(limits.end_effectors) + " end-effector(s)");
  if (!(p_.period_s > 0 && p_.period_s <= 0.01)) throw std::invalid_argument("VPS task: period must be in (0, 10 ms]");
  if (p_.budget < 1) throw std::invalid_argument("VPS task: budget must be >= 1");
  for (int k = 0; k < objects_; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const device::EndEffectorLimits& l = limits.ee[ku];
    vps::CouplingDeviceLimits d;
    d.dt = p_.period_s;
    d.peak_force = l.peak_force;
    d.max_stiffness = l.max_stiffness;
    d.max_speed = l.max_linear_speed > 0 ? std::min(l.max_linear_speed, p_.max_speed) : p_.max_speed;
    d.renders_torque = l.renders_torque;
    d.peak_torque = l.peak_torque;
    d.max_rot_stiffness = l.max_rotational_stiffness;
    d.max_angular_speed = p_.max_angular_speed;
    const VpsObjectModel& o = model_->objects[ku];
    design_[ku] = vps::design_coupling(o.mass.mass, o.mass.inertia_com, d, p_.design);
    T_C_M_[ku] = Eigen::Isometry3d::Identity();
    T_C_M_[ku].translation() = -o.mass.centre_of_mass;
  }
  if (objects_ == 2)
    vps::init_bimanual_state(model_->bimanual, &bimanual_state_);
  else
    vps::init_pair_state(model_->objects[0].shell, &single_state_);
  vps::TimeBudgetParams tb;
  tb.tick_ns = p_.tick_budget_ns;
  tb.margin_ns = p_.tick_margin_ns;
  tb.max_work = p_.budget;
  if (std::string e = vps::validate(tb); !e.empty()) throw std::invalid_argument("VPS task: " + e);
  if (p_.calibration_poses < 1 || p_.calibration_poses > 10000)
    throw std::invalid_argument("VPS task: calibration poses must be in [1, 10000]");
  // The cost of a work unit on this machine, on this model: the pairs the
  // ticks will run, timed here (off the servo thread) before the first tick.
  if (tb.tick_ns > 0) {
    const VpsLocalModel& m = *model_;
    std::vector<vps::CalibrationPair> pairs{{&m.scene, &m.objects[0].shell}};
    if (objects_ == 2) {
      pairs.push_back({&m.scene, &m.objects[1].shell});
      pairs.push_back({&m.objects[1].voxmap, &m.objects[0].shell});
    }
    calibration_ = vps::calibrate_work_rate(pairs, m.bimanual.params, tb.rate, p_.calibration_poses, &steady_now_ns);
  }
  budget_ = vps::TickWorkBudget(tb, calibration_.rate);
}

Eigen::Isometry3d VpsServoTask::object_pose(int k) const {
  return body_[static_cast<std::size_t>(k)].pose() * T_C_M_[static_cast<std::size_t>(k)];
}

void VpsServoTask::tick(const device::DeviceSample& in, const servo::ModelSnapshot& /*snapshot*/,
                        servo::TickOutput& out) noexcept {
  const std::int64_t t0 = steady_now_ns();
  const int n = std::min(objects_, in.end_effectors);
  // Where each end-effector wants its object's centre of mass (T_W_D), and how fast.
  std::array<Eigen::Isometry3d, device::kMaxEndEffectors> T_W_D, T_W_E;
  std::array<Eigen::Vector3d, device::kMaxEndEffectors> v_D, w_D;
  std::array<bool, device::kMaxEndEffectors> ok{};
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const device::EndEffectorSample& s = in.ee[ku];
    ok[ku] = finite_sample(s);
    if (!ok[ku]) continue;  // a bad reading: no wrench, the object stays where it is
    const VpsEndEffectorParams& e = p_.ee[ku];
    const Eigen::Isometry3d T_H_E = pose_of(s);
    T_W_E[ku] = e.T_W_H * T_H_E;
    T_W_D[ku] = object_pose_W(e, T_H_E) * T_C_M_[ku].inverse();
    const Eigen::Matrix3d R_W_H = e.T_W_H.linear();
    w_D[ku] = R_W_H * s.angular_velocity_H;
    const Eigen::Vector3d r_W = T_W_D[ku].translation() - T_W_E[ku].translation();
    v_D[ku] = R_W_H * s.velocity_H + w_D[ku].cross(r_W);
    if (!started_[ku]) {  // the object appears at rest where the hand holds it
      body_[ku] = vps::RigidBodyState{};
      body_[ku].position = T_W_D[ku].translation();
      body_[ku].orientation = Eigen::Quaterniond(T_W_D[ku].linear());
      started_[ku] = true;
    }
  }
  // The pairs, on the objects' present poses.
  // In the time-critical order (coarse to fine, all pairs per level) within
  // the tick's budget; the full cycle when there is none.
  const VpsLocalModel& m = *model_;
  vps::Wrench contact[device::kMaxEndEffectors];
  data_.work = 0;
  if (objects_ == 2 && started_[0] && started_[1]) {
    const Eigen::Isometry3d T_W_R = object_pose(0), T_W_L = object_pose(1);
    const std::int64_t units = budget_.begin(steady_now_ns(), out.deadline_ns);
    if (units == vps::kUnlimitedWork)
      vps::evaluate_bimanual(m.bimanual, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, &bimanual_state_, &data_);
    else
      vps::evaluate_bimanual_budgeted(m.bimanual, Eigen::Isometry3d::Identity(), T_W_R, T_W_L, units,
                                      &bimanual_state_, &data_);
    const int lr = m.objects[0].shell.levels, ll = m.objects[1].shell.levels;
    const bool complete = data_.right_scene.levels_completed >= lr && data_.left_scene.levels_completed >= ll &&
                          data_.right_left.levels_completed >= lr;
    budget_.end(steady_now_ns(), data_.work, data_.levels_completed, complete);
    contact[0] = data_.right_total;
    contact[1] = data_.left_total;
  } else if (objects_ == 1 && started_[0]) {
    const std::int64_t units = budget_.begin(steady_now_ns(), out.deadline_ns);
    vps::evaluate_pair_budgeted(m.scene, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), m.objects[0].shell,
                                object_pose(0), m.bimanual.params, units, &single_state_, &data_.right_scene);
    data_.work = data_.right_scene.points_tested + data_.right_scene.nodes_visited;
    data_.levels_completed = data_.right_scene.levels_completed;
    budget_.end(steady_now_ns(), data_.work, data_.levels_completed,
                data_.levels_completed >= m.objects[0].shell.levels);
    contact[0] = data_.right_scene.on_shell;
  }
  out.renderer = "vps";
  out.work = data_.work;
  // The couplings, and their reactions to the device at the end-effector point.
  VpsLogRecord rec;
  rec.t_ns = in.t_ns;
  rec.end_effectors = n;
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    if (!ok[ku]) continue;
    vps::Wrench dev;
    vps::step_virtual_coupling(design_[ku].params, T_W_D[ku], v_D[ku], w_D[ku], contact[ku], &body_[ku], &dev);
    const Eigen::Vector3d r = T_W_D[ku].translation() - T_W_E[ku].translation();
    const Eigen::Matrix3d R_H_W = p_.ee[ku].T_W_H.linear().transpose();
    const Eigen::Vector3d F_H = R_H_W * dev.force;
    const Eigen::Vector3d tau_H = R_H_W * (dev.torque + r.cross(dev.force));
    device::EndEffectorCommand& c = out.command.ee[ku];
    c.force_H = F_H;
    c.torque_H = tau_H;
    const device::EndEffectorSample& s = in.ee[ku];
    // Passivity observer: the energy the device gives the hand (a device
    // that renders no torque gives none through its gimbal).
    const double torque_power = c.torque_H.dot(s.angular_velocity_H);
    const double power = F_H.dot(s.velocity_H) + torque_power;
    stats_.energy_J[ku] += power * p_.period_s;
    stats_.max_energy_J[ku] = std::max(stats_.max_energy_J[ku], stats_.energy_J[ku]);
    stats_.min_energy_J[ku] = std::min(stats_.min_energy_J[ku], stats_.energy_J[ku]);
    stats_.max_force_N[ku] = std::max(stats_.max_force_N[ku], F_H.norm());
    stats_.max_torque_Nm[ku] = std::max(stats_.max_torque_Nm[ku], tau_H.norm());
    out.points[ku].proxy_position_H = p_.ee[ku].T_W_H.inverse() * object_pose(k).translation();
    for (int i = 0; i < 3; ++i) {
      rec.device_W[k][i] = T_W_E[ku].translation()[i];
      rec.object_W[k][i] = object_pose(k).translation()[i];
      rec.force_H[k][i] = F_H[i];
      rec.torque_H[k][i] = tau_H[i];
    }
    rec.energy_J[k] = stats_.energy_J[ku];
  }
  const vps::PairResult* pairs[3] = {&data_.right_scene, &data_.left_scene, &data_.right_left};
  for (int i = 0; i < (objects_ == 2 ? 3 : 1); ++i) {
    rec.contacts[i] = pairs[i]->contacts;
    rec.max_penetration[i] = pairs[i]->max_penetration;
    stats_.max_penetration[i] = std::max(stats_.max_penetration[i], pairs[i]->max_penetration);
    stats_.max_contacts[i] = std::max(stats_.max_contacts[i], pairs[i]->contacts);
  }
  if (objects_ == 2) {
    const Eigen::Vector3d rel = object_pose(1).inverse() * object_pose(0).translation();
    for (int i = 0; i < 3; ++i) rec.rel_01[i] = rel[i];
  }
  rec.work = data_.work;
  rec.levels = data_.levels_completed;
  stats_.max_work = std::max(stats_.max_work, data_.work);
  ++stats_.ticks;
  rec.vps_ns = steady_now_ns() - t0;
  vps_ns_.record(rec.vps_ns);
  if (log_ != nullptr) log_->push(rec);
  if (view_ != nullptr) {  // filled in place: one copy of the record
    DeviceViewRecord& v = view_->back();
    fill_device_view(in, out, view_arms_, stats_.ticks, v);
    v.objects = objects_;
    for (int k = 0; k < objects_; ++k) v.object_W[static_cast<std::size_t>(k)] = object_pose(k);
    v.pairs = objects_ == 2 ? 3 : 1;
    for (std::size_t i = 0; i < 3; ++i) {
      v.contacts[i] = rec.contacts[i];
      v.penetration_m[i] = rec.max_penetration[i];
    }
    for (std::size_t k = 0; k < 2; ++k) v.energy_J[k] = stats_.energy_J[k];
    v.vps_ns = rec.vps_ns;
    view_->publish();
  }
}

}  // namespace hemm::op
