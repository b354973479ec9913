// hemm-relay: the impairment relay between the two stations for loopback
// latency-injection tests (kernel netem is not available on the test machines).
// Exit codes: 0 normal end, 1 runtime failure (e.g. bind), 2 bad arguments.
#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <asio.hpp>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/net/relay/relay.h"

namespace {

using hemm::net::relay::DirectionImpairment;
using hemm::net::relay::HostPort;
using hemm::net::relay::JitterDistribution;
using hemm::net::relay::Outage;
using hemm::net::relay::Relay;
using hemm::net::relay::RelayConfig;

struct BadArgument : std::runtime_error {
  using std::runtime_error::runtime_error;
};

double parse_double(const std::string& opt, const std::string& text) {
  double v = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc() || ptr != end || !std::isfinite(v)) {
    throw BadArgument("--" + opt + ": '" + text + "' is not a finite number");
  }
  return v;
}

std::uint64_t parse_uint(const std::string& opt, const std::string& text) {
  std::uint64_t v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (text.empty() || ec != std::errc() || ptr != end) {
    throw BadArgument("--" + opt + ": '" + text + "' is not a non-negative integer");
  }
  return v;
}

double parse_probability(const std::string& opt, const std::string& text) {
  const double v = parse_double(opt, text);
  if (v < 0.0 || v > 1.0) throw BadArgument("--" + opt + ": " + text + " is not in [0, 1]");
  return v;
}

// Seconds/milliseconds -> ns, rejecting negatives and values that would overflow.
std::int64_t to_ns(const std::string& opt, double v, double scale) {
  const double ns = v * scale;
  if (ns < 0.0) throw BadArgument("--" + opt + ": must be >= 0");
  if (ns > 1e18) throw BadArgument("--" + opt + ": too large");
  return static_cast<std::int64_t>(std::llround(ns));
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::size_t b = 0;
  for (;;) {
    const std::size_t e = s.find(sep, b);
    out.push_back(s.substr(b, e == std::string::npos ? std::string::npos : e - b));
    if (e == std::string::npos) break;
    b = e + 1;
  }
  return out;
}

// One impairment option in its three spellings: --X (both), --up-X, --down-X.
struct Triple {
  std::string both, up, down;
  CLI::Option* o_both = nullptr;
  CLI::Option* o_up = nullptr;
  CLI::Option* o_down = nullptr;
  // Value for a direction, or nullopt when none of the spellings was given.
  std::optional<std::string> get(bool is_up) const {
    const CLI::Option* dir = is_up ? o_up : o_down;
    if (dir->count() > 0) return is_up ? up : down;
    if (o_both->count() > 0) return both;
    return std::nullopt;
  }
  // The spelling the value came from, for error messages.
  std::string name(bool is_up) const {
    const CLI::Option* dir = is_up ? o_up : o_down;
    return (dir->count() > 0 ? dir : o_both)->get_name().substr(2);
  }
};

struct TripleList {
  std::vector<std::string> both, up, down;
  CLI::Option* o_both = nullptr;
  CLI::Option* o_up = nullptr;
  CLI::Option* o_down = nullptr;
  const std::vector<std::string>* get(bool is_up) const {
    const CLI::Option* dir = is_up ? o_up : o_down;
    if (dir->count() > 0) return is_up ? &up : &down;
    if (o_both->count() > 0) return &both;
    return nullptr;
  }
  std::string name(bool is_up) const {
    const CLI::Option* dir = is_up ? o_up : o_down;
    return (dir->count() > 0 ? dir : o_both)->get_name().substr(2);
  }
};

struct TripleFlag {
  bool both = false, up = false, down = false;
  bool get(bool is_up) const { return both || (is_up ? up : down); }
};

struct ImpairmentOptions {
  Triple delay, jitter, dist, loss, ge, dup, reorder, reorder_extra, rate, queue;
  TripleList outage;
  TripleFlag jitter_reorder;

