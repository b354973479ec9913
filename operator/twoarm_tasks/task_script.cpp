#include "operator/twoarm_tasks/task_script.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/mapping/depth_stream.h"
#include "robot_side/twoarm/arms_wire.h"
#include "robot_side/twoarm/twoarm_model.h"

namespace hemm::twoarm_tasks {

namespace {

using twoarm::downward_grasp;
using twoarm::GripperTarget;


Eigen::Isometry3d script_blend(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = (1.0 - s) * a.translation() + s * b.translation();
  T.linear() = Eigen::Quaterniond(a.linear()).slerp(s, Eigen::Quaterniond(b.linear())).toRotationMatrix();
  return T;
}

// The grasp frame at p_A from above, turned about the fingers' closing axis
// (y_G, along x_A) by the side's tilt: the fingers still close across x_A.
Eigen::Isometry3d script_grasp(const ScriptParams& p, Side s, const Eigen::Vector3d& p_A) {
  Eigen::Isometry3d T = downward_grasp(p_A);
  T.linear() = T.linear() * Eigen::AngleAxisd(p.tilt_rad[twoarm::idx(s)], Eigen::Vector3d::UnitY()).toRotationMatrix();
  return T;
}

// A step moving one arm to a pose and waiting for it.
ScriptStep script_move(const std::string& name, Side s, const Eigen::Isometry3d& T, double speed = 0.0, double tol = 0.0) {
  ScriptStep st;
  st.name = name;
  st.pose[twoarm::idx(s)] = T;
  st.wait_reach[twoarm::idx(s)] = true;
  st.speed_mps = speed;
  st.tol_m = tol;
  return st;
}

ScriptStep script_grip(const std::string& name, Side s, const GripperTarget& g, bool close) {
  ScriptStep st;
  st.name = name;
  st.grip[twoarm::idx(s)] = g;
  (close ? st.wait_grasped : st.wait_opened)[twoarm::idx(s)] = true;
  return st;
}

// Over the grasp (10 cm above it, the gripper opening), down to it, close:
// the first three steps of every task.
void script_take(TaskScript& t, Side s, const std::string& what, const Eigen::Vector3d& grasp, double open) {
  const std::string who = s == Side::kRight ? "right" : "left";
  ScriptStep above = script_move(who + " over the " + what, s, script_grasp(t.p, s, grasp + Eigen::Vector3d(0, 0, 0.10)));
  above.grip[twoarm::idx(s)] = GripperTarget{open, t.p.grip_force_N};
  t.steps.push_back(above);
  t.steps.push_back(script_move(who + " down to the " + what, s, script_grasp(t.p, s, grasp), t.p.slow_speed_mps));
  t.steps.push_back(script_grip(who + " closes on the " + what, s, {0.0, t.p.grip_force_N}, true));
}

// Moves an arm by `delta` from its target and waits for it.
ScriptStep script_retreat(const std::string& name, Side s, const Eigen::Vector3d& delta) {
  ScriptStep back;
  back.name = name;
  back.delta[twoarm::idx(s)] = delta;
  back.wait_reach[twoarm::idx(s)] = true;
  return back;
}

// A step moving both arms to their grasp frames at the same offsets from
// one point c (both targets move together in A: the hands' relative pose is
// kept while they hold one object).
ScriptStep script_move_both(const std::string& name, const ScriptParams& p, const Eigen::Vector3d& c,
                            const std::array<Eigen::Vector3d, kArms>& off, double speed = 0.0, double tol = 0.0) {
  ScriptStep st;
  st.name = name;
  for (std::size_t a = 0; a < kArms; ++a) {
    st.pose[a] = script_grasp(p, static_cast<Side>(a), c + off[a]);
    st.wait_reach[a] = true;
  }
  st.speed_mps = speed;
  st.tol_m = tol;
  return st;
}

}  // namespace

std::optional<std::string> read_believed(const wire::ArmsState& s, std::array<BelievedArm, kArms>* out) {
  if (auto e = twoarm::check_arms_state(s)) return e;
  if (s.arm_size() != kArms || s.gripper_size() != kArms) return "the believed state has not two arms and two grippers";
  for (const wire::ArmState& a : s.arm()) {
    if (a.index() >= static_cast<uint32_t>(kArms)) return "an arm index beyond the two";
    BelievedArm& b = (*out)[a.index()];
    if (auto e = mapping::pose3_from_wire(a.t_a_g(), &b.T_A_G)) return e;
    b.v_A = Eigen::Vector3d(a.v_a().x(), a.v_a().y(), a.v_a().z());
    b.force_A = Eigen::Vector3d(a.force_a().x(), a.force_a().y(), a.force_a().z());
    b.torque_A = Eigen::Vector3d(a.torque_a().x(), a.torque_a().y(), a.torque_a().z());
  }
  for (const wire::GripperState& g : s.gripper()) {
    if (g.index() >= static_cast<uint32_t>(kArms)) return "a gripper index beyond the two";
    BelievedArm& b = (*out)[g.index()];
    b.opening_m = g.opening_m();
    b.holding = g.holding();
    b.grip_target = {g.target_opening_m(), g.target_force_n()};
  }
  return std::nullopt;
}

TaskScript box_script(const TaskScene& sc, const ScriptParams& params) {
  // The left hand reaches across to the box's and the shelf's right-hand
  // ends: from above it needs its grasp turned further (the inverse
  // kinematics finds none at the peg's -0.7 rad over the shelf).
  ScriptParams p = params;
  p.tilt_rad[1] = std::min(p.tilt_rad[1], -1.0);
  TaskScript t{"box", p, {}};
  const double open = std::min(0.218, sc.box_size.x() + 0.018);  // the gripper opens 0.22 at most
  // Each hand takes one end (along y), across the 0.20 m side, G 4 cm below the top.
  const double g_above_centre = sc.box_size.z() / 2.0 - 0.04;
  const double half_y = sc.box_size.y() / 2.0;
  const std::array<Eigen::Vector3d, kArms> off{Eigen::Vector3d(0, -(half_y - p.box_end_inset_m[0]), g_above_centre),
                                               Eigen::Vector3d(0, half_y - p.box_end_inset_m[1], g_above_centre)};
  const Eigen::Vector3d above(0, 0, 0.10);
  // Carried with its bottom 9 cm over the board (the arms sag under 2 kg).
  const double carry_z = sc.shelf_place.z() + sc.box_size.z() / 2.0 + 0.09;
  ScriptStep over = script_move_both("both over the box's ends", p, sc.box_centre + above, off);
  over.grip = {GripperTarget{open, p.grip_force_N}, GripperTarget{open, p.grip_force_N}};
  t.steps.push_back(over);
  t.steps.push_back(script_move_both("both down to the ends", p, sc.box_centre, off, p.slow_speed_mps));
  ScriptStep close;
  close.name = "both close on the box";
  close.grip = {GripperTarget{0.0, p.grip_force_N}, GripperTarget{0.0, p.grip_force_N}};
  // Slowly (the lever squeezed over ~2 s): at once the pads hit the box at
  // ~0.5 m/s, and a gripper a few millimetres off its centre took the first
  // pad's impact alone, 52-60 N on the wrist (the limit is 40 N).
  close.grip_speed_mps = p.box_grip_speed_mps;
  close.wait_grasped = {true, true};
  t.steps.push_back(close);
  t.steps.push_back(script_move_both("lift the box", p, Eigen::Vector3d(sc.box_centre.x(), sc.box_centre.y(), carry_z), off, 0.0, p.carry_tol_m));
  t.steps.push_back(script_move_both("carry it over the shelf", p, Eigen::Vector3d(sc.shelf_place.x(), sc.shelf_place.y(), carry_z), off, 0.0,
                                     p.carry_tol_m));
  // Set down: over the board (the box's bottom 2 cm above it, within the
  // carrying tolerance: the left, reaching across, stops ~1.5 cm short under
  // the load), then down, guarded, until the board takes the load - where
  // the box sits in the grippers is the grasp's, not the plan's (through the
  // device it slipped 3 cm: a target at the plan's height pressed it on).
  t.steps.push_back(script_move_both("over the board", p, sc.shelf_place + Eigen::Vector3d(0, 0, sc.box_size.z() / 2.0 + 0.02), off,
                                     p.slow_speed_mps, p.carry_tol_m));
  ScriptStep place;
  place.name = "set it on the board (guarded)";
  place.lower_until_unloaded = true;
  place.lower_max_m = 0.08;
  place.dwell_s = 0.3;
  t.steps.push_back(place);
  ScriptStep release;
  release.name = "both let go of the box";
  release.grip = {GripperTarget{open, p.grip_force_N}, GripperTarget{open, p.grip_force_N}};
  release.wait_opened = {true, true};
  t.steps.push_back(release);
  ScriptStep back;
  back.name = "both retreat";
  back.delta = {Eigen::Vector3d(0, 0, 0.12), Eigen::Vector3d(0, 0, 0.12)};
  back.wait_reach = {true, true};
  back.tol_m = p.carry_tol_m;  // the left, reaching across, stops ~1.3 cm short
  t.steps.push_back(back);
  return t;
}

TaskScript peg_script(const TaskScene& sc, const ScriptParams& p) {
  TaskScript t{"peg", p, {}};
  const Side l = Side::kLeft;
  const double open = 2.0 * sc.peg_half_width_m + 0.035;
  const double top = sc.peg_centre.z() + sc.peg_length_m / 2.0;
  const Eigen::Vector3d grasp(sc.peg_centre.x(), sc.peg_centre.y(), top - 0.02);
  const double g_to_end = grasp.z() - (sc.peg_centre.z() - sc.peg_length_m / 2.0);  // G above the peg's end
  const double entry_z = sc.hole_top.z() + g_to_end;
  const double carry_z = entry_z + 0.07;
  script_take(t, l, "peg", grasp, open);
  t.steps.push_back(script_move("lift the peg", l, script_grasp(p, l, Eigen::Vector3d(grasp.x(), grasp.y(), carry_z)), 0.0, 0.01));
  t.steps.push_back(script_move("over the hole", l, script_grasp(p, l, Eigen::Vector3d(sc.hole_top.x(), sc.hole_top.y(), carry_z)), 0.0, 0.01));
  t.steps.push_back(script_move("down to the hole", l, script_grasp(p, l, Eigen::Vector3d(sc.hole_top.x(), sc.hole_top.y(), entry_z + 0.01)),
                                p.slow_speed_mps, 0.004));
  ScriptStep ins;
  ins.name = "insert (guarded)";
  ins.insert_arm = 1;
  ins.entry_z = entry_z;
  ins.bottom_z = entry_z - (sc.hole_depth_m - 0.005);
  ins.pose[1] = script_grasp(p, l, Eigen::Vector3d(sc.hole_top.x(), sc.hole_top.y(), ins.bottom_z));
  t.steps.push_back(ins);
  t.steps.push_back(script_grip("let go of the peg", l, {open, p.grip_force_N}, false));
  t.steps.push_back(script_retreat("retreat", l, Eigen::Vector3d(0, 0, 0.10)));
  return t;
}

TaskScript bar_script(const TaskScene& sc, const ScriptParams& params) {
  // The hand-over pose, near the middle, asks more of the right wrist: its
  // grasp is turned further (at the box's 0.5 rad it stops 0.4 rad short at j6).
  ScriptParams p = params;
  p.tilt_rad[0] = std::max(p.tilt_rad[0], 0.9);
  TaskScript t{"bar", p, {}};
  const Side r = Side::kRight, l = Side::kLeft;
  const double open = 2.0 * sc.bar_radius_m + 0.04;
  // The left takes the bar at its middle, so that it hangs level from it (the
  // pads' torsional friction would let it turn about the fingers' axis
  // under its weight's moment); the right then takes it 0.12 m to the right.
  const Eigen::Vector3d left_grasp = sc.bar_centre;
  // The hand-over pose: the bar 12 cm up, 5 cm nearer the bench's middle.
  const Eigen::Vector3d left_handover = left_grasp + Eigen::Vector3d(0.05, 0, 0.12);
  script_take(t, l, "bar", left_grasp, open);
  t.steps.push_back(script_move("left lifts it to the middle", l, script_grasp(p, l, left_handover), 0.0, 0.01));
  // The right's grasp 0.12 m to the right of where the left is believed to be.
  ScriptStep r_above = script_move("right over the bar", r, script_grasp(p, r, Eigen::Vector3d(0, -0.12, 0.10)));
  r_above.from_other[0] = true;
  r_above.grip[0] = GripperTarget{open, p.grip_force_N};
  t.steps.push_back(r_above);
  ScriptStep r_down = script_move("right down to the bar", r, script_grasp(p, r, Eigen::Vector3d(0, -0.12, 0.0)), p.slow_speed_mps);
  r_down.from_other[0] = true;
  t.steps.push_back(r_down);
  t.steps.push_back(script_grip("right closes on the bar", r, {0.0, p.grip_force_N}, true));
  t.steps.push_back(script_grip("left lets go", l, {open, p.grip_force_N}, false));
  t.steps.push_back(script_retreat("left retreats", l, Eigen::Vector3d(0, 0.05, 0.10)));
  ScriptStep hold;
  hold.name = "right holds the bar";
  hold.dwell_s = 1.0;
  t.steps.push_back(hold);
  return t;
}

ScriptOutput script_step(const TaskScript& sc, ScriptState& st, const wire::ArmsState* believed, double t) {
  ScriptOutput out;
  if (believed == nullptr && !st.started) return out;
  std::array<BelievedArm, kArms> b;
  bool have = false;
  if (believed != nullptr) {
    if (auto e = read_believed(*believed, &b)) {
      st.error = *e;  // hold: nothing it cannot read moves the plan on
    } else {
      have = true;
    }
  }
  if (!st.started) {
    if (!have) return out;
    st.started = true;
    st.start_t = t;
    for (std::size_t a = 0; a < kArms; ++a) {
      st.targets.T_A_G[a] = b[a].T_A_G;
      st.targets.gripper[a] = b[a].grip_target;
      st.from[a] = st.to[a] = b[a].T_A_G;
    }
  }
  const ScriptParams& p = sc.p;
  out.send = true;
  out.deadman = t - st.start_t >= p.deadman_delay_s;
  if (!out.deadman || st.step >= sc.steps.size()) {
    out.targets = st.targets;
    return out;
  }
  const ScriptStep& step = sc.steps[st.step];
  if (!st.step_begun) {
    if (!have) {
      out.targets = st.targets;
      return out;
    }
    st.step_begun = true;
    st.step_t0 = t;
    st.move_s = 0.0;
    const double speed = step.speed_mps > 0.0 ? step.speed_mps : p.speed_mps;
    for (std::size_t a = 0; a < kArms; ++a) {
      st.from[a] = st.targets.T_A_G[a];
      st.to[a] = st.targets.T_A_G[a];
      if (step.pose[a]) {
        st.to[a] = *step.pose[a];
        if (step.from_other[a]) st.to[a].translation() += b[1 - a].T_A_G.translation();
        // A parallel gripper grasps the same turned half a turn about its
        // approach axis: take the turn nearer to where the arm is (the other
        // may lie beyond a wrist joint's limit).
        const Eigen::Matrix3d flipped = st.to[a].linear() * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        if ((twoarm::rotation_angle(st.from[a].linear(), flipped) < twoarm::rotation_angle(st.from[a].linear(), st.to[a].linear())) != false) st.to[a].linear() = flipped;
      }
      if (step.delta[a]) st.to[a].translation() += *step.delta[a];
      st.grip_from_m[a] = st.targets.gripper[a].opening_m;
      if (step.grip[a]) st.targets.gripper[a] = *step.grip[a];
      if (step.insert_arm == static_cast<int>(a)) continue;  // its own motion
      const double d = (st.to[a].translation() - st.from[a].translation()).norm();
      st.move_s = std::max({st.move_s, d / speed, twoarm::rotation_angle(st.from[a].linear(), st.to[a].linear()) / p.rot_speed_radps});
    }
    st.lower_stopped = false;
    st.lower_dz = 0.0;
    if (step.insert_arm >= 0) {
      st.insert_xy_set = false;
      st.insert = ScriptState::Insert::kDescend;
      st.insert_z = st.insert_z0 = st.from[static_cast<std::size_t>(step.insert_arm)].translation().z();
      st.insert_t0 = t;
    }
  }
  const double in_step = t - st.step_t0;
  const double s = st.move_s > 0.0 ? std::clamp(in_step / st.move_s, 0.0, 1.0) : 1.0;
  for (std::size_t a = 0; a < kArms; ++a) {
    if (step.insert_arm != static_cast<int>(a)) st.targets.T_A_G[a] = script_blend(st.from[a], st.to[a], s);
    if (step.grip[a] && step.grip_speed_mps > 0.0) {
      const double goal = step.grip[a]->opening_m, from = st.grip_from_m[a];
      const double moved = std::min(std::abs(goal - from), step.grip_speed_mps * in_step);
      st.targets.gripper[a].opening_m = from + std::copysign(moved, goal - from);
    }
  }
  bool confirmed = s >= 1.0 && in_step >= step.dwell_s && have;
  const double tol = step.tol_m > 0.0 ? step.tol_m : p.pos_tol_m;
  for (std::size_t a = 0; a < kArms; ++a) {
    const bool waits = step.wait_reach[a] && have;
    st.wait_pos_m[a] = waits ? (b[a].T_A_G.translation() - st.to[a].translation()).norm() : 0.0;
    st.wait_rot_rad[a] = waits ? twoarm::rotation_angle(b[a].T_A_G.linear(), st.to[a].linear()) : 0.0;
    st.wait_speed_mps[a] = waits ? b[a].v_A.norm() : 0.0;
  }
  for (std::size_t a = 0; a < kArms && confirmed; ++a) {
    if (step.wait_reach[a]) {
      confirmed = st.wait_pos_m[a] <= tol && st.wait_rot_rad[a] <= p.rot_tol_rad && st.wait_speed_mps[a] <= p.settle_speed_mps;
    }
    if (confirmed && step.wait_grasped[a]) confirmed = b[a].holding;
    if (confirmed && step.wait_opened[a]) {
      confirmed = !b[a].holding && b[a].opening_m >= st.targets.gripper[a].opening_m - p.open_tol_m;
    }
    // The weight off the wrist (vertical: two hands on one box also squeeze it sideways).
    if (confirmed && step.wait_unloaded[a]) confirmed = std::abs(b[a].force_A.z()) <= p.unloaded_N;
  }
  if (step.insert_arm >= 0) {
    // The guarded insertion: the target's height and, when stuck, a search
    // circle around the hole's axis.
    const auto a = static_cast<std::size_t>(step.insert_arm);
    Eigen::Vector3d xy = st.to[a].translation();
    const double z_seen = b[a].T_A_G.translation().z();
    const bool pressed = have && b[a].force_A.z() > p.contact_N;  // the environment pushes the peg up
    if (st.insert_xy_set && st.insert != ScriptState::Insert::kSearch) xy.head<2>() = st.insert_xy;
    switch (st.insert) {
      case ScriptState::Insert::kDescend:
        st.insert_z = std::max(step.bottom_z, st.insert_z0 - p.insert_speed_mps * (t - st.insert_t0));
        if (pressed && b[a].v_A.norm() < p.settle_speed_mps) {
          if (z_seen < step.entry_z - p.min_depth_m) {
            st.insert = ScriptState::Insert::kIn;  // on the hole's bottom already
          } else {
            st.insert = ScriptState::Insert::kSearch;  // on the rim: press lightly, search
            st.search_t0 = t;
            st.search_z = z_seen;
            st.insert_z = z_seen - p.press_m;
            ++st.searches;
          }
        }
        break;
      case ScriptState::Insert::kSearch: {
        const double turns = (t - st.search_t0) / p.search_period_s;
        const double r = std::fmod(turns * p.search_pitch_m, p.search_max_m);
        const double phi = 2.0 * std::numbers::pi * turns;
        xy += r * Eigen::Vector3d(std::cos(phi), std::sin(phi), 0.0);
        if (have && z_seen < st.search_z - p.in_margin_m && !pressed) {
          // Dropped in: on down from here, where G was when it dropped (the
          // hole holds the peg there; back on the axis would pull it sideways).
          st.insert = ScriptState::Insert::kDescend;
          st.insert_z0 = st.insert_z = z_seen;
          st.insert_t0 = t;
          st.insert_xy_set = true;
          st.insert_xy = b[a].T_A_G.translation().head<2>();
          xy.head<2>() = st.insert_xy;
        }
        break;
      }
      case ScriptState::Insert::kIn:
        break;
    }
    // Done: at the bottom target, or pressed at least min_depth in.
    confirmed = have && b[a].v_A.norm() <= p.settle_speed_mps &&
                ((st.insert_z <= step.bottom_z && std::abs(z_seen - step.bottom_z) <= p.pos_tol_m) ||
                 st.insert == ScriptState::Insert::kIn);
    st.targets.T_A_G[a] = st.to[a];
    st.targets.T_A_G[a].translation() = Eigen::Vector3d(xy.x(), xy.y(), st.insert_z);
  }
  if (step.lower_until_unloaded) {
    // Both down together from the step's pose until the support takes the
    // load, then back to where G was believed then (less the press).
    double fz = 0.0, dz_seen = 0.0, v = 0.0;
    for (std::size_t a = 0; a < kArms; ++a) {
      fz += have ? b[a].force_A.z() : 0.0;
      dz_seen += have ? (b[a].T_A_G.translation().z() - st.to[a].translation().z()) / kArms : 0.0;
      v = std::max(v, have ? b[a].v_A.norm() : 0.0);
    }
    const bool unloaded = have && std::abs(fz) <= p.unloaded_N;
    if (!st.lower_stopped) {
      st.lower_dz = -std::min(step.lower_max_m, p.place_speed_mps * in_step);
      if (unloaded) {
        // To where G was believed, less the press: back up when the descent
        // ran on (a round trip late), further down when the arms sag under
        // what they still carry (at 0 ms the targets stayed 4-11 mm above G
        // and the wrists let go of 8 N: the box dropped onto the board, 85 N).
        st.lower_stopped = true;
        st.lower_stop_t = t;
        st.lower_dz = dz_seen - p.place_press_m;
      }
    }
    confirmed = st.lower_stopped && unloaded && v <= p.settle_speed_mps && t - st.lower_stop_t >= step.dwell_s;
    for (std::size_t a = 0; a < kArms; ++a) {
      st.targets.T_A_G[a] = st.to[a];
      st.targets.T_A_G[a].translation().z() += st.lower_dz;
    }
  }
  if (confirmed) {
    st.step_end_t.push_back(t);
    // A slow squeeze confirmed (holding) ends at the step's grip.
    for (std::size_t a = 0; a < kArms; ++a)
      if (step.grip[a]) st.targets.gripper[a] = *step.grip[a];
    ++st.step;
    st.step_begun = false;
    if (st.step >= sc.steps.size()) {
      st.done = true;
      st.done_t = t;
    }
  }
  out.targets = st.targets;
  return out;
}

}  // namespace hemm::twoarm_tasks
