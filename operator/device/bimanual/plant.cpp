#include "operator/device/bimanual/plant.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include <mujoco/mujoco.h>

#include "common/sim/mujoco_owner.h"
#include "operator/device/bimanual/scene.h"

namespace hemm::device::bimanual {

namespace hk = hemm::kinematics;

ActuatorModel lwr_actuators(const hk::Arm7Model& arm) {
  ActuatorModel a;
  a.coulomb_friction << 0.8, 0.8, 0.5, 0.5, 0.3, 0.15, 0.15;
  a.viscous_friction << 0.3, 0.3, 0.2, 0.2, 0.1, 0.05, 0.05;
  a.ripple_fraction = 0.02;
  a.cogging_torque << 0.3, 0.3, 0.15, 0.15, 0.15, 0.05, 0.05;
  a.gear_ratio = 160.0;
  a.brake_torque = 0.8 * arm.tau_max;
  a.brake_delay_s = 0.015;
  return a;
}

ActuatorModel ideal_actuators(const hk::Arm7Model& arm) {
  ActuatorModel a = lwr_actuators(arm);
  a.coulomb_friction.setZero();
  a.viscous_friction.setZero();
  a.ripple_fraction = 0.0;
  a.cogging_torque.setZero();
  return a;
}

hk::Arm7Model perturbed(const hk::Arm7Model& nominal, const ModelError& e, std::uint64_t stream) {
  hk::Arm7Model m = nominal;
  std::mt19937_64 rng(e.seed * 1000003u + stream);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& l : m.link) {
    const double sm = 1.0 + e.mass * u(rng);
    const double si = 1.0 + e.inertia * u(rng);
    const Eigen::Vector3d dc(u(rng), u(rng), u(rng));
    l.mass *= sm;
    l.inertia *= si;
    l.com += e.com_m * dc.normalized();
  }
  for (int i = 0; i < hk::kArm7Dof; ++i) m.armature(i) *= 1.0 + e.inertia * u(rng);
  return m;
}

std::optional<std::string> validate(const PlantConfig& c) {
  if (auto e = validate(c.rig)) return "rig: " + *e;
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    if (auto e = validate(handle_spec(c.handles[k]))) return "handle: " + *e;
    if (auto e = validate(c.humans[k])) return "human: " + *e;
  }
  const ActuatorModel& a = c.actuators;
  for (const hk::Arm7Vector* v : {&a.coulomb_friction, &a.viscous_friction, &a.cogging_torque, &a.brake_torque}) {
    if (!v->allFinite() || (v->array() < 0.0).any()) return "actuator friction, cogging and brake torques must be >= 0";
  }
  if (!(a.ripple_fraction >= 0.0 && a.ripple_fraction < 0.5)) return "ripple_fraction must be in [0, 0.5)";
  if (!(a.gear_ratio > 0.0 && std::isfinite(a.gear_ratio))) return "gear_ratio must be > 0";
  if (!(a.brake_delay_s >= 0.0 && a.brake_delay_s < 1.0)) return "brake_delay_s must be in [0, 1) s";
  const ModelError& m = c.model_error;
  if (!(m.mass >= 0 && m.mass < 0.5 && m.inertia >= 0 && m.inertia < 0.5 && m.com_m >= 0 && m.com_m < 0.05))
    return "model errors must be in [0, 0.5) (relative) and [0, 0.05) m";
  const SensorNoise& n = c.noise;
  if (!(n.ft_force_N >= 0 && n.ft_torque_Nm >= 0 && n.joint_torque_Nm >= 0 && std::isfinite(n.ft_force_N) &&
        std::isfinite(n.ft_torque_Nm) && std::isfinite(n.joint_torque_Nm)))
    return "sensor noise must be finite and >= 0";
  if (!(c.control_period_s > 0.0 && c.control_period_s <= 0.01)) return "control_period_s must be in (0, 0.01] s";
  if (c.substeps < 1 || c.substeps > 100) return "substeps must be in [1, 100]";
  if (!(c.proximity_margin_m > 0.0 && c.proximity_margin_m <= 1.0)) return "proximity_margin_m must be in (0, 1] m";
  return std::nullopt;
}

