#include "common/net/station_cli.h"

#include <CLI/CLI.hpp>
#include <unistd.h>
#include <google/protobuf/stubs/logging.h>
#include <asio.hpp>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <vector>

#include "common/config/config.h"
#include "common/config/data_dir.h"
#include "common/net/exit_codes.h"
#include "common/net/handshake.h"
#include "common/net/station_control.h"
#include "common/terminal/terminal_keys.h"
#include "config_link.pb.h"

namespace hemm::net {

bool setup_station_logging(const std::string& station, const std::string& level) {
  const auto lvl = spdlog::level::from_str(level);
  if (lvl == spdlog::level::off && level != "off") return false;
  auto logger = spdlog::stderr_logger_mt("hemm");
  logger->set_pattern("%Y-%m-%dT%H:%M:%S.%e level=%l station=" + station + " %v");
  logger->set_level(lvl);
  logger->flush_on(spdlog::level::trace);
  spdlog::set_default_logger(logger);
  // Protobuf complains (e.g. invalid UTF-8 from a hostile peer) through its own
  // logger; route it into ours at debug level so peers cannot flood the log.
  google::protobuf::SetLogHandler([](google::protobuf::LogLevel, const char*, int, const std::string& msg) {
    spdlog::debug("event=protobuf_log message=\"{}\"", msg);
  });
  return true;
}

std::string default_station_config(const std::string& station, const std::string& file_name) {
  std::vector<std::string> searched;
  const std::string path = config::default_config_path(file_name, &searched);
  if (!path.empty()) {
    spdlog::info("event=default_config station={} file=\"{}\"", station, path);
    return path;
  }
  std::string dirs;
  for (const std::string& d : searched) dirs += (dirs.empty() ? "" : ", ") + d;
  spdlog::warn("event=no_default_config station={} file=configs/{} searched=\"{}\" (built-in defaults; --config "
               "FILE or HEMM_DATA_DIR)",
               station, file_name, dirs);
  return {};
}

std::string printable_text(const std::string& s) {
  std::string out;
  for (char c : truncate_text(s, kMaxReasonBytes)) out.push_back((c >= 0x20 && c <= 0x7e && c != '"') ? c : '_');
  return out;
}

bool write_text_file(const std::string& path, const std::string& text, std::string* error) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out || !(out << text) || !out.flush()) {
      if (error) *error = "cannot write " + tmp;
      return false;
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    if (error) *error = "cannot rename " + tmp + " to " + path;
    return false;
  }
  return true;
}

bool is_loopback_address(const std::string& address) {
  asio::error_code ec;
  const auto a = asio::ip::make_address(address, ec);
  return !ec && a.is_loopback();
}

std::optional<Key> load_station_key(const std::string& program, const std::string& key_option,
                                    const std::string& config_path, const std::string& config_key_file,
                                    const std::string& network_address) {
  std::string key_path = key_option;
  if (key_path.empty()) key_path = config::resolve_relative_to(config_path, config_key_file);
  if (key_path.empty()) {
    std::cerr << program << ": no key: give --key FILE or link.key_file in the config\n";
    return std::nullopt;
  }
  std::string key_error;
  KeyFileInfo info;
  auto key = load_key_file(key_path, &key_error, &info);
  if (key && is_demo_key(*key) && !is_loopback_address(network_address)) {
    key.reset();
    key_error = key_path + ": the demo key is public and accepted only on a loopback address, not " +
                network_address + "; make a key with: head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \\n' > FILE";
  }
  if (!key) {
    std::cerr << program << ": bad key file: " << key_error << "\n";
    spdlog::error("event=bad_key error=\"{}\"", key_error);
    return std::nullopt;
  }
  // The demo key is no secret: its permissions do not matter.
  if (info.readable_by_others && !is_demo_key(*key)) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", info.mode);
    std::cerr << program << ": warning: key file " << key_path << " is accessible to group or others (mode " << mode
              << "); chmod 600 " << key_path << "\n";
    spdlog::warn("event=key_file_permissions file=\"{}\" mode={}", key_path, mode);
  }
  return key;
}

}  // namespace hemm::net

namespace hemm::net {

void apply_link_config(const config::LinkConfig& link, const Key& psk, LinkOptions* out) {
  out->station_name = link.station_name();
  out->psk = psk;
  out->heartbeat_period_ms = link.heartbeat_period_ms();
  out->ping_period_ms = link.ping_period_ms();
  out->link_timeout_ms = link.link_timeout_ms();
  out->handshake_timeout_ms = link.handshake_timeout_ms();
  out->max_frame_bytes = link.max_frame_bytes();
  out->replay_window = link.replay_window();
  out->stale_margin_ms = link.stale_margin_ms();
  out->rtt_ms = link.rtt_ms();
}

void add_station_control_options(CLI::App& app, const std::string& station, StationControlOptions* out) {
  app.add_option("--control-socket", out->socket,
                 "listen on this Unix socket (owner-only) for the e-stop: `" + station +
                     " estop|release|status --control-socket PATH`");
  app.add_flag("--no-keys", out->no_keys,
               "do not read e-stop keys from the terminal (by default, when stdin is a terminal: space or e engages "
               "the e-stop, R releases it)");
  struct Sub {
    const char* name;
    const char* help;
  };
  for (const Sub& c : {Sub{"estop", "engage the e-stop of a running "}, Sub{"release", "release the e-stop of a running "},
                       Sub{"status", "print the session and e-stop state of a running "}}) {
    CLI::App* sub = app.add_subcommand(c.name, c.help + station + " through its --control-socket");
    sub->footer("Exit codes: 0 done, 6 refused (the reply says why), 7 no station answered on the socket.");
    sub->add_option("--control-socket", out->command_socket, "the running station's --control-socket path")
        ->required();
    sub->callback([out, name = std::string(c.name)] { out->command = name; });
  }
}

void start_estop_keys(terminal::TerminalKeys& keys, const StationControlOptions& o) {
  if (o.no_keys || !::isatty(STDIN_FILENO)) return;
  std::string error;
  if (keys.start(&error)) {
    spdlog::info("event=estop_keys keys=\"space or e: e-stop, R: release\"");
  } else {
    spdlog::warn("event=estop_keys_off reason=\"{}\"", error);
  }
}

int run_control_command(const std::string& program, const StationControlOptions& o) {
  std::string error;
  // The operator's station waits for the robot's Ack (up to 5 s) before it replies.
  const auto reply = control_request(o.command_socket, o.command, std::chrono::milliseconds(8000), &error);
  if (!reply) {
    std::cerr << program << ": " << error << "\n";
    return kExitPeerLost;
  }
  std::cout << *reply << std::endl;
  return reply->rfind("ok", 0) == 0 ? kExitOk : kExitRefused;
}

}  // namespace hemm::net
