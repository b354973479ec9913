// What a peer can put into the logs, kept harmless: its text made printable
// and bounded, and a rate limit for lines a peer can cause (one per
// connection, per refused handshake, ...), so that a flood writes a bounded
// log. Pure: explicit time, no I/O.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace hemm::net {

// Printable ASCII only (0x20..0x7e without '"' and '\'), every other byte
// (newlines, escape sequences, UTF-8) as '_', at most max_bytes: safe inside
// a quoted key="value" log field and on a terminal.
std::string log_safe(std::string_view s, size_t max_bytes = 256);

// Token bucket: at most `burst` lines at once and `per_second` on average.
class LogLimiter {
 public:
  LogLimiter(double per_second, double burst) : rate_(per_second), burst_(burst), tokens_(burst) {}
  // True if a line may be written at now_ns; then *suppressed (if given) is
  // the number of lines held back since the last one let through.
  bool allow(int64_t now_ns, uint64_t* suppressed = nullptr);
  uint64_t suppressed_total() const { return suppressed_total_; }

 private:
  double rate_, burst_, tokens_;
  int64_t last_ns_ = 0;
  bool started_ = false;
  uint64_t held_ = 0, suppressed_total_ = 0;
};

}  // namespace hemm::net
