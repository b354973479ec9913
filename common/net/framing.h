// Session channel (TCP) framing: every frame is a 4-byte big-endian payload
// length followed by that many payload bytes. Lengths of 0 or above the
// configured maximum are errors; after an error the byte stream cannot be
// resynchronised, so the decoder stays failed and the connection must close.
//
// After the handshake every frame payload is  ciphertext || tag(16): the
// SessionFrame bytes sealed with ChaCha20-Poly1305-IETF (crypto.h), key =
// the direction's tcp key, nonce = 0(4) || counter(8, BE), associated data =
// the frame's 4-byte length header. The counter is implicit: 0 for the first
// sealed frame in that direction, +1 per frame. A dropped, reordered,
// replayed, truncated or injected frame therefore fails to open.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/net/crypto.h"

namespace hemm::net {

inline constexpr size_t kFrameHeaderBytes = 4;

// Appends header + payload to *out.
void encode_frame(std::span<const uint8_t> payload, std::vector<uint8_t>* out);

// Incremental decoder of a TCP byte stream.
class FrameDecoder {
 public:
  enum class Status { kNeedMore, kFrame, kError };

  explicit FrameDecoder(size_t max_frame_bytes) : max_frame_bytes_(max_frame_bytes) {}

  // Buffers bytes. Returns false (and buffers nothing) once failed.
  bool feed(std::span<const uint8_t> bytes);
  // Extracts the next complete frame payload into *payload.
  Status next(std::vector<uint8_t>* payload);

  // E.g. raised after the handshake (handshake frames are small).
  void set_max_frame_bytes(size_t n) { max_frame_bytes_ = n; }

  bool failed() const { return failed_; }
  const std::string& error() const { return error_; }
  size_t buffered() const { return buf_.size() - pos_; }

 private:
  size_t max_frame_bytes_;
  std::vector<uint8_t> buf_;
  size_t pos_ = 0;
  bool failed_ = false;
  std::string error_;
};

// Seals outgoing frame payloads of one direction (AEAD, implicit counter).
class FrameSealer {
 public:
  explicit FrameSealer(const Key& key) : key_(key) {}
  // ciphertext || tag; advances the counter.
  std::vector<uint8_t> seal(std::span<const uint8_t> payload);
  uint64_t counter() const { return counter_; }

 private:
  Key key_;
  uint64_t counter_ = 0;
};

// Opens incoming frame payloads of one direction. The counter only advances
// on success, so a forged frame changes no state (the connection is closed
// by the caller anyway).
class FrameOpener {
 public:
  explicit FrameOpener(const Key& key) : key_(key) {}
  // On success writes the plaintext to *inner and returns true.
  bool open(std::span<const uint8_t> sealed, std::vector<uint8_t>* inner);
  uint64_t counter() const { return counter_; }

 private:
  Key key_;
  uint64_t counter_ = 0;
};

}  // namespace hemm::net
