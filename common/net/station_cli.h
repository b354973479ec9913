// Small helpers shared by the station binaries (hemm-robot, hemm-operator):
// structured logging setup and writing result files. Not for libraries.
#pragma once

#include <string>

namespace hemm::net {

// Logs go to stderr, one line per event: "<time> level=<l> station=<name> event=... key=value ...".
// Returns false if `level` is not a spdlog level name.
bool setup_station_logging(const std::string& station, const std::string& level);

// Writes `text` to `path` atomically enough for tests (write + rename).
bool write_text_file(const std::string& path, const std::string& text, std::string* error);

}  // namespace hemm::net