  void add(CLI::App& app) {
    auto triple = [&app](Triple& t, const std::string& name, const std::string& type,
                         const std::string& help) {
      t.o_both = app.add_option("--" + name, t.both, help + " (both directions)")
                     ->type_name(type)
                     ->group("Impairment");
      t.o_up = app.add_option("--up-" + name, t.up, "--" + name + " for client->server only")
                   ->type_name(type)
                   ->group("Per-direction overrides");
      t.o_down = app.add_option("--down-" + name, t.down, "--" + name + " for server->client only")
                     ->type_name(type)
                     ->group("Per-direction overrides");
    };
    triple(delay, "delay-ms", "MS", "fixed one-way delay [ms], default 0");
    triple(jitter, "jitter-ms", "MS", "jitter [ms]: half-width for uniform, std for normal; delay+jitter truncated at >= 0");
    triple(dist, "jitter-dist", "uniform|normal", "jitter distribution: uniform|normal, default uniform");
    triple(loss, "loss", "P", "UDP random loss probability in [0,1]");
    triple(ge, "ge", "P,R,K,H", "UDP Gilbert-Elliott burst loss P,R,K,H: P good->bad, R bad->good, loss 1-K in good, 1-H in bad");
    triple(dup, "duplicate", "P", "UDP duplication probability; the copy gets its own delay+jitter");
    triple(reorder, "reorder", "P", "UDP reorder probability: such a packet gets --reorder-extra-ms extra delay");
    triple(reorder_extra, "reorder-extra-ms", "MS", "extra delay of reordered UDP packets [ms], default 10");
    triple(rate, "rate-kbps", "KBIT/S", "rate limit [kbit/s] (1 kbit = 1000 bit), 0 = unlimited");
    triple(queue, "queue-bytes", "BYTES", "rate-limit queue [bytes]: UDP packets beyond it are dropped; TCP pauses reading; 0 = unlimited");
    outage.o_both = app.add_option("--outage", outage.both,
                                   "outage START_S:DURATION_S after relay start (repeatable): UDP dropped, TCP held")
                        ->type_name("START_S:DURATION_S")
                        ->group("Impairment");
    outage.o_up = app.add_option("--up-outage", outage.up, "--outage for client->server only (repeatable)")
                      ->type_name("START_S:DURATION_S")
                      ->group("Per-direction overrides");
    outage.o_down = app.add_option("--down-outage", outage.down, "--outage for server->client only (repeatable)")
                        ->type_name("START_S:DURATION_S")
                        ->group("Per-direction overrides");
    app.add_flag("--jitter-reorder", jitter_reorder.both,
                 "let jitter reorder UDP packets (default: release order kept when --reorder is 0)")
        ->group("Impairment");
    app.add_flag("--up-jitter-reorder", jitter_reorder.up, "--jitter-reorder client->server only")
        ->group("Per-direction overrides");
    app.add_flag("--down-jitter-reorder", jitter_reorder.down, "--jitter-reorder server->client only")
        ->group("Per-direction overrides");
  }

  DirectionImpairment build(bool is_up) const {
    
    DirectionImpairment d;
    d.reorder_extra_ns = 10'000'000;
    if (auto v = delay.get(is_up)) d.delay_ns = to_ns(delay.name(is_up), parse_double(delay.name(is_up), *v), 1e6);
    if (auto v = jitter.get(is_up)) d.jitter_ns = to_ns(jitter.name(is_up), parse_double(jitter.name(is_up), *v), 1e6);
    if (auto v = dist.get(is_up)) {
      if (*v == "uniform") {
        d.jitter_distribution = JitterDistribution::kUniform;
      } else if (*v == "normal") {
        d.jitter_distribution = JitterDistribution::kNormal;
      } else {
        throw BadArgument("--" + dist.name(is_up) + ": '" + *v + "' is not uniform|normal");
      }
    }
    if (auto v = loss.get(is_up)) d.loss = parse_probability(loss.name(is_up), *v);
    if (auto v = ge.get(is_up)) {
      const auto parts = split(*v, ',');
      if (parts.size() != 4) throw BadArgument("--" + ge.name(is_up) + ": expected P,R,K,H, got '" + *v + "'");
      d.gilbert_elliott.enabled = true;
      d.gilbert_elliott.p = parse_probability(ge.name(is_up) + " P", parts[0]);
      d.gilbert_elliott.r = parse_probability(ge.name(is_up) + " R", parts[1]);
      d.gilbert_elliott.k = parse_probability(ge.name(is_up) + " K", parts[2]);
      d.gilbert_elliott.h = parse_probability(ge.name(is_up) + " H", parts[3]);
    }
    if (auto v = dup.get(is_up)) d.duplicate = parse_probability(dup.name(is_up), *v);
    if (auto v = reorder.get(is_up)) d.reorder = parse_probability(reorder.name(is_up), *v);
    if (auto v = reorder_extra.get(is_up)) {
      d.reorder_extra_ns = to_ns(reorder_extra.name(is_up), parse_double(reorder_extra.name(is_up), *v), 1e6);
    }
    if (auto v = rate.get(is_up)) {
      const double kbps = parse_double(rate.name(is_up), *v);
      if (kbps < 0.0) throw BadArgument("--" + rate.name(is_up) + ": must be >= 0");
      d.rate_bytes_per_s = kbps * 1000.0 / 8.0;
    }
    if (auto v = queue.get(is_up)) {
      const std::uint64_t q = parse_uint(queue.name(is_up), *v);
      if (q > (std::uint64_t{1} << 40)) throw BadArgument("--" + queue.name(is_up) + ": too large");
      d.queue_bytes = static_cast<std::int64_t>(q);
    }
    if (const auto* list = outage.get(is_up)) {
      for (const std::string& o : *list) {
        const auto parts = split(o, ':');
        if (parts.size() != 2) {
          throw BadArgument("--" + outage.name(is_up) + ": expected START_S:DURATION_S, got '" + o + "'");
        }
        Outage out;
        out.start_ns = to_ns(outage.name(is_up) + " start", parse_double(outage.name(is_up), parts[0]), 1e9);
        out.duration_ns = to_ns(outage.name(is_up) + " duration", parse_double(outage.name(is_up), parts[1]), 1e9);
        d.outages.push_back(out);
      }
    }
    d.keep_order = !jitter_reorder.get(is_up);
    if (std::string err = hemm::net::relay::validate(d, is_up ? "up" : "down"); !err.empty()) {
      throw BadArgument(err);
    }
    return d;
  }
};

