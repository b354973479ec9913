// Small helpers shared by the station binaries (hemm-robot, hemm-operator):
// structured logging setup and writing result files. Not for libraries.
#pragma once

#include <optional>
#include <string>

#include "common/net/crypto.h"
#include "common/net/link_options.h"

namespace hemm::config {
class LinkConfig;
}
namespace CLI {
class App;
}

namespace hemm::terminal {
class TerminalKeys;
}

namespace hemm::net {

// Logs go to stderr, one line per event: "<time> level=<l> station=<name> event=... key=value ...".
// Returns false if `level` is not a spdlog level name.
bool setup_station_logging(const std::string& station, const std::string& level);

// Peer- or user-supplied text for a log line or a reply: at most
// kMaxReasonBytes, printable ASCII, no double quotes (each other byte '_').
std::string printable_text(const std::string& s);

// Writes `text` to `path` atomically enough for tests (write + rename).
bool write_text_file(const std::string& path, const std::string& text, std::string* error);

// The pre-shared key of a station: --key if given, else the config's
// link.key_file resolved relative to the config file. Refuses weak keys
// (crypto.h) and the public demo key unless `network_address` (the robot's
// listen address, the operator's robot address) is a loopback address; warns
// when the file is readable or writable by group or others. On failure
// prints one line (prefixed with `program`), logs it, and returns nullopt:
// the caller exits with kExitKey.
std::optional<Key> load_station_key(const std::string& program, const std::string& key_option,
                                    const std::string& config_path, const std::string& config_key_file,
                                    const std::string& network_address);

// A station's config when none was given on the command line: `file_name`
// in configs/ of the data directory (common/config/data_dir.h), logged as
// event=default_config; "" (built-in defaults, with a warning naming the
// directories searched) if there is none.
std::string default_station_config(const std::string& station, const std::string& file_name);

// True for 127.0.0.0/8 and ::1 (false for anything else, also names and 0.0.0.0).
bool is_loopback_address(const std::string& address);

// The link section of a station's config (with its key) into the options
// both stations share.
void apply_link_config(const config::LinkConfig& link, const Key& psk, LinkOptions* out);

// Local control of a running station (station_control.h): the options
// --control-socket PATH (listen for e-stop commands there) and --no-keys
// (no e-stop keys from the terminal), and the subcommands `estop`,
// `release` and `status`, each with --control-socket PATH, which send that
// command to a running station instead of starting one.
struct StationControlOptions {
  std::string socket;     // --control-socket: empty, none
  bool no_keys = false;   // --no-keys
  std::string command;    // a subcommand given: run it, not the station
  std::string command_socket;
};
void add_station_control_options(CLI::App& app, const std::string& station, StationControlOptions* out);
// Starts the e-stop keys (space or e: engage, R: release) when stdin is a
// terminal and --no-keys was not given; logs which.
void start_estop_keys(terminal::TerminalKeys& keys, const StationControlOptions& o);
int run_control_command(const std::string& program, const StationControlOptions& o);

}  // namespace hemm::net
