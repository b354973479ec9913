// Datagram decoder + stream receiver. Inputs that open under the fuzz key
// (a valid Poly1305 tag) are impossible to find by chance; the target also
// seals the input as a well-formed datagram so the AEAD round trip, the
// payload parser and the replay window get exercised, and checks the
// invariants of what is accepted.
#include <cstdint>
#include <algorithm>
#include <cstdlib>

#include "common/net/datagram.h"
#include "common/net/stream_receiver.h"

using namespace hemm::net;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Key key{};
  key.fill(7);
  constexpr uint64_t kSid = 0x1122334455667788ull;
  static StreamReceiver rx(64);
  static bool opened = false;
  if (!opened) {
    rx.open(kSid, key);
    opened = true;
  }
  DatagramHeader h;
  hemm::wire::StreamMessage m;
  // 1) Raw bytes: must never be delivered (the fuzzer cannot know the key's tags).
  const auto v = rx.receive(std::span<const uint8_t>(data, size), &h, &m);
  if (v == StreamReceiver::Verdict::kDeliver) {
    // Only possible if the input is a correctly sealed datagram.
    std::vector<uint8_t> p;
    if (decode_datagram(std::span<const uint8_t>(data, size), kSid, key, &h, &p) != DatagramError::kOk) abort();
  }
  // 2) The input as payload of a correctly sealed datagram with a sequence
  //    number taken from its first bytes: it must open to exactly the input.
  if (size >= 2) {
    const uint64_t seq = 1 + (static_cast<uint64_t>(data[0]) << 8 | data[1]);
    std::vector<uint8_t> d;
    const bool fits = encode_datagram(key, DatagramHeader{kSid, seq, 0}, std::span<const uint8_t>(data + 2, size - 2), &d);
    if (fits != (size - 2 <= kMaxDatagramPayloadBytes)) abort();
    if (fits) {
      std::vector<uint8_t> plain;
      DatagramHeader h2;
      if (decode_datagram(d, kSid, key, &h2, &plain) != DatagramError::kOk) abort();
      if (h2.seq != seq || !std::equal(plain.begin(), plain.end(), data + 2, data + size)) abort();
      const auto before = rx.counters();
      rx.receive(d, &h, &m);
      const auto& after = rx.counters();
      if (after.received != before.received + 1) abort();
      if (after.rejected_bad_tag != before.rejected_bad_tag) abort();
    }
  }
  return 0;
}
