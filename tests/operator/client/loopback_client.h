// Test helper: the operator's client and station options for a loopback test
// against a robot on 127.0.0.1 (no reconnecting, no real-time servo, logs in
// the build directory).
#pragma once

#include <cstdint>
#include <string>

#include "operator/client/operator_client.h"
#include "operator/station/operator_station.h"
#include "tests/temp_dir.h"

namespace hemm::test {

inline op::OperatorClientOptions loopback_client_options(const std::string& name, std::uint16_t session_port,
                                                         const net::Key& key) {
  op::OperatorClientOptions co;
  co.station_name = name;
  co.robot_address = "127.0.0.1";
  co.session_port = session_port;
  co.bind_address = "127.0.0.1";
  co.psk = key;
  co.reconnect_for_ms = 0;
  return co;
}

// Servo without SCHED_FIFO or mlockall; the 1 kHz log at log_name in a fresh
// temporary directory (tests/temp_dir.h).
inline op::OperatorStationOptions loopback_station_options(const std::string& log_name) {
  op::OperatorStationOptions so;
  so.servo.realtime = false;
  so.servo.lock_memory = false;
  so.log_path = make_temp_dir() + "/" + log_name;
  return so;
}

}  // namespace hemm::test
