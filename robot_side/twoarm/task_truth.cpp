#include "robot_side/twoarm/task_truth.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <mujoco/mujoco.h>

namespace hemm::twoarm {

namespace {

int truth_id(const mjModel* m, mjtObj type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw std::runtime_error("task truth: the workbench scene lacks " + name);
  return id;
}

bool truth_has(const std::vector<int>& v, int x) noexcept { return std::find(v.begin(), v.end(), x) != v.end(); }

// -1: not a gripper's; else the side whose gripper the body belongs to.
int truth_gripper_of(const TaskTruthModel& tm, int body) noexcept {
  for (int s = 0; s < kArms; ++s) {
    if (truth_has(tm.gripper_bodies[static_cast<std::size_t>(s)], body)) return s;
  }
  return -1;
}

Eigen::Vector3d truth_vec(const mjtNum* p) { return {p[0], p[1], p[2]}; }

}  // namespace

const char* to_string(Task t) {
  switch (t) {
    case Task::kBox: return "box";
    case Task::kPeg: return "peg";
    case Task::kBar: return "bar";
  }
  return "?";
}

std::optional<Task> task_from_string(std::string_view name) {
  for (const Task t : {Task::kBox, Task::kPeg, Task::kBar})
    if (name == to_string(t)) return t;
  return std::nullopt;
}

TaskTruthModel make_task_truth_model(const WorkbenchSim& sim, Task task, const TaskTruthParams& p) {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  TaskTruthModel tm;
  tm.task = task;
  tm.p = p;
  tm.floor_geom = truth_id(m, mjOBJ_GEOM, "floor");
  const int bench_top = truth_id(m, mjOBJ_GEOM, "bench_top");
  for (Side s : {Side::kRight, Side::kLeft}) {
    const std::string pre = prefix(s);
    auto& bodies = tm.gripper_bodies[idx(s)];
    bodies.push_back(truth_id(m, mjOBJ_BODY, pre + "gripper"));
    tm.finger_bodies[idx(s)] = {truth_id(m, mjOBJ_BODY, pre + "finger_a"), truth_id(m, mjOBJ_BODY, pre + "finger_b")};
    bodies.push_back(tm.finger_bodies[idx(s)][0]);
    bodies.push_back(tm.finger_bodies[idx(s)][1]);
    tm.pad_sensor_adr[idx(s)] = {m->sensor_adr[truth_id(m, mjOBJ_SENSOR, pre + "pad_a")],
                                 m->sensor_adr[truth_id(m, mjOBJ_SENSOR, pre + "pad_b")]};
  }
  switch (task) {
    case Task::kBox: {
      tm.object_body = truth_id(m, mjOBJ_BODY, "box");
      tm.start_support_geoms = {bench_top};
      const int board = truth_id(m, mjOBJ_GEOM, "shelf_board");
      tm.goal_support_geoms = {board};
      tm.goal = truth_vec(d->geom_xpos + 3 * board) + Eigen::Vector3d(0.0, 0.0, m->geom_size[3 * board + 2]);
      tm.object_half_height_m = m->geom_size[3 * truth_id(m, mjOBJ_GEOM, "box_geom") + 2];
      break;
    }
    case Task::kPeg: {
      tm.object_body = truth_id(m, mjOBJ_BODY, "peg");
      tm.start_support_geoms = {bench_top};
      const int fixture = truth_id(m, mjOBJ_BODY, "fixture");
      for (int g = 0; g < m->ngeom; ++g) {
        if (m->geom_bodyid[g] == fixture) tm.goal_support_geoms.push_back(g);
      }
      if (tm.goal_support_geoms.empty()) throw std::runtime_error("task truth: the fixture has no geoms");
      tm.goal = truth_vec(d->site_xpos + 3 * truth_id(m, mjOBJ_SITE, "fixture_hole"));
      tm.object_half_height_m = m->geom_size[3 * truth_id(m, mjOBJ_GEOM, "peg_geom") + 2];  // a box: its half length along z
      break;
    }
    case Task::kBar: {
      tm.object_body = truth_id(m, mjOBJ_BODY, "bar");
      tm.start_support_geoms = {bench_top, truth_id(m, mjOBJ_GEOM, "bar_stand_r"), truth_id(m, mjOBJ_GEOM, "bar_stand_l")};
      break;
    }
  }
  return tm;
}

TaskTruthSample task_truth_sample(const TaskTruthModel& tm, const WorkbenchSim& sim) noexcept {
  const mjModel* m = sim.m();
  const mjData* d = sim.d();
  TaskTruthSample s;
  s.t_s = d->time;
  std::array<std::array<bool, 2>, kArms> pad_seen{};
  for (int i = 0; i < d->ncon; ++i) {
    const mjContact& c = d->contact[i];
    if (c.efc_address < 0) continue;  // excluded: no force
    mjtNum f6[6];
    mj_contactForce(m, d, i, f6);
    // The contact frame's rows are the normal (geom1 -> geom2) and two
    // tangents; the force acts on geom2 as +F, on geom1 as -F.
    const Eigen::Vector3d F = f6[0] * truth_vec(c.frame) + f6[1] * truth_vec(c.frame + 3) + f6[2] * truth_vec(c.frame + 6);
    const int g[2] = {c.geom1, c.geom2};
    const int b[2] = {m->geom_bodyid[g[0]], m->geom_bodyid[g[1]]};
    const int grip[2] = {truth_gripper_of(tm, b[0]), truth_gripper_of(tm, b[1])};
    for (int k = 0; k < 2; ++k) {
      if (grip[k] < 0) continue;
      const auto side = static_cast<std::size_t>(grip[k]);
      s.gripper_force_A[side] += k == 1 ? F : Eigen::Vector3d(-F);
      s.gripper_in_contact[side] = true;
    }
    for (int k = 0; k < 2; ++k) {
      if (b[k] != tm.object_body) continue;
      const int og = g[1 - k], ob = b[1 - k];
      if (grip[1 - k] >= 0) {
        const auto side = static_cast<std::size_t>(grip[1 - k]);
        s.finger_on_object[side] = true;
        const auto& fb = tm.finger_bodies[side];
        // A pad counts once, however many contact points it has (a flat on a flat gives several).
        if ((ob == fb[0] || ob == fb[1]) && f6[0] > tm.p.pad_touch_N) pad_seen[side][ob == fb[0] ? 0 : 1] = true;
        continue;
      }
      s.object_env_force_N += f6[0];
      if (og == tm.floor_geom) {
        s.on_floor = true;
      } else if (truth_has(tm.start_support_geoms, og)) {
        s.on_start_support = true;
      } else if (truth_has(tm.goal_support_geoms, og)) {
        s.on_goal_support = true;
      } else {
        s.on_other = true;
      }
    }
  }
  for (std::size_t a = 0; a < kArms; ++a) {
    s.pads_on_object[a] = static_cast<int>(pad_seen[a][0]) + static_cast<int>(pad_seen[a][1]);
    s.hand_squeeze_N[a] = d->sensordata[tm.pad_sensor_adr[a][0]] + d->sensordata[tm.pad_sensor_adr[a][1]];
    s.squeeze_N += s.hand_squeeze_N[a];
  }
  const Eigen::Vector3d pos = truth_vec(d->xpos + 3 * tm.object_body);
  const mjtNum* R = d->xmat + 9 * tm.object_body;
  const Eigen::Vector3d z_obj(R[2], R[5], R[8]);  // the body's z axis in A (= W)
  s.tilt_rad = std::acos(std::clamp(z_obj.z(), -1.0, 1.0));
  const bool any_finger = s.finger_on_object[0] || s.finger_on_object[1];
  switch (tm.task) {
    case Task::kBox:
      s.goal_xy_err_m = (pos - tm.goal).head<2>().norm();
      s.goal_z_err_m = pos.z() - (tm.goal.z() + tm.object_half_height_m);
      s.goal = s.on_goal_support && !s.on_other && !s.on_start_support && !s.on_floor && !any_finger &&
               s.goal_xy_err_m <= tm.p.goal_xy_tol_m && std::abs(s.goal_z_err_m) <= tm.p.goal_z_tol_m &&
               s.tilt_rad <= tm.p.max_tilt_rad;
      break;
    case Task::kPeg: {
      // The peg's lower end; the hole's axis is +z through tm.goal.
      const Eigen::Vector3d tip = pos - tm.object_half_height_m * z_obj;
      s.depth_m = tm.goal.z() - tip.z();
      s.axis_offset_m = (tip - tm.goal).head<2>().norm();
      s.goal = !s.on_floor && s.depth_m >= tm.p.min_insert_depth_m && s.axis_offset_m <= tm.p.max_axis_offset_m &&
               s.tilt_rad <= tm.p.max_tilt_rad;
      break;
    }
    case Task::kBar:
      s.goal = s.pads_on_object[idx(Side::kRight)] == 2 && !s.finger_on_object[idx(Side::kLeft)] && !s.on_start_support &&
               !s.on_goal_support && !s.on_other && !s.on_floor;
      break;
  }
  return s;
}

void task_truth_tick(const TaskTruthModel& tm, const WorkbenchSim& sim, TaskTruthData& data) noexcept {
  const TaskTruthSample s = task_truth_sample(tm, sim);
  ++data.ticks;
  const bool any_finger = s.finger_on_object[0] || s.finger_on_object[1];
  if (!data.lifted && any_finger && !s.on_start_support && !s.on_floor) {
    data.lifted = true;
    data.lift_time_s = s.t_s;
  }
  if (s.on_floor) {
    data.touched_floor = true;
    data.dropped = true;
  }
  if (data.lifted && !any_finger && !s.on_goal_support) {
    if (data.unsupported_since_s < 0.0) data.unsupported_since_s = s.t_s;
    if (s.t_s - data.unsupported_since_s >= tm.p.drop_window_s) data.dropped = true;
  } else {
    data.unsupported_since_s = -1.0;
  }
  if (!s.goal) {
    data.goal_since_s = -1.0;
  } else if (data.goal_since_s < 0.0) {
    data.goal_since_s = s.t_s;
  }
  const bool unsupported = !s.on_start_support && !s.on_goal_support && !s.on_other && !s.on_floor;
  for (std::size_t a = 0; a < kArms; ++a) {
    data.hand_squeeze_peak_N[a] = std::max(data.hand_squeeze_peak_N[a], s.hand_squeeze_N[a]);
    if (unsupported && s.pads_on_object[a] == 2) data.carried[a] = true;
    if (!s.gripper_in_contact[a]) continue;
    const double f = s.gripper_force_A[a].norm();
    if (f > data.wrist_peak_N[a]) {
      data.wrist_peak_N[a] = f;
      data.wrist_peak_t_s[a] = s.t_s;
      data.wrist_peak_force_A[a] = s.gripper_force_A[a];
    }
    data.wrist_sum_sq[a] += f * f;
    ++data.wrist_contact_ticks[a];
  }
  if (s.object_env_force_N > data.object_env_peak_N) {
    data.object_env_peak_N = s.object_env_force_N;
    data.object_env_peak_t_s = s.t_s;
  }
  data.squeeze_peak_N = std::max(data.squeeze_peak_N, s.squeeze_N);
  data.last = s;
}

TaskVerdict task_truth_verdict(const TaskTruthModel& tm, const TaskTruthData& data) {
  TaskVerdict v;
  v.end = data.last;
  v.goal = data.ticks > 0 && data.last.goal;
  v.dropped = data.dropped;
  v.completion_s = v.goal ? data.goal_since_s : -1.0;
  v.wrist_peak_N = data.wrist_peak_N;
  v.wrist_peak_t_s = data.wrist_peak_t_s;
  v.wrist_peak_force_A = data.wrist_peak_force_A;
  v.object_env_peak_t_s = data.object_env_peak_t_s;
  for (std::size_t a = 0; a < kArms; ++a) {
    const long n = data.wrist_contact_ticks[a];
    v.wrist_rms_N[a] = n > 0 ? std::sqrt(data.wrist_sum_sq[a] / static_cast<double>(n)) : 0.0;
  }
  v.object_env_peak_N = data.object_env_peak_N;
  v.squeeze_peak_N = data.squeeze_peak_N;
  v.hand_squeeze_peak_N = data.hand_squeeze_peak_N;
  v.carried = data.carried;
  const int hands = static_cast<int>(data.carried[0]) + static_cast<int>(data.carried[1]);
  const bool hands_ok = tm.task != Task::kBox || hands >= tm.p.box_hands;
  const double wrist_max = tm.p.wrist_force_limit_N + tm.p.wrist_force_margin_N;
  v.forces_ok = data.wrist_peak_N[0] <= wrist_max && data.wrist_peak_N[1] <= wrist_max &&
                data.object_env_peak_N <= tm.p.object_contact_limit_N;
  v.success = v.goal && !v.dropped && v.forces_ok && hands_ok;
  if (!v.goal) v.why += std::string("end condition not met (") + to_string(tm.task) + "); ";
  if (v.dropped) v.why += data.touched_floor ? "dropped (touched the floor); " : "dropped (unsupported after lift-off); ";
  if (!v.forces_ok) v.why += "contact forces beyond the limits; ";
  if (!hands_ok) v.why += "carried by " + std::to_string(hands) + " hand(s), not " + std::to_string(tm.p.box_hands) + "; ";
  return v;
}

}  // namespace hemm::twoarm