namespace {

int id_of(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw std::runtime_error("BimanualPlant: scene lacks " + name);
  return id;
}

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

Eigen::Matrix3d mat3(const mjtNum* x) {
  Eigen::Matrix3d R;
  R << x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8];
  return R;
}

constexpr int kOwnerNone = -1, kOwnerStatic = 2;

}  // namespace

struct BimanualPlant::Impl {
  PlantConfig cfg;
  std::array<hk::Arm7Model, kArms> arms;
  std::array<HandleSpec, kArms> handles;
  std::string xml;
  sim::MjModelPtr m;
  sim::MjDataPtr d;

  struct Arm {
    std::array<int, hk::kArm7Dof> qpos{}, dof{};
    int handle_body = -1, hand_body = -1, ee_site = -1;
    int hand_qpos = -1, hand_dof = -1;
    int ft_force = -1, ft_torque = -1;  // sensordata addresses
    int lever_qpos = -1, lever_dof = -1;
    hk::Arm7Vector ripple_phase = hk::Arm7Vector::Zero(), cogging_phase = hk::Arm7Vector::Zero();
    // State.
    ArmActuation act;
    HumanTarget human;
    bool attached = true, grasping = true, powered = true, brakes = false;
    double t_power_off = 0.0;
    hk::Arm7Vector tau_applied = hk::Arm7Vector::Zero();
    Eigen::Vector3d voluntary_D = Eigen::Vector3d::Zero();  // the human's voluntary force (human.h)
    ArmReading reading;
  };
  std::array<Arm, kArms> arm;
  std::vector<int> owner;  // geom -> 0 right arm, 1 left arm, 2 static, -1 none
  PlantTruth truth;
  double t = 0.0;
  double h = 0.0005;
  std::mt19937_64 rng;
  std::normal_distribution<double> normal{0.0, 1.0};

  void build() {
    SceneSpec sp;
    sp.rig = cfg.rig;
    sp.arms = arms;
    sp.handles = handles;
    sp.humans = cfg.humans;
    sp.viscous_friction = cfg.actuators.viscous_friction;
    sp.coulomb_friction = cfg.actuators.coulomb_friction;
    sp.timestep_s = h;
    sp.proximity_margin_m = cfg.proximity_margin_m;
    xml = bimanual_scene_mjcf(sp);
    try {
      m = sim::load_model_xml("bimanual.xml", xml);
      d = sim::make_data(m.get());
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(std::string("BimanualPlant: MuJoCo rejected the scene: ") + e.what());
    }
    owner.assign(static_cast<std::size_t>(m->ngeom), kOwnerNone);
    owner[static_cast<std::size_t>(id_of(m.get(), mjOBJ_GEOM, "table"))] = kOwnerStatic;
    owner[static_cast<std::size_t>(id_of(m.get(), mjOBJ_GEOM, "column"))] = kOwnerStatic;
    std::mt19937_64 phases(cfg.model_error.seed + 99);
    std::uniform_real_distribution<double> ph(0.0, 2.0 * std::numbers::pi);
    for (ArmSide side : {ArmSide::kRight, ArmSide::kLeft}) {
      const int a = index(side);
      Arm& A = arm[static_cast<std::size_t>(a)];
      const std::string p = prefix(side);
      for (int i = 0; i < hk::kArm7Dof; ++i) {
        const int j = id_of(m.get(), mjOBJ_JOINT, p + "j" + std::to_string(i + 1));
        A.qpos[static_cast<std::size_t>(i)] = m->jnt_qposadr[j];
        A.dof[static_cast<std::size_t>(i)] = m->jnt_dofadr[j];
        owner[static_cast<std::size_t>(id_of(m.get(), mjOBJ_GEOM, p + "geom" + std::to_string(i + 1)))] = a;
        A.ripple_phase(i) = ph(phases);
        A.cogging_phase(i) = ph(phases);
      }
      owner[static_cast<std::size_t>(id_of(m.get(), mjOBJ_GEOM, p + "handle_geom"))] = a;
      A.handle_body = id_of(m.get(), mjOBJ_BODY, p + "handle");
      A.hand_body = id_of(m.get(), mjOBJ_BODY, p + "hand");
      A.ee_site = id_of(m.get(), mjOBJ_SITE, p + "ee");
      const int hj = id_of(m.get(), mjOBJ_JOINT, p + "hand_free");
      A.hand_qpos = m->jnt_qposadr[hj];
      A.hand_dof = m->jnt_dofadr[hj];
      A.ft_force = m->sensor_adr[id_of(m.get(), mjOBJ_SENSOR, p + "ft_force")];
      A.ft_torque = m->sensor_adr[id_of(m.get(), mjOBJ_SENSOR, p + "ft_torque")];
      if (handles[static_cast<std::size_t>(a)].kind == HandleKind::kGripForce) {
        const int g = id_of(m.get(), mjOBJ_JOINT, p + "grip");
        A.lever_qpos = m->jnt_qposadr[g];
        A.lever_dof = m->jnt_dofadr[g];
      }
    }
  }

