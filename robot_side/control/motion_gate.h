// The robot's re-arm gate (docs/security.md, SAFETY_REARM), one for every
// robot kind: a stop is not undone by its cause going away. After a stop
// (e-stop, lost link, expired watchdog, no operator in control, start-up)
// the robot follows nothing until, with no stop in force, it has seen a
// neutral command (one that asks for no motion, e.g. the dead-man released)
// and then a command with the dead-man pressed. A pure value over explicit
// state, like watchdog.h.
#pragma once

namespace hemm::robot {

struct MotionGate {
  bool armed = false;
  bool neutral_seen = false;
};

inline void gate_disarm(MotionGate& g) {
  g.armed = false;
  g.neutral_seen = false;
}

// An operator command towards the re-arm: counted only when no stop is in
// force; a pressed command after a neutral one arms.
inline void gate_offer(MotionGate& g, bool stop_in_force, bool neutral, bool deadman) {
  if (g.armed || stop_in_force) return;
  if (deadman && g.neutral_seen) {
    g.armed = true;
  } else if (neutral) {
    g.neutral_seen = true;
  }
}

}  // namespace hemm::robot