std::optional<HostPort> endpoint(const std::string& opt, const std::string& text) {
  if (text.empty()) return std::nullopt;
  HostPort hp;
  if (std::string err = hemm::net::relay::parse_host_port(text, hp); !err.empty()) {
    throw BadArgument("--" + opt + ": " + err);
  }
  return hp;
}

bool write_json_file(const std::string& path, const std::string& json) {
  // Write then rename, so a reader never sees a half-written file.
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::trunc);
    if (!f) return false;
    f << json << "\n";
    if (!f.flush()) return false;
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  return !ec;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "hemm-relay: impairment relay for loopback latency-injection tests (simulated network;\n"
      "kernel netem is not available). Forwards TCP and/or UDP between a listen and a forward\n"
      "endpoint, per direction: up = client->server, down = server->client. Impairment options\n"
      "apply to both directions; --up-<opt>/--down-<opt> override one direction.\n"
      "TCP cannot lose bytes: only delay, jitter (order kept), rate limit and outages (bytes\n"
      "held until the outage ends) apply to TCP; loss, bursts, duplication and reordering are\n"
      "UDP only. Prints 'hemm-relay ready' on stdout once listening, its counters at exit.\n"
      "Exit codes: 0 ok, 1 runtime error, 2 bad arguments."};
  app.set_help_all_flag("--help-all", "show all options");

  std::string tcp_listen, tcp_forward, udp_listen, udp_forward;
  std::string seed_text = "1", duration_text = "0", stats_period_text = "0", log_level = "info";
  std::string stats_json;
  app.add_option("--tcp-listen", tcp_listen, "TCP listen endpoint HOST:PORT (with --tcp-forward)")->type_name("HOST:PORT")->group("Endpoints");
  app.add_option("--tcp-forward", tcp_forward, "TCP forward endpoint HOST:PORT")->type_name("HOST:PORT")->group("Endpoints");
  app.add_option("--udp-listen", udp_listen, "UDP listen endpoint HOST:PORT (with --udp-forward)")->type_name("HOST:PORT")->group("Endpoints");
  app.add_option("--udp-forward", udp_forward, "UDP forward endpoint HOST:PORT")->type_name("HOST:PORT")->group("Endpoints");
  ImpairmentOptions imp;
  imp.add(app);
  app.add_option("--seed", seed_text, "random seed (same seed, same decisions), default 1")->type_name("N")->group("Run");
  app.add_option("--duration", duration_text, "run for S seconds; 0 = until SIGINT/SIGTERM (default)")->type_name("S")->group("Run");
  app.add_option("--stats-json", stats_json, "write counters as JSON to FILE (at exit, and every --stats-period)")->type_name("FILE")->group("Run");
  app.add_option("--stats-period", stats_period_text, "log counters (and rewrite --stats-json) every S seconds; 0 = off")->type_name("S")->group("Run");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|critical|off, default info")->type_name("LEVEL")->group("Run");

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }

  RelayConfig cfg;
  double duration_s = 0.0;
  double stats_period_s = 0.0;
  spdlog::level::level_enum level = spdlog::level::info;
  try {
    cfg.tcp_listen = endpoint("tcp-listen", tcp_listen);
    cfg.tcp_forward = endpoint("tcp-forward", tcp_forward);
    cfg.udp_listen = endpoint("udp-listen", udp_listen);
    cfg.udp_forward = endpoint("udp-forward", udp_forward);
    cfg.up = imp.build(true);
    cfg.down = imp.build(false);
    cfg.seed = parse_uint("seed", seed_text);
    duration_s = parse_double("duration", duration_text);
    if (duration_s < 0.0 || duration_s > 1e9) throw BadArgument("--duration: must be in [0, 1e9] s");
    stats_period_s = parse_double("stats-period", stats_period_text);
    if (stats_period_s < 0.0 || stats_period_s > 1e9) throw BadArgument("--stats-period: must be in [0, 1e9] s");
    level = spdlog::level::from_str(log_level);
    if (level == spdlog::level::off && log_level != "off") {
      throw BadArgument("--log-level: '" + log_level + "' is not trace|debug|info|warn|error|critical|off");
    }
    if (std::string err = hemm::net::relay::validate(cfg); !err.empty()) throw BadArgument(err);
  } catch (const BadArgument& e) {
    std::cerr << "hemm-relay: error: " << e.what() << "\nRun with --help for more information.\n";
    return 2;
  }

  auto logger = spdlog::stderr_color_mt("hemm-relay");
  spdlog::set_default_logger(logger);
  spdlog::set_level(level);

  asio::io_context io;
  asio::signal_set signals(io, SIGINT, SIGTERM);
  std::optional<Relay> relay;
  try {
    relay.emplace(cfg);
  } catch (const std::exception& e) {
    spdlog::error("cannot start: {}", e.what());
    return 1;
  }
  if (cfg.tcp_listen) {
    spdlog::info("TCP {}:{} -> {}", cfg.tcp_listen->host, relay->tcp_listen_port(),
                 hemm::net::relay::to_string(*cfg.tcp_forward));
  }
  if (cfg.udp_listen) {
    spdlog::info("UDP {}:{} -> {}", cfg.udp_listen->host, relay->udp_listen_port(),
                 hemm::net::relay::to_string(*cfg.udp_forward));
  }
  // Signals are caught before "ready" is printed, so a test may stop us right after it.
  std::cout << "hemm-relay ready" << std::endl;  // endl: flushed, tests wait for it

  signals.async_wait([&io](const asio::error_code& ec, int sig) {
    if (!ec) spdlog::info("signal {}: stopping", sig);
    io.stop();
  });
  asio::steady_timer end_timer(io);
  if (duration_s > 0.0) {
    end_timer.expires_after(std::chrono::nanoseconds(static_cast<std::int64_t>(duration_s * 1e9)));
    end_timer.async_wait([&io](const asio::error_code& ec) {
      if (!ec) io.stop();
    });
  }
  asio::steady_timer period_timer(io);
  const auto period = std::chrono::nanoseconds(static_cast<std::int64_t>(stats_period_s * 1e9));
  std::function<void()> arm_period = [&] {
    period_timer.expires_after(period);
    period_timer.async_wait([&](const asio::error_code& ec) {
      if (ec) return;
      const auto s = relay->stats();
      spdlog::info("stats {}", hemm::net::relay::stats_to_json(s));
      if (!stats_json.empty() && !write_json_file(stats_json, hemm::net::relay::stats_to_json(s))) {
        spdlog::warn("cannot write {}", stats_json);
      }
      arm_period();
    });
  };
  if (stats_period_s > 0.0) arm_period();
  io.run();

  relay->stop();
  const auto s = relay->stats();
  const std::string json = hemm::net::relay::stats_to_json(s);
  std::cout << hemm::net::relay::stats_to_text(s) << "stats " << json << std::endl;
  if (!stats_json.empty() && !write_json_file(stats_json, json)) {
    spdlog::error("cannot write {}", stats_json);
    return 1;
  }
  return 0;
}