  void reset(const std::array<hk::Arm7Vector, kArms>& q) {
    mj_resetData(m.get(), d.get());
    for (int a = 0; a < kArms; ++a) {
      Arm& A = arm[static_cast<std::size_t>(a)];
      for (int i = 0; i < hk::kArm7Dof; ++i) d->qpos[A.qpos[static_cast<std::size_t>(i)]] = q[static_cast<std::size_t>(a)](i);
      A.attached = A.grasping = A.powered = true;
      A.brakes = false;
      A.act = ArmActuation{};
      A.tau_applied.setZero();
      A.voluntary_D.setZero();
      for (int i = 0; i < hk::kArm7Dof; ++i)
        m->dof_frictionloss[A.dof[static_cast<std::size_t>(i)]] = cfg.actuators.coulomb_friction(i);
    }
    mj_forward(m.get(), d.get());
    // Each hand on its handle's end-effector frame.
    for (int a = 0; a < kArms; ++a) {
      Arm& A = arm[static_cast<std::size_t>(a)];
      const mjtNum* p = d->site_xpos + 3 * A.ee_site;
      const Eigen::Quaterniond qe(mat3(d->site_xmat + 9 * A.ee_site));
      mjtNum* hq = d->qpos + A.hand_qpos;
      hq[0] = p[0];
      hq[1] = p[1];
      hq[2] = p[2];
      hq[3] = qe.w();
      hq[4] = qe.x();
      hq[5] = qe.y();
      hq[6] = qe.z();
      A.human = HumanTarget{};
      A.human.position_D = Eigen::Vector3d(p[0], p[1], p[2]);
      A.human.orientation_D = qe;
    }
    mj_forward(m.get(), d.get());
    t = 0.0;
    truth = PlantTruth{};
    update_outputs(false);
  }

  Eigen::Matrix<double, 6, 1> velocity(mjtObj type, int id) const {
    mjtNum v[6];
    mj_objectVelocity(m.get(), d.get(), type, id, v, 0);
    Eigen::Matrix<double, 6, 1> out;  // linear, angular
    out << v[3], v[4], v[5], v[0], v[1], v[2];
    return out;
  }

  void substep(double& min_aa, double& min_at, bool& touch_aa, bool& touch_at) {
    mj_step1(m.get(), d.get());
    for (int i = 0; i < d->ncon; ++i) {
      const mjContact& c = d->contact[i];
      const int o1 = owner[static_cast<std::size_t>(c.geom1)], o2 = owner[static_cast<std::size_t>(c.geom2)];
      if (o1 == kOwnerNone || o2 == kOwnerNone || o1 == o2) continue;
      if (o1 != kOwnerStatic && o2 != kOwnerStatic) {
        min_aa = std::min(min_aa, static_cast<double>(c.dist));
        touch_aa = touch_aa || c.dist < 0.0;
      } else {
        min_at = std::min(min_at, static_cast<double>(c.dist));
        touch_at = touch_at || c.dist < 0.0;
      }
    }
    mju_zero(d->xfrc_applied, 6 * m->nbody);
    mju_zero(d->qfrc_applied, m->nv);
    for (int a = 0; a < kArms; ++a) arm_forces(a);
    mj_step2(m.get(), d.get());
    t += h;
  }

