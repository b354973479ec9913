// Key text parsing (libsodium's hex decoder) and the weak-key rules: any
// input either fails with a message or gives a key that re-encodes to the
// input's hex digits; the rules never crash and are deterministic.
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "common/net/crypto.h"

using namespace hemm::net;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::string err;
  const auto k = parse_key_hex(text, &err);
  if (!k) {
    if (err.empty() || err.find('\n') != std::string::npos) abort();  // one clear line
    return 0;
  }
  std::string digits;
  for (char c : text) {
    if (std::isxdigit(static_cast<unsigned char>(c))) digits.push_back(static_cast<char>(std::tolower(c)));
  }
  static const char* hex = "0123456789abcdef";
  std::string again;
  for (uint8_t b : *k) {
    again.push_back(hex[b >> 4]);
    again.push_back(hex[b & 15]);
  }
  if (again != digits) abort();
  const auto w1 = weak_key_reason(*k), w2 = weak_key_reason(*k);
  if (w1.has_value() != w2.has_value()) abort();
  // A key and its copy are the same demo-or-not.
  const Key copy = *k;
  if (is_demo_key(*k) != is_demo_key(copy)) abort();
  return 0;
}
