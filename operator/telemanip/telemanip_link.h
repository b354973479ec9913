// Telemanipulation (issue 25, part 2): the operator's network side of the
// two-arm robot (wire.proto ArmsCommand / ArmsState). Runs on the network
// thread (one asio io_context); the servo thread only publishes setpoints
// into a mailbox and reads the remote state from another (newest wins on
// both), so it never touches a socket.
//
//  - Commands: at rate_hz (>= 100) the newest TelemanipSetpoint becomes one
//    ArmsCommand (mode MANIPULATION): each arm whose mapping is initialized
//    with its commanded T_A_G, each gripper the hand commands, and the
//    dead-man pressed only while some arm's is and the setpoint is fresh (a
//    stalled servo thread stops the robot). Nothing is sent while the link is
//    down.
//  - State: each ArmsState is checked (twoarm::check_arms_state: counts,
//    finite values, rigid poses); a malformed one is counted and changes
//    nothing; an older one (a lower datagram sequence) is dropped; the rest
//    go to the servo thread as a RemoteArmsState.
//  - Refusals: the state carries the robot's refusal count (this frame
//    epoch), the newest refusal's reason, sequence and index. Each increase
//    is a new refusal: counted by reason and logged here, once.
#pragma once

#include <asio.hpp>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "common/concurrency/newest_mailbox.h"
#include "operator/telemanip/direct_hand.h"
#include "wire.pb.h"

namespace hemm::net {
class StreamLink;
}

namespace hemm::op::telemanip {

inline constexpr int kTeleArms = 2;  // arm and gripper i: 0 right, 1 left (wire.proto)

// Servo -> network: what one hand asks of its arm.
struct ArmSetpoint {
  bool active = false;   // the mapping is initialized (the robot's G was seen): send T_A_G
  bool pressed = false;  // the hand's dead-man
  Eigen::Vector3d p_A = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_A = Eigen::Quaterniond::Identity();
  bool has_gripper = false;
  double opening_m = 0.0;
  double force_n = 0.0;
  // The direct mode (direct_hand.h): the hand's twist in A is sent in place
  // of the pose, with this end's passivity port (a copy of the servo's).
  bool direct = false;
  tdpa::ArmTwist twist_A;
  tdpa::ArmSide side;
};
struct TelemanipSetpoint {
  std::int64_t t_ns = 0;  // the servo tick's time (steady clock)
  std::uint64_t tick = 0;
  std::array<ArmSetpoint, kTeleArms> arm{};
};

// Network -> servo: the robot's newest state (A).
struct RemoteArm {
  Eigen::Vector3d p_A = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_A = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d force_A = Eigen::Vector3d::Zero();  // the environment's on the gripper, at G
  Eigen::Vector3d torque_A = Eigen::Vector3d::Zero();
  bool force_limited = false;
  DirectPeer direct;  // the direct mode's port and wrench (has_port / has_wrench: the state carried them)
};
struct RemoteGripper {
  double opening_m = 0.0;
  double grip_force_n = 0.0;
  bool holding = false;
};
struct RemoteArmsState {
  bool valid = false;
  std::int64_t stamp_ns = 0;  // robot clock
  std::int64_t recv_ns = 0;   // operator clock at arrival
  std::uint64_t seq = 0;      // datagram sequence
  std::uint64_t frame_epoch = 0;
  std::uint32_t safety = 0;
  std::uint64_t last_command_seq = 0;
  std::array<RemoteArm, kTeleArms> arm{};
  std::array<RemoteGripper, kTeleArms> gripper{};
};

// The robot's refusals of our commands, as seen in its states.
struct ArmsRefusalSummary {
  std::uint64_t refused = 0;  // sum of the count's increases
  std::uint64_t events = 0;   // states that showed an increase
  std::array<std::uint64_t, 8> by_reason{};  // events by ArmsRefusalReason (0..7)
  wire::ArmsRefusalReason last_reason = wire::ARMS_REFUSAL_UNSPECIFIED;
  std::uint64_t last_seq = 0;
  std::uint32_t last_index = 0;
  std::uint64_t errors = 0;  // states with inconsistent refusal fields (ignored)
};
struct ArmsRefusalMonitor {
  std::uint64_t frame_epoch = 0;
  std::uint64_t count = 0;
  ArmsRefusalSummary summary;
};
struct ArmsRefusalEvent {
  wire::ArmsRefusalReason reason = wire::ARMS_REFUSAL_UNSPECIFIED;
  std::uint64_t seq = 0;
  std::uint32_t index = 0;
  std::uint64_t new_refusals = 0;
  std::uint64_t total = 0;
};
// "nonfinite", "unknown_arm", "unknown_gripper", "bad_pose", "out_of_reach",
// "gripper_range", "passivity" ("none" for unspecified, "?" otherwise).
const char* short_name(wire::ArmsRefusalReason r);
// Pure: one state's refusal fields. A count above the one seen in the same
// frame epoch (a new epoch starts from 0) is a new refusal, returned; a lower
// one (reordered) is ignored; a count without a known reason sets *error and
// changes nothing but `errors`.
std::optional<ArmsRefusalEvent> observe_arms_refusals(ArmsRefusalMonitor& m, const wire::ArmsState& s,
                                                      std::string* error);

// The command for a setpoint (pure). Arms not active are not named (the
// robot keeps their targets); mode MANIPULATION. An arm in the direct mode is
// named with its twist (zero unless `deadman`) and its port, never a pose
// (a pose would end the robot's direct mode and pull the arm to the mapping's
// pose); pc_mode is this end's, for the port's pc_on.
void setpoint_to_command(const TelemanipSetpoint& sp, bool deadman, std::int64_t stamp_ns, wire::ArmsCommand* out,
                         tdpa::PcMode pc_mode = tdpa::PcMode::kControl);
// The direct mode's fields of a state, per arm: a port (read_energy_in) or a
// DirectWrench (6 finite values) that is bad or of an unknown arm is dropped
// and counted in *bad_ports / *bad_wrenches, `error` (may be null) saying the
// last why; the rest fill out->arm[i].direct. Pure.
void direct_from_wire(const wire::ArmsState& s, std::uint64_t seq, RemoteArmsState* out, std::uint64_t* bad_ports,
                      std::uint64_t* bad_wrenches, std::string* error);
// A checked state as the servo reads it (pure; expects check_arms_state ok;
// direct_from_wire then fills the direct fields, after it: it takes force_A).
void state_from_wire(const wire::ArmsState& s, std::uint64_t seq, std::int64_t recv_ns, RemoteArmsState* out);

struct TelemanipLinkParams {
  double rate_hz = 200.0;                     // [100, 1000]
  std::int64_t stale_after_ns = 100'000'000;  // an older setpoint: dead-man released
  tdpa::PcMode pc_mode = tdpa::PcMode::kControl;  // the operator end's (the ports' pc_on)
};

struct TelemanipLinkStats {
  std::uint64_t commands_sent = 0;
  std::uint64_t send_failures = 0;
  std::uint64_t link_down = 0;        // periods with nothing sent (no link)
  std::uint64_t deadman_pressed = 0;  // commands sent with the dead-man pressed
  std::uint64_t stale = 0;            // sent released because the setpoint was stale
  std::uint64_t no_setpoint = 0;      // periods before the servo published anything
  std::uint64_t states_in = 0;        // accepted ArmsStates
  std::uint64_t states_rejected = 0;  // malformed
  std::uint64_t states_reordered = 0; // older than one accepted
  std::uint64_t ports_rejected = 0;   // direct mode: bad PassivityPorts dropped
  std::uint64_t wrenches_rejected = 0;  // direct mode: bad DirectWrenches dropped
  std::uint64_t direct_commands = 0;  // commands that named a twist
  ArmsRefusalSummary refusals;
};

class TelemanipLink {
 public:
  using SendStream = std::function<bool(const wire::StreamMessage&)>;
  using Clock = std::function<std::int64_t()>;
  using LinkUp = std::function<bool()>;

