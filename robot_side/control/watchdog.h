// The robot station's command watchdog: a pure function over explicit state
// (time stamps int64 ns).
#pragma once

#include <cstdint>

namespace hemm::robot {

// No valid command for `timeout_ns` => expired. Before the first command it is
// expired too (nothing to follow). The watchdog judges a command's age, not
// its arrival: feed it the time the command was *sent*, on the watchdog's
// clock, as a command that took the least delay on the path would have
// arrived (the station passes arrival - the time the path held it, see
// net::judge_message_age). A command held on the path for longer than the
// timeout is expired on arrival; one held for t is followed for timeout - t.
// A time in the future (after `now`) would extend the timeout: the feed
// clamps it to now.
struct Watchdog {
  int64_t timeout_ns = 250'000'000;
  int64_t last_valid_ns = 0;
  bool has_command = false;
};
inline void watchdog_feed(Watchdog& w, int64_t sent_ns, int64_t now_ns) {
  w.last_valid_ns = sent_ns < now_ns ? sent_ns : now_ns;
  w.has_command = true;
}
// A command that took the least delay (sent_ns == now_ns).
inline void watchdog_feed(Watchdog& w, int64_t now_ns) { watchdog_feed(w, now_ns, now_ns); }
inline bool watchdog_expired(const Watchdog& w, int64_t now_ns) {
  return !w.has_command || now_ns - w.last_valid_ns > w.timeout_ns;
}

}  // namespace hemm::robot
