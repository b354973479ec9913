// The path validator driven by fuzzer-chosen events (datagrams from 8
// addresses, responses carrying issued, altered or random tokens, time
// steps). Invariant: the peer changes only on a response that carries a
// token issued to exactly that address, and never to an address whose token
// was not returned.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <vector>

#include "common/net/path_validation.h"

using namespace hemm::net;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  PathValidatorParams p;
  p.min_interval_ns = 5'000'000;
  p.max_candidates = 3;
  p.max_tokens = 4;
  PathValidator v(p);
  std::vector<std::pair<PathToken, PathAddress>> issued;
  int64_t now = 0;
  size_t i = 0;
  while (i < size) {
    const uint8_t op = data[i++];
    PathAddress a;
    a.ip[15] = static_cast<uint8_t>(op & 7);
    a.port = static_cast<uint16_t>(1000 + (op & 7));
    switch (op >> 6) {
      case 0:
      case 1:
        if (auto t = v.on_datagram(a, now)) issued.emplace_back(*t, a);
        break;
      case 2: {  // response with an issued token (maybe altered)
        if (issued.empty() || i >= size) break;
        const auto& [tok, to] = issued[data[i++] % issued.size()];
        PathToken t = tok;
        const bool altered = (op & 8) != 0;
        if (altered) t[op % t.size()] ^= 0x5a;
        const auto before = v.peer();
        const auto got = v.on_response(t, now);
        if (got && (altered || !(*got == to) || !(v.peer() == got))) abort();
        if (!got && !(v.peer() == before)) abort();
        break;
      }
      default: {  // time step, or a random token
        if ((op & 32) != 0 && i + kPathTokenBytes <= size) {
          const auto before = v.peer();
          const bool known = [&] {
            for (const auto& [tok, to] : issued) {
              if (std::memcmp(tok.data(), data + i, kPathTokenBytes) == 0) return true;
            }
            return false;
          }();
          const auto got = v.on_response(std::span(data + i, kPathTokenBytes), now);
          if (got && !known) abort();
          if (!got && !(v.peer() == before)) abort();
          i += kPathTokenBytes;
        } else {
          now += int64_t{op & 31} * 50'000'000;
        }
        break;
      }
    }
  }
  return 0;
}
