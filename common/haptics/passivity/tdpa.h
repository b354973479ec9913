#pragma once
// Time-domain passivity approach (TDPA) for the direct force-feedback mode
// (issue 25, part 5; docs/telemanipulation_passivity.md).
//
// The direct mode is a velocity-force (position-force) architecture: the
// operator's end sends the hand's velocity, the robot's end tracks it and
// returns the wrist force it measures, the operator's device displays that
// force. Over a delayed link the channel between the two ends can generate
// energy (a stiff contact felt a round trip late drives an oscillation).
//
// The channel is a two-port with one port at each end. Each end observes the
// power flowing through its own port, sample by sample (the passivity
// observer, Hannaford & Ryu 2002), split into the energy that entered the
// channel there, E_in, and the energy that left it there, E_out. The
// two-port stays passive when each end keeps
//     E_out(this end, now) <= E_in(other end, as last received)
// at every tick (Ryu, Artigas & Preusche 2010: a time delay power network
// split into two one-port conditions that need no knowledge of the delay).
// E_in is cumulative, so each end sends its E_in with every message: a lost
// packet loses nothing (the next one carries the sum), reordering is handled
// by taking the newest sequence number, and during an outage the budget
// simply stops growing, so the output stays within what had arrived.
//
// The passivity controller (PC) at each end dissipates what would break the
// condition:
//   * robot end, admittance type: it scales the velocity the robot tracks
//     (a series damper: v = v_received - beta f, beta >= 0), and
//   * operator end, impedance type: it scales the force the device displays
//     (a parallel damper: f = f_received - alpha v, alpha >= 0),
// each by just enough that this tick's output energy meets the budget
// exactly. Written as a scale r in [0, 1] of the output variable, which is
// the same damper with no division by a small force or velocity: |output|
// never exceeds what was received, and r = 1 (no change) whenever the output
// stays within the budget (free space; a loop passive on its own).
// In kObserveOnly mode the same calls are the passivity observer alone.
//
// Sign conventions, per axis, in the robot's torso frame A on both ends (the
// per-axis split depends on the frame, the sum does not):
//   robot end:    f = the wrench the robot returns, as the environment's on
//                 the gripper (ArmState force_A / torque_A; or its
//                 impedance's spring wrench, which makes the robot end a
//                 passive terminal: docs, "Results"), v = the velocity the
//                 robot tracks; power into the channel  P = f . v
//   operator end: f = the wrench the device applies to the hand,
//                 v = the hand's velocity;  power into the channel P = -f . v
// (the hand does work against the displayed force: P > 0).
//
// Pure and allocation-free: a side's data is a plain struct of fixed-size
// Eigen vectors, updated by free functions. N axes: N = 1 for one degree of
// freedom, N = 6 for an arm (tdpa_arm.h).
#include <cmath>
#include <cstdint>

#include <Eigen/Core>

