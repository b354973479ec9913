// What both stations' links are configured with (LinkConfig in
// proto/config_link.proto, plus the key): RobotServerOptions and
// OperatorClientOptions extend it with their own endpoints and limits.
#pragma once

#include <cstdint>
#include <string>

#include "common/net/crypto.h"
#include "common/net/handshake.h"

namespace hemm::net {

struct LinkOptions {
  std::string station_name = "hemm";  // shown in the peer's logs
  Key psk{};
  uint32_t protocol_version = kProtocolVersion;
  uint32_t heartbeat_period_ms = 50;
  uint32_t ping_period_ms = 50;
  uint32_t link_timeout_ms = 500;
  uint32_t handshake_timeout_ms = 3000;
  uint32_t max_frame_bytes = 1 << 20;
  uint32_t replay_window = 1024;
  uint32_t stale_margin_ms = 200;   // robot: commands older than rtt + this are refused
  uint32_t rtt_ms = 0;              // expected round trip, 0: unknown
};

}  // namespace hemm::net
