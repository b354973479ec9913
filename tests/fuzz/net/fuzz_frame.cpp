// TCP frame decoder fed in fuzzer-chosen chunks, each frame then to the
// sealed-frame opener (must never open without the key) and the frame parser.
#include <cstdint>
#include <cstdlib>

#include "common/net/framing.h"
#include "common/net/handshake.h"

using namespace hemm::net;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const size_t chunk = 1 + data[0] % 97;
  FrameDecoder dec(4096);
  Key key{};
  key.fill(3);
  FrameOpener opener(key);
  std::vector<uint8_t> p, inner;
  size_t i = 1;
  size_t total = 0;
  while (i < size) {
    const size_t n = std::min(chunk, size - i);
    dec.feed(std::span<const uint8_t>(data + i, n));
    i += n;
    for (;;) {
      const auto st = dec.next(&p);
      if (st != FrameDecoder::Status::kFrame) break;
      if (p.empty() || p.size() > 4096) abort();
      total += p.size() + kFrameHeaderBytes;
      if (total > size) abort();
      if (opener.open(p, &inner)) abort();  // no tag forgery by chance
      hemm::wire::SessionFrame f;
      parse_session_frame(p, &f);
    }
  }
  return 0;
}
