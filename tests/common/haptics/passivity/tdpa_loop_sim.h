#pragma once
// A SIMULATED 1-DoF direct force loop over a SIMULATED delayed, lossy link,
// for the TDPA tests (pure, no sockets, no clock): a human arm (a spring
// and damper pulling a hand-held device towards a scripted reference) on the
// operator end, a robot tracking the velocity it receives with an impedance
// (1 kHz control, the plant integrated at 10 kHz) on the other, touching a
// stiff wall. Each end sends one message per 1 ms tick: velocity or force
// and its TDPA input energy. The link drops, delays (with jitter that
// reorders) and cuts messages on a seeded schedule.
//
// The energies this file asserts on are the test's own: it recomputes each
// port's E_in / E_out from the signals actually applied (the displayed force
// and the hand's velocity; the tracked velocity and the measured force) and
// knows which message, so which sender's E_in, each end had received. The
// code under test only scales the outputs; it cannot mark its own work.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "common/haptics/passivity/tdpa.h"

namespace hemm::tdpa_sim {

struct LoopParams {
  double dt = 1e-3;
  double duration_s = 12.0;
  // Link (each way half the round trip).
  double rtt_s = 0.3;
  double loss = 0.0;            // per message, independent
  int jitter_ticks = 0;         // extra delay 0..jitter ticks per message (reorders)
  double outage_start_s = -1;   // all messages sent in [start, start + length) are lost
  double outage_s = 0.0;
  std::uint32_t seed = 1;
  // The robot end holds still (tracks zero velocity) when its newest
  // command was sent longer ago than this, as the station's watchdog does;
  // holding the last velocity through an outage would carry the arm on.
  double robot_stale_s = 0.05;
  // SIMULATED operator: device + hand mass, the arm's spring and damper.
  double m_hand = 0.5, k_hand = 200.0, b_hand = 10.0;
  // The reference: approach at approach_speed to push_depth beyond the wall,
  // hold, go back to 0; repeated every cycle_s.
  double approach_speed = 0.1, push_depth = 0.05, hold_s = 3.0, cycle_s = 6.0;
  // SIMULATED robot: mass, the impedance tracking its target (hemm's arm
  // defaults and form: a spring to the target, damping of the robot's own
  // velocity, u = k (x_target - x) - b v).
  double m_robot = 2.0, k_track = 1000.0, b_track = 60.0;
  // What the robot end returns and observes as its port's force: the
  // contact force its wrist sensor measures (the direct mode of issue 25;
  // default), or its impedance's spring force (what the arm pushes with).
  // With the contact force the robot's mass and its impedance sit between
  // the observed port and the contact, unseen by the observer; with the
  // spring force the robot end is a passive terminal, but a free-space move
  // needs energy too (docs/telemanipulation_passivity.md, "Results").
  enum class Feedback { kContactForce, kSpringForce };
  Feedback feedback = Feedback::kContactForce;
  // The wall (x >= x_wall); no wall: free space.
  bool wall = true;
  double x_wall = 0.05, k_wall = 5000.0, b_wall = 0.0;
  haptics::tdpa::PcMode mode = haptics::tdpa::PcMode::kControl;
};

struct LoopResult {
  // Truth energies at the end, J.
  double op_in_J = 0, op_out_J = 0, robot_in_J = 0, robot_out_J = 0;
  // max over ticks of E_out(end) - E_in(peer, as that end had received it):
  // <= 0 is the passivity condition.
  double op_violation_J = -1e300, robot_violation_J = -1e300;
  // The operator's output energy in the first and second half of the run.
  double op_out_first_J = 0, op_out_second_J = 0;
  double peak_env_force_N = 0, peak_displayed_N = 0;  // contact force on the robot; shown on the hand
  double max_abs_hand_m = 0, max_abs_robot_m = 0, max_abs_hand_v = 0;
  // Means over the last second of the first hold: where the hand rests (a
  // wall felt stiff stops it near the wall), how far the robot's target is
  // behind it, the force shown on the hand and the contact force.
  double hand_hold_m = 0, target_lag_hold_m = 0, shown_hold_N = 0, contact_hold_N = 0;
  // How much the PCs changed their outputs (0: nothing).
  double max_force_change_N = 0, max_velocity_change = 0;
  std::uint64_t op_pc_ticks = 0, robot_pc_ticks = 0;
  double op_dissipated_J = 0, robot_dissipated_J = 0;
  bool finite = true;
};

inline double sim_reference(const LoopParams& p, double t) {
  const double depth = p.x_wall + p.push_depth;
  const double tc = std::fmod(t, p.cycle_s);
  const double t_in = depth / p.approach_speed;
  if (tc < t_in) return p.approach_speed * tc;
  if (tc < t_in + p.hold_s) return depth;
  return std::max(0.0, depth - p.approach_speed * (tc - t_in - p.hold_s));
}

inline LoopResult run_loop(const LoopParams& p) {
  namespace td = haptics::tdpa;
  using V1 = Eigen::Matrix<double, 1, 1>;
  struct Msg {
    std::uint64_t seq;
    double value;   // velocity (to the robot) or force (to the operator)
    double in_J;    // the sender's TDPA input energy (what the code sends)
  };
  const auto ticks = static_cast<std::int64_t>(std::llround(p.duration_s / p.dt));
  const auto delay = static_cast<std::int64_t>(std::llround(0.5 * p.rtt_s / p.dt));
  const std::int64_t span = ticks + delay + p.jitter_ticks + 3;
  std::vector<std::vector<Msg>> to_robot(static_cast<std::size_t>(span)), to_op(static_cast<std::size_t>(span));
  std::mt19937 rng(p.seed);
  auto uniform = [&rng]() { return static_cast<double>(rng()) / 4294967296.0; };
  // Within a tick the operator end runs first: its message can reach the
  // robot end the same tick (delay 0), the robot's reaches it the next.
  auto send = [&](std::vector<std::vector<Msg>>& q, std::int64_t n, const Msg& m) {
    const double t = static_cast<double>(n) * p.dt;  // n: the tick it may first be read
    const bool outage = p.outage_s > 0 && t >= p.outage_start_s && t < p.outage_start_s + p.outage_s;
    const bool lost = uniform() < p.loss;
    const std::int64_t jitter = p.jitter_ticks > 0 ? static_cast<std::int64_t>(rng() % (p.jitter_ticks + 1)) : 0;
    if (outage || lost) return;
    q[static_cast<std::size_t>(n + delay + jitter)].push_back(m);
  };

  // Truth E_in of each end by tick (what its message of that seq carried in truth).
  std::vector<double> op_in_by_tick(static_cast<std::size_t>(ticks), 0.0), robot_in_by_tick(op_in_by_tick);

  td::Side<1> op, rob;
  double x_h = 0, v_h = 0;                   // hand
  double x_r = 0, v_r = 0, x_target = 0;     // robot, its target
  double f_recv = 0, v_recv = 0;             // newest received (held)
  std::uint64_t v_recv_seq = 0;              // the tick v_recv was sent
  std::uint64_t op_newest = 0, rob_newest = 0;
  bool op_any = false, rob_any = false;
  double op_in = 0, op_out = 0, rob_in = 0, rob_out = 0;  // truth
  std::int64_t op_next = 0, rob_next = 0;                 // next arrival bucket to read
  LoopResult r;
  const int sub = 10;
  for (std::int64_t n = 0; n < ticks; ++n) {
    const double t = static_cast<double>(n) * p.dt;
    // ---- operator end
    for (; op_next <= n; ++op_next) {
      for (const Msg& m : to_op[static_cast<std::size_t>(op_next)]) {
        if (td::receive_peer<1>(op, m.seq, V1(m.in_J)) == td::Receive::kAccepted) f_recv = m.value;
        if (!op_any || m.seq > op_newest) op_newest = m.seq, op_any = true;
      }
    }
    const double f_disp = td::operator_tick<1>(op, V1(f_recv), V1(v_h), p.dt, p.mode)[0];
    {
      const double pw = -f_disp * v_h;
      (pw > 0 ? op_in : op_out) += std::abs(pw) * p.dt;
      if (pw < 0) (n < ticks / 2 ? r.op_out_first_J : r.op_out_second_J) += -pw * p.dt;
      op_in_by_tick[static_cast<std::size_t>(n)] = op_in;
      const double budget = op_any ? robot_in_by_tick[op_newest] : 0.0;
      r.op_violation_J = std::max(r.op_violation_J, op_out - budget);
      r.max_force_change_N = std::max(r.max_force_change_N, std::abs(f_disp - f_recv));
      r.peak_displayed_N = std::max(r.peak_displayed_N, std::abs(f_disp));
    }
    send(to_robot, n, Msg{static_cast<std::uint64_t>(n), v_h, op.in_J[0]});
    {
      const double f_h = p.k_hand * (sim_reference(p, t) - x_h) - p.b_hand * v_h;
      v_h += (f_h + f_disp) / p.m_hand * p.dt;
      x_h += v_h * p.dt;
    }
    // ---- robot end
    for (; rob_next <= n; ++rob_next) {
      for (const Msg& m : to_robot[static_cast<std::size_t>(rob_next)]) {
        if (td::receive_peer<1>(rob, m.seq, V1(m.in_J)) == td::Receive::kAccepted) {
          v_recv = m.value;
          v_recv_seq = m.seq;
        }
        if (!rob_any || m.seq > rob_newest) rob_newest = m.seq, rob_any = true;
      }
    }
    if (static_cast<double>(n - static_cast<std::int64_t>(v_recv_seq)) * p.dt > p.robot_stale_s + p.rtt_s / 2) {
      v_recv = 0.0;
    }
    auto env_force = [&p](double x, double v) {
      if (!p.wall || x < p.x_wall) return 0.0;
      return -p.k_wall * (x - p.x_wall) - p.b_wall * v;
    };
    const double f_contact = env_force(x_r, v_r);
    // The port's force, as the environment's on the robot: minus the spring's pull.
    const double f_env =
        p.feedback == LoopParams::Feedback::kSpringForce ? -p.k_track * (x_target - x_r) : f_contact;
    const double v_s = td::robot_tick<1>(rob, V1(v_recv), V1(f_env), p.dt, p.mode)[0];
    {
      const double pw = f_env * v_s;
      (pw > 0 ? rob_in : rob_out) += std::abs(pw) * p.dt;
      robot_in_by_tick[static_cast<std::size_t>(n)] = rob_in;
      const double budget = rob_any ? op_in_by_tick[rob_newest] : 0.0;
      r.robot_violation_J = std::max(r.robot_violation_J, rob_out - budget);
      r.max_velocity_change = std::max(r.max_velocity_change, std::abs(v_s - v_recv));
      r.peak_env_force_N = std::max(r.peak_env_force_N, std::abs(f_contact));
    }
    send(to_op, n + 1, Msg{static_cast<std::uint64_t>(n), f_env, rob.in_J[0]});
    x_target += v_s * p.dt;
    {
      const double u = p.k_track * (x_target - x_r) - p.b_track * v_r;  // held for the tick
      const double h = p.dt / sub;
      for (int k = 0; k < sub; ++k) {
        v_r += (u + env_force(x_r, v_r)) / p.m_robot * h;
        x_r += v_r * h;
      }
    }
    {
      const double hold_end = (p.x_wall + p.push_depth) / p.approach_speed + p.hold_s;
      if (t >= hold_end - 1.0 && t < hold_end) {
        const double w = p.dt / 1.0;
        r.hand_hold_m += w * x_h;
        r.target_lag_hold_m += w * (x_h - x_target);
        r.shown_hold_N += w * f_disp;
        r.contact_hold_N += w * env_force(x_r, v_r);
      }
    }
    r.max_abs_hand_m = std::max(r.max_abs_hand_m, std::abs(x_h));
    r.max_abs_hand_v = std::max(r.max_abs_hand_v, std::abs(v_h));
    r.max_abs_robot_m = std::max(r.max_abs_robot_m, std::abs(x_r));
    if (!std::isfinite(x_h) || !std::isfinite(x_r)) {
      r.finite = false;
      break;
    }
  }
  r.op_in_J = op_in;
  r.op_out_J = op_out;
  r.robot_in_J = rob_in;
  r.robot_out_J = rob_out;
  r.op_pc_ticks = op.pc_active_ticks;
  r.robot_pc_ticks = rob.pc_active_ticks;
  r.op_dissipated_J = op.dissipated_J[0];
  r.robot_dissipated_J = rob.dissipated_J[0];
  return r;
}

}  // namespace hemm::tdpa_sim
