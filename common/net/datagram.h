// Stream channel (UDP) datagrams: one StreamMessage per datagram, never more
// than kMaxDatagramBytes (1200) so that no path with the IPv6 minimum MTU
// (1280) fragments it. Larger payloads do not travel here: dense scans are
// split by the sender into self-contained RangeScan chunks of consecutive
// beams (RangeScan.first_beam; each chunk carries the full pose, so each can
// be placed on its own), and bulk data (point clouds, meshes) goes over the
// TCP session channel.
//
// Byte layout (all integers big-endian):
//   0  2  magic "HM" (0x48 0x4D)
//   2  1  header version (kDatagramVersion = 2)
//   3  1  flags, must be 0
//   4  8  session id
//  12  8  sequence number (per sender and session, starts at 1, +1 per datagram)
//  20  8  send time, int64 ns of the sender's steady clock
//  28  N  ciphertext of a serialised hemm.wire.StreamMessage (N = its length)
//  28+N 16 Poly1305 tag
// sealed with ChaCha20-Poly1305-IETF (crypto.h): key = the direction's udp
// key, nonce = 0(4) || sequence number(8), associated data = bytes [0, 28).
// The header stays readable (the receiver needs the session and sequence
// number before it can open anything) and is authenticated.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/net/crypto.h"

namespace hemm::net {

inline constexpr size_t kMaxDatagramBytes = 1200;
inline constexpr size_t kDatagramHeaderBytes = 28;
inline constexpr size_t kDatagramOverheadBytes = kDatagramHeaderBytes + kTagBytes;
inline constexpr size_t kMaxDatagramPayloadBytes = kMaxDatagramBytes - kDatagramOverheadBytes;
inline constexpr uint8_t kDatagramVersion = 2;

struct DatagramHeader {
  uint64_t session_id = 0;
  uint64_t seq = 0;
  int64_t send_time_ns = 0;
};

// Builds (seals) a datagram. Returns false (and leaves *out empty) if the
// payload is too large. The caller must never reuse a sequence number under
// one key (StreamLink counts up from 1 per session).
bool encode_datagram(const Key& key, const DatagramHeader& h, std::span<const uint8_t> payload,
                     std::vector<uint8_t>* out);

enum class DatagramError {
  kOk = 0,
  kBadSize,         // shorter than header+tag or longer than kMaxDatagramBytes
  kBadMagic,        // not ours (or flags set)
  kBadVersion,      // header version differs
  kUnknownSession,  // session id is not the open session
  kBadTag,          // authentication failed (the AEAD did not open)
};
const char* to_string(DatagramError e);

// Checks layout, version and session, then opens the AEAD (replay is
// checked separately, see ReplayWindow). On kOk, *h and *payload (the
// plaintext, resized; reuse one vector to avoid allocations) are set; on
// any error both are left untouched.
DatagramError decode_datagram(std::span<const uint8_t> bytes, uint64_t expected_session, const Key& key,
                              DatagramHeader* h, std::vector<uint8_t>* payload);

// Layout-only parse (no tag check), e.g. for tools. kOk means well-formed.
DatagramError parse_datagram_header(std::span<const uint8_t> bytes, DatagramHeader* h);

}  // namespace hemm::net