namespace hemm::haptics::tdpa {

// What a side does with its output: observe only (the baseline without PC:
// the energies are still counted and reported) or observe and control.
enum class PcMode { kObserveOnly, kControl };

// One end's data: its own port's energies per axis, the other end's input
// energy as newest received, and what the PC did.
template <int N>
struct Side {
  using Vec = Eigen::Matrix<double, N, 1>;
  Vec in_J = Vec::Zero();           // entered the channel at this port (send it to the peer)
  Vec out_J = Vec::Zero();          // left the channel at this port; kept <= peer_in_J with the PC
  Vec peer_in_J = Vec::Zero();      // the peer's E_in, newest by sequence number
  Vec dissipated_J = Vec::Zero();   // output energy the PC withheld
  std::uint64_t peer_seq = 0;       // sequence number of the newest accepted peer energy
  bool peer_received = false;       // any accepted yet
  std::uint64_t ticks = 0;
  std::uint64_t pc_active_ticks = 0;  // ticks where the PC scaled some axis
  std::uint64_t peer_refused = 0;     // peer energies refused as bad (not the old ones)
  std::uint64_t peer_old = 0;         // peer energies older than the newest (reordered, duplicated)
};

// Why a peer's energy was or was not taken.
enum class Receive {
  kAccepted,
  kOld,         // a sequence number not newer than the newest taken: ignored
  kNonFinite,   // refused: a non-finite energy
  kNegative,    // refused: E_in is a sum of positive flows
  kDecreasing,  // refused: a newer message with less energy than an older one (a peer reset needs reset())
};
const char* to_string(Receive r) noexcept;

// Takes the peer's cumulative input energy carried by its message `seq`.
// Bad input changes nothing but a counter; an old message changes nothing
// but its counter (it carries less or the same energy).
template <int N>
Receive receive_peer(Side<N>& s, std::uint64_t seq, const Eigen::Matrix<double, N, 1>& peer_in_J) noexcept {
  if (!peer_in_J.allFinite()) {
    ++s.peer_refused;
    return Receive::kNonFinite;
  }
  if ((peer_in_J.array() < 0.0).any()) {
    ++s.peer_refused;
    return Receive::kNegative;
  }
  if (s.peer_received && seq <= s.peer_seq) {
    ++s.peer_old;
    return Receive::kOld;
  }
  if (s.peer_received && (peer_in_J.array() < s.peer_in_J.array()).any()) {
    ++s.peer_refused;
    return Receive::kDecreasing;
  }
  s.peer_in_J = peer_in_J;
  s.peer_seq = seq;
  s.peer_received = true;
  return Receive::kAccepted;
}

// Observer and controller on one axis. power_in_W is the power into the
// channel if the output were applied unchanged. Returns the scale in [0, 1]
// for the output variable; updates the energies with the scaled output.
inline double observe_and_limit(double& in_J, double& out_J, double& dissipated_J, double peer_in_J,
                                double power_in_W, double dt_s, PcMode mode) noexcept {
  if (power_in_W >= 0.0) {
    in_J += power_in_W * dt_s;
    return 1.0;
  }
  const double out_step = -power_in_W * dt_s;  // > 0
  if (mode == PcMode::kObserveOnly || out_J + out_step <= peer_in_J) {
    out_J += out_step;
    return 1.0;
  }
  // The budget left; 0 if the output already reached it (the invariant keeps
  // out_J <= peer_in_J, so this is the energy the peer's last message allows).
  const double allowed = peer_in_J > out_J ? peer_in_J - out_J : 0.0;
  out_J += allowed;
  dissipated_J += out_step - allowed;
  return allowed / out_step;
}

// One tick of a side: `output` is the variable the PC may scale (velocity or
// force), power_in_W per axis the power into the channel if it is applied
// unchanged. Returns the output to apply.
template <int N>
Eigen::Matrix<double, N, 1> limit_output(Side<N>& s, const Eigen::Matrix<double, N, 1>& output,
                                         const Eigen::Matrix<double, N, 1>& power_in_W, double dt_s,
                                         PcMode mode) noexcept {
  Eigen::Matrix<double, N, 1> out = output;
  bool active = false;
  for (int i = 0; i < N; ++i) {
    const double r =
        observe_and_limit(s.in_J[i], s.out_J[i], s.dissipated_J[i], s.peer_in_J[i], power_in_W[i], dt_s, mode);
    if (r < 1.0) {
      out[i] = r * output[i];
      active = true;
    }
  }
  ++s.ticks;
  if (active) ++s.pc_active_ticks;
  return out;
}

// Robot end, one tick: v_received is the velocity the operator sent (newest,
// held between messages), f_env the environment's wrench on the gripper
// measured this tick. Returns the velocity the robot tracks this tick.
template <int N>
Eigen::Matrix<double, N, 1> robot_tick(Side<N>& s, const Eigen::Matrix<double, N, 1>& v_received,
                                       const Eigen::Matrix<double, N, 1>& f_env, double dt_s,
                                       PcMode mode = PcMode::kControl) noexcept {
  return limit_output<N>(s, v_received, f_env.cwiseProduct(v_received), dt_s, mode);
}

// Operator end, one tick: f_received is the robot's measured wrench (newest,
// held between messages) as the device would display it on the hand, v_hand
// the hand's velocity this tick. Returns the wrench to display.
template <int N>
Eigen::Matrix<double, N, 1> operator_tick(Side<N>& s, const Eigen::Matrix<double, N, 1>& f_received,
                                          const Eigen::Matrix<double, N, 1>& v_hand, double dt_s,
                                          PcMode mode = PcMode::kControl) noexcept {
  return limit_output<N>(s, f_received, -f_received.cwiseProduct(v_hand), dt_s, mode);
}

// The passivity margin of a side per axis: the peer's received input energy
// less this port's output energy (>= 0 while the PC controls).
template <int N>
Eigen::Matrix<double, N, 1> margin_J(const Side<N>& s) noexcept {
  return s.peer_in_J - s.out_J;
}

// A new session (the peer restarted its count): both ends start from zero.
template <int N>
void reset(Side<N>& s) noexcept {
  s = Side<N>{};
}

// ----------------------------------------------------------- mode choice
enum class FeedbackMode { kModelMediated, kDirect };
const char* to_string(FeedbackMode m) noexcept;

// When the direct mode (with TDPA) is worth offering; see
// docs/telemanipulation_passivity.md, "Which mode". From the operator's
// config through tdpa_wire.h (thresholds_from, validated there).
struct ModeThresholds {
  // The direct mode shows a contact one round trip after it happens: the hand
  // keeps moving for that long, and the robot's impedance turns the overshoot
  // into force, K_t v RTT. With hemm's arm impedance (1000 N/m), a careful
  // approach of 0.1 m/s and a quarter of the 40 N wrist limit as the most an
  // unfelt contact may build: 10 N / (1000 N/m * 0.1 m/s) = 100 ms.
  double max_direct_rtt_s = 0.100;
  // Loss leaves the passivity guarantee intact (energy is cumulative) but
  // holds a stale force and budget for 1 / (1 - loss) periods on average
  // and bursts for longer; past 10 % the PC dissipates most contact force.
  double max_direct_loss = 0.10;
  // Back to direct only below (1 - hysteresis) of the thresholds, so a link
  // near a threshold does not flip the suggestion at every estimate.
  double hysteresis = 0.2;
};

// The mode to suggest for a measured link (round trip in s, loss as a share
// 0..1), given the mode in use. A non-finite or negative measurement
// suggests the model-mediated mode (it needs nothing of the link).
FeedbackMode suggest_mode(double round_trip_s, double loss, FeedbackMode current, const ModeThresholds& t) noexcept;
inline FeedbackMode suggest_mode(double round_trip_s, double loss) noexcept {
  return suggest_mode(round_trip_s, loss, FeedbackMode::kModelMediated, ModeThresholds{});
}

}  // namespace hemm::haptics::tdpa