  void arm_forces(int a) {
    Arm& A = arm[static_cast<std::size_t>(a)];
    const HandleSpec& hs = handles[static_cast<std::size_t>(a)];
    const HumanModel& hm = cfg.humans[static_cast<std::size_t>(a)];
    HandTruth& ht = truth.hands[static_cast<std::size_t>(a)];
    // --- the human: hand on the handle, arm towards the target.
    const Eigen::Vector3d p_h(d->xpos + 3 * A.hand_body);
    const Eigen::Matrix3d R_h = mat3(d->xmat + 9 * A.hand_body);
    const Eigen::Vector3d p_E(d->site_xpos + 3 * A.ee_site);
    const Eigen::Matrix3d R_E = mat3(d->site_xmat + 9 * A.ee_site);
    const auto v_h = velocity(mjOBJ_BODY, A.hand_body);
    const auto v_E = velocity(mjOBJ_SITE, A.ee_site);
    // Letting go / taking hold again (the clutch only re-attaches by reset).
    if (!A.human.grasp) {
      A.grasping = false;
    } else if (!A.grasping && (hs.kind != HandleKind::kMagneticClutch || A.attached) && (p_E - p_h).norm() < 0.02 &&
               rotation_vector(R_E * R_h.transpose()).norm() < 0.2) {
      A.grasping = true;
    }
    Eigen::Vector3d F = Eigen::Vector3d::Zero(), T = Eigen::Vector3d::Zero();  // handle -> hand
    const bool coupled = A.grasping && A.attached;
    if (coupled) {
      F = hm.grasp_stiffness * (p_E - p_h) + hm.grasp_damping * (v_E.head<3>() - v_h.head<3>());
      T = hm.grasp_rot_stiffness * rotation_vector(R_E * R_h.transpose()) +
          hm.grasp_rot_damping * (v_E.tail<3>() - v_h.tail<3>());
      if (hs.kind == HandleKind::kMagneticClutch &&
          (F.norm() > hs.clutch_force_limit || T.norm() > hs.clutch_torque_limit)) {
        A.attached = false;  // the bracket comes off the flange with the hand
        F.setZero();
        T.setZero();
      }
    }
    const HumanTarget& g = A.human;
    // Voluntary effort while holding on: integral of the error, clamped.
    if (A.grasping && hm.max_voluntary_force > 0.0) {
      A.voluntary_D += hm.voluntary_gain * h * (g.position_D - p_h);
      const double n = A.voluntary_D.norm();
      if (n > hm.max_voluntary_force) A.voluntary_D *= hm.max_voluntary_force / n;
    } else {
      A.voluntary_D.setZero();
    }
    Eigen::Vector3d F_arm = hm.arm_stiffness * (g.position_D - p_h) - hm.arm_damping * v_h.head<3>() + g.push_force_D +
                            A.voluntary_D;
    if (hm.carries_own_weight) F_arm -= hm.hand_mass * cfg.rig.gravity_D;
    const Eigen::Vector3d T_arm = hm.arm_rot_stiffness * rotation_vector(g.orientation_D.toRotationMatrix() * R_h.transpose()) -
                                  hm.arm_rot_damping * v_h.tail<3>() + g.push_torque_D;
    mjtNum* xh = d->xfrc_applied + 6 * A.hand_body;
    mjtNum* xd = d->xfrc_applied + 6 * A.handle_body;
    const Eigen::Vector3d c_handle(d->xipos + 3 * A.handle_body);
    const Eigen::Vector3d T_on_handle = -T + (p_E - c_handle).cross(-F);
    for (int k = 0; k < 3; ++k) {
      xh[k] = F(k) + F_arm(k);
      xh[3 + k] = T(k) + T_arm(k);
      xd[k] = -F(k);
      xd[3 + k] = T_on_handle(k);
    }
    ht.grasp_force_D = F;
    ht.grasp_torque_D = T;
    ht.grasping = coupled;
    // --- dead-man interlock, power and brakes.
    bool deadman = true;
    if (hs.kind == HandleKind::kMagneticClutch) deadman = A.attached;
    if (hs.kind == HandleKind::kJoystick) deadman = g.deadman && A.grasping;
    const bool powered = A.act.power && deadman;
    if (A.powered && !powered) A.t_power_off = t;
    A.powered = powered;
    const bool brakes = !powered && t - A.t_power_off >= cfg.actuators.brake_delay_s - 1e-12;
    if (brakes != A.brakes) {
      for (int i = 0; i < hk::kArm7Dof; ++i)
        m->dof_frictionloss[A.dof[static_cast<std::size_t>(i)]] =
            brakes ? cfg.actuators.brake_torque(i) : cfg.actuators.coulomb_friction(i);
      A.brakes = brakes;
    }
    A.reading.deadman_closed = deadman;
    // --- joint torques: ripple, saturation.
    const hk::Arm7Model& am = arms[static_cast<std::size_t>(a)];
    const ActuatorModel& ac = cfg.actuators;
    for (int i = 0; i < hk::kArm7Dof; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const double q = d->qpos[A.qpos[k]];
      double tau = 0.0;
      if (powered) {
        const double cmd = std::isfinite(A.act.tau(i)) ? A.act.tau(i) : 0.0;
        tau = cmd * (1.0 + ac.ripple_fraction * std::sin(2.0 * ac.gear_ratio * q + A.ripple_phase(i))) +
              ac.cogging_torque(i) * std::sin(ac.gear_ratio * q + A.cogging_phase(i));
        tau = std::clamp(tau, -am.tau_max(i), am.tau_max(i));
      }
      A.tau_applied(i) = tau;
      d->qfrc_applied[A.dof[k]] = tau;
    }
    // --- the grip lever: forefinger against the rendered grip force.
    if (A.lever_dof >= 0) {
      const double x = d->qpos[A.lever_qpos], xd_ = d->qvel[A.lever_dof];
      double f = 0.0;
      if (A.grasping) f += hm.finger_stiffness * (g.finger_position - x) - hm.finger_damping * xd_;
      if (powered && std::isfinite(A.act.grip_force)) f -= std::clamp(A.act.grip_force, 0.0, hs.grip_max_force);
      d->qfrc_applied[A.lever_dof] = f;
    }
  }

