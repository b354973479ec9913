// Process exit codes of hemm-robot and hemm-operator (also listed in --help).
#pragma once

namespace hemm::net {

enum ExitCode : int {
  kExitOk = 0,
  kExitInternal = 1,        // internal error
  kExitUsage = 2,           // bad command line or config
  kExitKey = 3,             // key file missing or bad
  kExitAuth = 4,            // authentication failed
  kExitVersion = 5,         // protocol version mismatch
  kExitRefused = 6,         // refused: another operator has control
  kExitPeerLost = 7,        // peer lost / connect failed / gave up reconnecting
};

inline constexpr const char* kExitCodeHelp =
    "Exit codes: 0 ok, 1 internal error, 2 bad command line or config, 3 key file bad,\n"
    "  4 authentication failed, 5 protocol version mismatch, 6 refused (another operator\n"
    "  has control), 7 peer lost or connect failed.";

}  // namespace hemm::net