  // Throws std::invalid_argument on a rate outside [100, 1000] Hz or a null
  // send / clock. link_up may be null (always up).
  TelemanipLink(asio::io_context& io, NewestMailbox<TelemanipSetpoint>& setpoints,
                NewestMailbox<RemoteArmsState>& remote, SendStream send, Clock clock, const TelemanipLinkParams& p,
                LinkUp link_up = nullptr);
  // Every ArmsState received, before its checks (the session recorder).
  using ReceivedTap = std::function<void(std::uint64_t seq, std::int64_t recv_ns, const wire::StreamMessage&)>;
  // Each ArmsState the link took (the SIMULATED task human's belief).
  using Accepted = std::function<void(const wire::ArmsState&)>;
  // Registers the ArmsState handler on the link (network thread).
  void attach(net::StreamLink& streams, ReceivedTap tap = nullptr, Accepted accepted = nullptr);
  void start();
  void stop();
  // One period's work (the timer's; tests may call it on the io thread).
  void send_once();
  // One ArmsState (the handler attach() registers calls it).
  void on_arms_state(std::uint64_t seq, std::int64_t recv_ns, const wire::ArmsState& s);
  // Network thread only (or after stop).
  const TelemanipLinkStats& stats() const { return stats_; }
  // Where to store each accepted ArmsState's safety flags (before start();
  // may be null): the SIMULATED human (telemanip_human.h) watches the
  // robot's status there as a person would at the station's display.
  void set_safety_out(std::atomic<std::uint32_t>* out) { safety_out_ = out; }

 private:
  void arm_timer();

  asio::steady_timer timer_;
  NewestMailbox<TelemanipSetpoint>& setpoints_;
  NewestMailbox<RemoteArmsState>& remote_;
  SendStream send_;
  Clock clock_;
  TelemanipLinkParams p_;
  LinkUp link_up_;
  TelemanipSetpoint latest_;
  bool have_ = false;
  bool running_ = false;
  bool was_down_ = false;
  std::chrono::steady_clock::time_point next_;
  wire::StreamMessage msg_;
  std::uint64_t newest_seq_ = 0;    // of the newest state accepted
  std::uint64_t state_epoch_ = 0;   // its frame epoch
  ArmsRefusalMonitor refusals_;
  std::atomic<std::uint32_t>* safety_out_ = nullptr;
  TelemanipLinkStats stats_;
};

}  // namespace hemm::op::telemanip