  void update_outputs(bool noisy) {
    for (int a = 0; a < kArms; ++a) {
      Arm& A = arm[static_cast<std::size_t>(a)];
      ArmReading& r = A.reading;
      for (int i = 0; i < hk::kArm7Dof; ++i) {
        const auto k = static_cast<std::size_t>(i);
        r.q(i) = d->qpos[A.qpos[k]];
        r.qd(i) = d->qvel[A.dof[k]];
        r.tau_J(i) = A.tau_applied(i) + d->qfrc_passive[A.dof[k]];
      }
      // Coulomb friction and brakes: the friction-loss constraint rows.
      for (int e = 0; e < d->nefc; ++e) {
        if (d->efc_type[e] != mjCNSTR_FRICTION_DOF) continue;
        for (int i = 0; i < hk::kArm7Dof; ++i) {
          if (d->efc_id[e] == A.dof[static_cast<std::size_t>(i)]) r.tau_J(i) += d->efc_force[e];
        }
      }
      // MuJoCo's force/torque sensors give the flange's action on the handle
      // (site frame = J7 axes): the handle's action on the flange is minus that.
      for (int k = 0; k < 3; ++k) {
        r.ft_J7(k) = -d->sensordata[A.ft_force + k];
        r.ft_J7(3 + k) = -d->sensordata[A.ft_torque + k];
      }
      if (noisy) {
        for (int k = 0; k < 3; ++k) {
          r.ft_J7(k) += cfg.noise.ft_force_N * normal(rng);
          r.ft_J7(3 + k) += cfg.noise.ft_torque_Nm * normal(rng);
        }
        for (int i = 0; i < hk::kArm7Dof; ++i) r.tau_J(i) += cfg.noise.joint_torque_Nm * normal(rng);
      }
      if (A.lever_dof >= 0) {
        r.grip_position = d->qpos[A.lever_qpos];
        r.grip_velocity = d->qvel[A.lever_dof];
      }
      const HandleKind kind = handles[static_cast<std::size_t>(a)].kind;
      r.buttons = has_input(kind, HandleInput::kButtons) ? A.human.buttons : 0u;
      r.joystick.setZero();
      if (has_input(kind, HandleInput::kJoystickAxes)) r.joystick = A.human.joystick.cwiseMax(-1.0).cwiseMin(1.0);
      r.switch_on = has_input(kind, HandleInput::kSwitch) && A.human.switch_on;
      r.attached = A.attached;
      r.powered = A.powered;
      r.brakes_engaged = A.brakes;
      // Truth: the hand's free joint.
      HandTruth& ht = truth.hands[static_cast<std::size_t>(a)];
      const mjtNum* hq = d->qpos + A.hand_qpos;
      const mjtNum* hv = d->qvel + A.hand_dof;
      ht.position_D = Eigen::Vector3d(hq[0], hq[1], hq[2]);
      ht.orientation_D = Eigen::Quaterniond(hq[3], hq[4], hq[5], hq[6]).normalized();
      ht.velocity_D = Eigen::Vector3d(hv[0], hv[1], hv[2]);
      ht.angular_velocity_D = ht.orientation_D * Eigen::Vector3d(hv[3], hv[4], hv[5]);  // free joint: local
    }
    truth.t_s = t;
  }
};

