#include "robot_side/twoarm/workbench_sim.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <mujoco/mujoco.h>

#include "common/sim/mujoco_owner.h"
#include "common/sim/mujoco_pose.h"

namespace hemm::twoarm {

namespace hk = hemm::kinematics;

namespace {

int id_of(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw std::runtime_error("workbench scene lacks " + name);
  return id;
}

// A body's mass, centre of mass and inertia about it, in frame F (T_F_W).
hk::RigidBodyInertia body_inertia_in(const mjModel* m, const mjData* d, int b, const Eigen::Isometry3d& T_F_W) {
  hk::RigidBodyInertia r;
  r.mass = m->body_mass[b];
  const Eigen::Isometry3d T_W_I = sim::mujoco_pose(d->xipos + 3 * b, d->ximat + 9 * b);
  const Eigen::Matrix3d R = T_F_W.linear() * T_W_I.linear();
  r.com = T_F_W * T_W_I.translation();
  r.inertia = R * Eigen::Vector3d(m->body_inertia[3 * b], m->body_inertia[3 * b + 1], m->body_inertia[3 * b + 2]).asDiagonal() *
              R.transpose();
  return r;
}

// Throws unless body `b` (link i+1) carries exactly lwr_arm_model()'s numbers.
void check_link(const mjModel* m, const mjData* d, int b, int jnt, const hk::Arm7Model& lwr, int i,
                const std::string& who) {
  const auto k = static_cast<std::size_t>(i);
  const std::string what = who + "link" + std::to_string(i + 1) + " differs from lwr_arm_model(): ";
  constexpr double kTol = 1e-9;
  for (int c = 0; c < 3; ++c) {
    if (std::abs(m->body_pos[3 * b + c] - lwr.offset[k](c)) > kTol) throw std::runtime_error(what + "offset");
    if (std::abs(m->jnt_axis[3 * jnt + c] - lwr.axis[k](c)) > kTol) throw std::runtime_error(what + "axis");
  }
  if (std::abs(m->body_quat[4 * b] - 1.0) > kTol) throw std::runtime_error(what + "body orientation");
  if (m->jnt_type[jnt] != mjJNT_HINGE || !m->jnt_limited[jnt] || std::abs(m->jnt_range[2 * jnt] - lwr.q_min(i)) > kTol ||
      std::abs(m->jnt_range[2 * jnt + 1] - lwr.q_max(i)) > kTol)
    throw std::runtime_error(what + "joint type or range");
  if (std::abs(m->dof_armature[m->jnt_dofadr[jnt]] - lwr.armature(i)) > kTol) throw std::runtime_error(what + "armature");
  const Eigen::Isometry3d T_W_B = sim::mujoco_pose(d->xpos + 3 * b, d->xmat + 9 * b);
  const hk::RigidBodyInertia in = body_inertia_in(m, d, b, T_W_B.inverse());
  if (std::abs(in.mass - lwr.link[k].mass) > kTol || (in.com - lwr.link[k].com).norm() > kTol ||
      (in.inertia - lwr.link[k].inertia).norm() > 1e-7)
    throw std::runtime_error(what + "mass, centre of mass or inertia");
}

}  // namespace

struct WorkbenchSim::Impl {
  sim::MjModelPtr m;
  sim::MjDataPtr d;
  struct Arm {
    std::array<int, hk::kArm7Dof> qpos{}, dof{}, motor{};
    std::array<int, 2> finger_qpos{}, finger_dof{}, finger_motor{}, pad{};
    int ft_force = -1, ft_torque = -1, grasp_site = -1;
  };
  std::array<Arm, kArms> arm;
  int torso = -1;
};

WorkbenchSim::WorkbenchSim(const std::string& scene_path) : impl_(std::make_unique<Impl>()) {
  Impl& I = *impl_;
  I.m = sim::load_model_file(scene_path);
  I.d = sim::make_data(I.m.get());
  mjModel* m = I.m.get();
  mjData* d = I.d.get();
  I.torso = id_of(m, mjOBJ_BODY, "torso");
  mj_forward(m, d);  // the reference pose: every joint at 0
  const Eigen::Isometry3d T_A_W = sim::mujoco_pose(d->xpos + 3 * I.torso, d->xmat + 9 * I.torso).inverse();
  const hk::Arm7Model lwr = hk::lwr_arm_model();
  for (Side s : {Side::kRight, Side::kLeft}) {
    Impl::Arm& a = I.arm[idx(s)];
    ArmMount& mount = model_.arms[idx(s)];
    const std::string p = prefix(s);
    for (int i = 0; i < hk::kArm7Dof; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const std::string n = std::to_string(i + 1);
      const int j = id_of(m, mjOBJ_JOINT, p + "j" + n);
      const int b = id_of(m, mjOBJ_BODY, p + "link" + n);
      if (m->jnt_bodyid[j] != b) throw std::runtime_error("workbench scene: " + p + "j" + n + " is not on " + p + "link" + n);
      check_link(m, d, b, j, lwr, i, p);
      a.qpos[k] = m->jnt_qposadr[j];
      a.dof[k] = m->jnt_dofadr[j];
      a.motor[k] = id_of(m, mjOBJ_ACTUATOR, p + "m" + n);
      const int g = id_of(m, mjOBJ_GEOM, p + "geom" + n);
      mount.link_radius(i) = m->geom_size[3 * g];
    }
    const int link7 = id_of(m, mjOBJ_BODY, p + "link7");
    const Eigen::Isometry3d T_W_Ar = sim::mujoco_pose(d->xpos + 3 * id_of(m, mjOBJ_BODY, p + "mount"),
                                             d->xmat + 9 * id_of(m, mjOBJ_BODY, p + "mount"));
    mount.T_A_Ar = T_A_W * T_W_Ar;
    const Eigen::Isometry3d T_J7_W = sim::mujoco_pose(d->xpos + 3 * link7, d->xmat + 9 * link7).inverse();
    // The gripper (palm and fingers, fingers closed) as link 7's payload.
    hk::RigidBodyInertia payload;
    for (const char* body : {"gripper", "finger_a", "finger_b"}) {
      const int b = id_of(m, mjOBJ_BODY, p + body);
      payload = hk::combine(payload, body_inertia_in(m, d, b, T_J7_W));
    }
    mount.gripper_J7 = payload;
    mount.arm = hk::with_payload(lwr, payload);
    a.grasp_site = id_of(m, mjOBJ_SITE, p + "grasp");
    mount.T_J7_G = T_J7_W * sim::mujoco_pose(d->site_xpos + 3 * a.grasp_site, d->site_xmat + 9 * a.grasp_site);
    const char* finger[2] = {"finger_a", "finger_b"};
    const char* pad[2] = {"pad_a", "pad_b"};
    for (int f = 0; f < 2; ++f) {
      const auto fk = static_cast<std::size_t>(f);
      const int j = id_of(m, mjOBJ_JOINT, p + finger[f]);
      a.finger_qpos[fk] = m->jnt_qposadr[j];
      a.finger_dof[fk] = m->jnt_dofadr[j];
      a.finger_motor[fk] = id_of(m, mjOBJ_ACTUATOR, p + finger[f]);
      a.pad[fk] = m->sensor_adr[id_of(m, mjOBJ_SENSOR, p + pad[f])];
      mount.gripper.finger_stroke_m = m->jnt_range[2 * j + 1];
      mount.gripper.max_force_N = m->actuator_ctrlrange[2 * a.finger_motor[fk] + 1];
    }
    a.ft_force = m->sensor_adr[id_of(m, mjOBJ_SENSOR, p + "ft_force")];
    a.ft_torque = m->sensor_adr[id_of(m, mjOBJ_SENSOR, p + "ft_torque")];
    // The palm box as a capsule along its long (y) axis.
    const int palm = id_of(m, mjOBJ_GEOM, p + "palm");
    const Eigen::Isometry3d T_J7_palm = T_J7_W * sim::mujoco_pose(d->geom_xpos + 3 * palm, d->geom_xmat + 9 * palm);
    const double* sz = m->geom_size + 3 * palm;
    mount.palm_radius_m = std::max(sz[0], sz[2]);
    mount.palm_a_J7 = T_J7_palm * Eigen::Vector3d(0.0, -sz[1], 0.0);
    mount.palm_b_J7 = T_J7_palm * Eigen::Vector3d(0.0, sz[1], 0.0);
  }
  // The rest postures: the operator rig's home posture, mirrored for the
  // right arm (the mounts are the rig's turned to face the bench, with right
  // and left swapped; deploy/scenes/README.md): every joint >= 0.7 rad from
  // its limits, the grasp frames 0.2 m above the bench pointing forward.
  hk::Arm7Vector home;
  home << 0.0, 1.26, -0.57, -1.38, 0.68, -0.82, 1.68;
  hk::Arm7Vector mirror;
  mirror << -1, 1, -1, 1, -1, 1, -1;
  model_.arms[idx(Side::kRight)].rest_q = mirror.cwiseProduct(home);
  model_.arms[idx(Side::kLeft)].rest_q = home;
  const int top = id_of(m, mjOBJ_GEOM, "bench_top");
  const double* tp = d->geom_xpos + 3 * top;
  const double* ts = m->geom_size + 3 * top;
  model_.bench.top_z = (T_A_W * Eigen::Vector3d(tp[0], tp[1], tp[2])).z() + ts[2];
  model_.bench.min_xy = (T_A_W * Eigen::Vector3d(tp[0] - ts[0], tp[1] - ts[1], 0.0)).head<2>();
  model_.bench.max_xy = (T_A_W * Eigen::Vector3d(tp[0] + ts[0], tp[1] + ts[1], 0.0)).head<2>();
  model_.gravity_A = T_A_W.linear() * Eigen::Vector3d(m->opt.gravity[0], m->opt.gravity[1], m->opt.gravity[2]);
  if (auto e = validate(model_)) throw std::runtime_error("workbench scene: " + *e);
  reset({model_.arms[0].rest_q, model_.arms[1].rest_q});
}

WorkbenchSim::~WorkbenchSim() = default;

double WorkbenchSim::timestep_s() const noexcept { return impl_->m->opt.timestep; }
double WorkbenchSim::time_s() const noexcept { return impl_->d->time; }
mjModel_* WorkbenchSim::m() const noexcept { return impl_->m.get(); }
mjData_* WorkbenchSim::d() const noexcept { return impl_->d.get(); }

void WorkbenchSim::reset(const std::array<hk::Arm7Vector, kArms>& q, const std::array<double, kArms>& finger_m) {
  mjModel* m = impl_->m.get();
  mjData* d = impl_->d.get();
  mj_resetData(m, d);
  for (int s = 0; s < kArms; ++s) {
    const auto k = static_cast<std::size_t>(s);
    const Impl::Arm& a = impl_->arm[k];
    for (int i = 0; i < hk::kArm7Dof; ++i) d->qpos[a.qpos[static_cast<std::size_t>(i)]] = q[k](i);
    for (int f = 0; f < 2; ++f) d->qpos[a.finger_qpos[static_cast<std::size_t>(f)]] = finger_m[k];
  }
  mj_forward(m, d);
}

ArmReading WorkbenchSim::reading(Side s) const noexcept {
  const mjData* d = impl_->d.get();
  const Impl::Arm& a = impl_->arm[idx(s)];
  ArmReading r;
  for (int i = 0; i < hk::kArm7Dof; ++i) {
    const auto k = static_cast<std::size_t>(i);
    r.q(i) = d->qpos[a.qpos[k]];
    r.qd(i) = d->qvel[a.dof[k]];
  }
  // MuJoCo's force/torque sensors: the wrench the parent (link 7) exerts on
  // the site's body (the gripper), about the site, in its frame (= J7).
  for (int c = 0; c < 3; ++c) {
    r.ft_J7(c) = d->sensordata[a.ft_force + c];
    r.ft_J7(3 + c) = d->sensordata[a.ft_torque + c];
  }
  for (std::size_t f = 0; f < 2; ++f) {
    r.gripper.finger_m[f] = d->qpos[a.finger_qpos[f]];
    r.gripper.finger_mps[f] = d->qvel[a.finger_dof[f]];
    r.gripper.pad_force_N[f] = d->sensordata[a.pad[f]];
  }
  return r;
}

void WorkbenchSim::set_command(Side s, const ArmCommand& c) noexcept {
  mjData* d = impl_->d.get();
  const Impl::Arm& a = impl_->arm[idx(s)];
  for (int i = 0; i < hk::kArm7Dof; ++i) {
    const double t = c.tau(i);
    d->ctrl[a.motor[static_cast<std::size_t>(i)]] = std::isfinite(t) ? t : 0.0;
  }
  for (std::size_t f = 0; f < 2; ++f) {
    const double t = c.finger_force_N[f];
    d->ctrl[a.finger_motor[f]] = std::isfinite(t) ? t : 0.0;
  }
}

void WorkbenchSim::step() noexcept { mj_step(impl_->m.get(), impl_->d.get()); }

Eigen::Isometry3d WorkbenchSim::body_pose_A(const std::string& body) const {
  const mjModel* m = impl_->m.get();
  const mjData* d = impl_->d.get();
  const int b = mj_name2id(m, mjOBJ_BODY, body.c_str());
  if (b < 0) throw std::invalid_argument("no body " + body);
  const Eigen::Isometry3d T_W_A = sim::mujoco_pose(d->xpos + 3 * impl_->torso, d->xmat + 9 * impl_->torso);
  return T_W_A.inverse() * sim::mujoco_pose(d->xpos + 3 * b, d->xmat + 9 * b);
}

Eigen::Isometry3d WorkbenchSim::grasp_site_A(Side s) const noexcept {
  const mjData* d = impl_->d.get();
  const int g = impl_->arm[idx(s)].grasp_site;
  const Eigen::Isometry3d T_W_A = sim::mujoco_pose(d->xpos + 3 * impl_->torso, d->xmat + 9 * impl_->torso);
  return T_W_A.inverse() * sim::mujoco_pose(d->site_xpos + 3 * g, d->site_xmat + 9 * g);
}

}  // namespace hemm::twoarm
