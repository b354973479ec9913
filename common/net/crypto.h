// Pre-shared-key cryptography of the link (libsodium underneath): key files
// and the rules a key must pass, HMAC-SHA256 proofs, per-session key
// derivation and the AEAD that seals every datagram and session frame.
//
// Key derivation (all HMAC-SHA256 keyed with the 32-byte PSK):
//   K = HMAC(psk, label || client_nonce(32) || server_nonce(32) || session_id(8, BE))
// with label one of (ASCII, no terminator)
//   "hemm-v1 udp c2s", "hemm-v1 udp s2c", "hemm-v1 tcp c2s", "hemm-v1 tcp s2c"
// (c2s: operator -> robot). Each direction and channel has its own key, so a
// message sealed for one can never open on another.
//
// Sealing: ChaCha20-Poly1305 in its IETF form (RFC 8439; libsodium's
// crypto_aead_chacha20poly1305_ietf) with
//   nonce = 0x00000000 || counter(8, BE)
// where counter is the datagram's sequence number or the session frame's
// implicit counter. A key is used by one sender only and its counter never
// repeats within a session (and every session has fresh keys), so a nonce is
// never reused; that is why the short-nonce IETF variant suffices and no
// random nonce (XChaCha20) is needed. The 16-byte Poly1305 tag authenticates
// the associated data (the clear header) and the ciphertext.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace hemm::net {

inline constexpr size_t kKeyBytes = 32;
inline constexpr size_t kNonceBytes = 32;
inline constexpr size_t kProofBytes = 32;
inline constexpr size_t kTagBytes = 16;  // Poly1305

using Key = std::array<uint8_t, kKeyBytes>;
using Nonce = std::array<uint8_t, kNonceBytes>;
using Proof = std::array<uint8_t, kProofBytes>;

// Initialises libsodium once (thread-safe). Returns false if it cannot.
bool crypto_init();

// Parses 64 hex characters (libsodium's sodium_hex2bin; whitespace around and
// between bytes allowed). On failure returns nullopt and sets *error. Does
// not judge the key's strength (see weak_key_reason).
std::optional<Key> parse_key_hex(std::string_view text, std::string* error);

// Why a key must not be used, or nullopt. A key is weak when it has
//   * fewer than 16 distinct byte values (all zero, one repeated byte, short
//     alphabets), or
//   * fewer than 16 distinct differences between neighbouring bytes
//     (counting and stepping patterns such as 00 01 02 ...), or
//   * a period of at most 16 bytes (a short pattern repeated).
// A key drawn uniformly at random fails with probability below 1e-14 (the
// first rule below 3e-16, the second below 5e-15, the third below 3e-39;
// docs/protocol.md, "Keys").
std::optional<std::string> weak_key_reason(const Key& k);

// The committed demonstration key (deploy/configs/demo.key). It is public:
// stations accept it only on a loopback address.
bool is_demo_key(const Key& k);

// What load_key_file found besides the key.
struct KeyFileInfo {
  bool readable_by_others = false;  // group or other permission bits set
  unsigned mode = 0;                // permission bits (e.g. 0644)
};

// Reads and parses a key file and refuses weak keys; errors name the file
// and fit on one line. The file must be a regular file of at most
// kMaxKeyFileBytes, checked on the opened file before anything is read; its
// text is read into one local buffer (never the heap), which is wiped
// (sodium_memzero) whatever happens, as is a refused key.
inline constexpr size_t kMaxKeyFileBytes = 4096;
std::optional<Key> load_key_file(const std::string& path, std::string* error, KeyFileInfo* info = nullptr);

void random_bytes(uint8_t* out, size_t n);
uint64_t random_u64_nonzero();

// HMAC-SHA256(key, label || data).
Proof hmac_sha256(const Key& key, std::string_view label, std::span<const uint8_t> data);

// Constant-time equality of two equal-length byte ranges (false if lengths differ;
// the lengths themselves are not secret).
bool equal_constant_time(std::span<const uint8_t> a, std::span<const uint8_t> b);

// AEAD seal: writes ciphertext (plain.size() bytes) || tag(16) to `out`,
// which must hold plain.size() + kTagBytes bytes (it may not overlap plain
// except exactly, out == plain.data()).
void aead_seal(const Key& key, uint64_t counter, std::span<const uint8_t> ad, std::span<const uint8_t> plain,
               uint8_t* out);
// AEAD open: verifies the tag (constant time) and on success writes the
// plaintext (sealed.size() - kTagBytes bytes) to `out`. False (nothing
// written) on a bad tag or a sealed input shorter than the tag.
bool aead_open(const Key& key, uint64_t counter, std::span<const uint8_t> ad, std::span<const uint8_t> sealed,
               uint8_t* out);

struct SessionKeys {
  Key udp_c2s{}, udp_s2c{}, tcp_c2s{}, tcp_s2c{};
};
SessionKeys derive_session_keys(const Key& psk, const Nonce& client_nonce, const Nonce& server_nonce,
                                uint64_t session_id);

}  // namespace hemm::net