BimanualPlant::BimanualPlant(const PlantConfig& config) : impl_(std::make_unique<Impl>()) {
  if (auto e = validate(config)) throw std::invalid_argument("BimanualPlant: " + *e);
  Impl& I = *impl_;
  I.cfg = config;
  I.h = config.control_period_s / config.substeps;
  I.rng.seed(config.noise.seed);
  for (int a = 0; a < kArms; ++a) {
    const auto k = static_cast<std::size_t>(a);
    I.arms[k] = perturbed(config.rig.arm, config.model_error, k);
    HandleSpec h = handle_spec(config.handles[k]);
    std::mt19937_64 rng(config.model_error.seed * 7919u + k);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    h.inertia_J7.mass *= 1.0 + config.model_error.mass * u(rng);
    h.inertia_J7.inertia *= 1.0 + config.model_error.inertia * u(rng);
    I.handles[k] = h;
  }
  I.build();
  I.reset({config.rig.home(ArmSide::kRight), config.rig.home(ArmSide::kLeft)});
}

BimanualPlant::~BimanualPlant() = default;

void BimanualPlant::step(const std::array<ArmActuation, kArms>& act, const std::array<HumanTarget, kArms>& human) noexcept {
  Impl& I = *impl_;
  for (int a = 0; a < kArms; ++a) {
    I.arm[static_cast<std::size_t>(a)].act = act[static_cast<std::size_t>(a)];
    I.arm[static_cast<std::size_t>(a)].human = human[static_cast<std::size_t>(a)];
  }
  double min_aa = std::numeric_limits<double>::infinity(), min_at = min_aa;
  for (int s = 0; s < I.cfg.substeps; ++s) {
    bool touch_aa = false, touch_at = false;
    I.substep(min_aa, min_at, touch_aa, touch_at);
    I.truth.arm_arm_contact_steps += touch_aa;
    I.truth.arm_table_contact_steps += touch_at;
  }
  I.truth.min_arm_arm_m = min_aa;
  I.truth.min_arm_table_m = min_at;
  I.update_outputs(true);
}

const ArmReading& BimanualPlant::reading(ArmSide s) const noexcept {
  return impl_->arm[static_cast<std::size_t>(index(s))].reading;
}
const PlantTruth& BimanualPlant::truth() const noexcept { return impl_->truth; }
double BimanualPlant::time_s() const noexcept { return impl_->t; }
void BimanualPlant::reset(const std::array<hk::Arm7Vector, kArms>& q) { impl_->reset(q); }
const PlantConfig& BimanualPlant::config() const noexcept { return impl_->cfg; }
const hk::Arm7Model& BimanualPlant::true_arm(ArmSide s) const noexcept {
  return impl_->arms[static_cast<std::size_t>(index(s))];
}
const HandleSpec& BimanualPlant::true_handle(ArmSide s) const noexcept {
  return impl_->handles[static_cast<std::size_t>(index(s))];
}
const std::string& BimanualPlant::scene_xml() const noexcept { return impl_->xml; }

}  // namespace hemm::device::bimanual
