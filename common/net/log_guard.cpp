#include "common/net/log_guard.h"

#include <algorithm>

namespace hemm::net {

std::string log_safe(std::string_view s, size_t max_bytes) {
  std::string out;
  out.reserve(std::min(s.size(), max_bytes));
  for (char c : s.substr(0, max_bytes)) {
    const bool ok = c >= 0x20 && c <= 0x7e && c != '"' && c != '\\';
    out.push_back(ok ? c : '_');
  }
  return out;
}

bool LogLimiter::allow(int64_t now, uint64_t* suppressed) {
  if (!started_) {
    started_ = true;
    last_ns_ = now;
  }
  if (now > last_ns_) {
    tokens_ = std::min(burst_, tokens_ + rate_ * static_cast<double>(now - last_ns_) * 1e-9);
    last_ns_ = now;
  }
  if (tokens_ < 1.0) {
    ++held_;
    ++suppressed_total_;
    return false;
  }
  tokens_ -= 1.0;
  if (suppressed) *suppressed = held_;
  held_ = 0;
  return true;
}

}  // namespace hemm::net
