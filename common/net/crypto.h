// Pre-shared-key cryptography of the link (libsodium underneath): key files,
// HMAC-SHA256 proofs, per-session key derivation and the 16-byte keyed
// BLAKE2b authentication tags of datagrams and session frames.
//
// Key derivation (all HMAC-SHA256 keyed with the 32-byte PSK):
//   K = HMAC(psk, label || client_nonce(32) || server_nonce(32) || session_id(8, BE))
// with label one of (ASCII, no terminator)
//   "hemm-v1 udp c2s", "hemm-v1 udp s2c", "hemm-v1 tcp c2s", "hemm-v1 tcp s2c"
// (c2s: operator -> robot). Each direction and channel has its own key, so a
// tag made for one can never verify on another.
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
inline constexpr size_t kTagBytes = 16;

using Key = std::array<uint8_t, kKeyBytes>;
using Nonce = std::array<uint8_t, kNonceBytes>;
using Proof = std::array<uint8_t, kProofBytes>;
using Tag = std::array<uint8_t, kTagBytes>;

// Initialises libsodium once (thread-safe). Returns false if it cannot.
bool crypto_init();

// Parses 64 hex characters (surrounding whitespace allowed). On failure
// returns nullopt and sets *error.
std::optional<Key> parse_key_hex(const std::string& text, std::string* error);
// Reads and parses a key file; errors name the file.
std::optional<Key> load_key_file(const std::string& path, std::string* error);

void random_bytes(uint8_t* out, size_t n);
uint64_t random_u64_nonzero();

// HMAC-SHA256(key, label || data).
Proof hmac_sha256(const Key& key, std::string_view label, std::span<const uint8_t> data);

// Constant-time equality of two equal-length byte ranges (false if lengths differ;
// the lengths themselves are not secret).
bool equal_constant_time(std::span<const uint8_t> a, std::span<const uint8_t> b);

// Keyed BLAKE2b with a 16-byte output over the concatenation of a and b.
Tag auth_tag(const Key& key, std::span<const uint8_t> a, std::span<const uint8_t> b = {});

struct SessionKeys {
  Key udp_c2s{}, udp_s2c{}, tcp_c2s{}, tcp_s2c{};
};
SessionKeys derive_session_keys(const Key& psk, const Nonce& client_nonce, const Nonce& server_nonce,
                                uint64_t session_id);

}  // namespace hemm::net
