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
//   2  1  header version (kDatagramVersion = 1)
//   3  1  flags, must be 0
//   4  8  session id
//  12  8  sequence number (per sender and session, starts at 1, +1 per datagram)
//  20  8  send time, int64 ns of the sender's steady clock
//  28  N  payload: a serialised hemm.wire.StreamMessage, in clear
//  28+N 16 tag = BLAKE2b-128 keyed with the direction's udp key over bytes [0, 28+N)
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
inline constexpr uint8_t kDatagramVersion = 1;

struct DatagramHeader {
  uint64_t session_id = 0;
  uint64_t seq = 0;
  int64_t send_time_ns = 0;
};

// Builds a datagram. Returns false (and leaves *out empty) if the payload is too large.
bool encode_datagram(const Key& key, const DatagramHeader& h, std::span<const uint8_t> payload,
                     std::vector<uint8_t>* out);

enum class DatagramError {
  kOk = 0,
  kBadSize,         // shorter than header+tag or longer than kMaxDatagramBytes
  kBadMagic,        // not ours (or flags set)
  kBadVersion,      // header version differs
  kUnknownSession,  // session id is not the open session
  kBadTag,          // authentication failed
};
const char* to_string(DatagramError e);

// Checks layout, version, session and tag (replay is checked separately, see
// ReplayWindow). On kOk, *h and *payload (a view into `bytes`) are set.
DatagramError decode_datagram(std::span<const uint8_t> bytes, uint64_t expected_session, const Key& key,
                              DatagramHeader* h, std::span<const uint8_t>* payload);

// Layout-only parse (no tag check), e.g. for tools. kOk means well-formed.
DatagramError parse_datagram_header(std::span<const uint8_t> bytes, DatagramHeader* h);

}  // namespace hemm::net
