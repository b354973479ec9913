#include "common/net/crypto.h"

#include <sodium.h>

#include <cctype>
#include <fstream>
#include <sstream>

#include "common/net/bytes.h"

namespace hemm::net {

bool crypto_init() {
  static const bool ok = sodium_init() >= 0;
  return ok;
}

std::optional<Key> parse_key_hex(const std::string& text, std::string* error) {
  std::string hex;
  for (char c : text) {
    if (std::isspace(static_cast<unsigned char>(c))) continue;
    if (!std::isxdigit(static_cast<unsigned char>(c))) {
      if (error) *error = "key contains a non-hexadecimal character";
      return std::nullopt;
    }
    hex.push_back(c);
  }
  if (hex.size() != 2 * kKeyBytes) {
    if (error) *error = "key must be 64 hexadecimal characters (32 bytes), got " + std::to_string(hex.size());
    return std::nullopt;
  }
  Key k{};
  for (size_t i = 0; i < kKeyBytes; ++i) {
    k[i] = static_cast<uint8_t>(std::stoul(hex.substr(2 * i, 2), nullptr, 16));
  }
  return k;
}

std::optional<Key> load_key_file(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open key file";
    return std::nullopt;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  if (ss.str().size() > 4096) {
    if (error) *error = path + ": key file too large";
    return std::nullopt;
  }
  std::string why;
  auto k = parse_key_hex(ss.str(), &why);
  if (!k && error) *error = path + ": " + why;
  return k;
}

void random_bytes(uint8_t* out, size_t n) {
  crypto_init();
  randombytes_buf(out, n);
}

uint64_t random_u64_nonzero() {
  uint64_t v = 0;
  while (v == 0) {
    uint8_t b[8];
    random_bytes(b, 8);
    v = get_u64(b);
  }
  return v;
}

Proof hmac_sha256(const Key& key, std::string_view label, std::span<const uint8_t> data) {
  crypto_init();
  crypto_auth_hmacsha256_state st;
  crypto_auth_hmacsha256_init(&st, key.data(), key.size());
  crypto_auth_hmacsha256_update(&st, reinterpret_cast<const unsigned char*>(label.data()), label.size());
  crypto_auth_hmacsha256_update(&st, data.data(), data.size());
  Proof out{};
  crypto_auth_hmacsha256_final(&st, out.data());
  sodium_memzero(&st, sizeof st);
  return out;
}

bool equal_constant_time(std::span<const uint8_t> a, std::span<const uint8_t> b) {
  if (a.size() != b.size()) return false;
  if (a.empty()) return true;
  crypto_init();
  return sodium_memcmp(a.data(), b.data(), a.size()) == 0;
}

Tag auth_tag(const Key& key, std::span<const uint8_t> a, std::span<const uint8_t> b) {
  crypto_init();
  crypto_generichash_state st;
  crypto_generichash_init(&st, key.data(), key.size(), kTagBytes);
  crypto_generichash_update(&st, a.data(), a.size());
  if (!b.empty()) crypto_generichash_update(&st, b.data(), b.size());
  Tag out{};
  crypto_generichash_final(&st, out.data(), out.size());
  return out;
}

SessionKeys derive_session_keys(const Key& psk, const Nonce& client_nonce, const Nonce& server_nonce,
                                uint64_t session_id) {
  std::array<uint8_t, 2 * kNonceBytes + 8> ctx{};
  std::copy(client_nonce.begin(), client_nonce.end(), ctx.begin());
  std::copy(server_nonce.begin(), server_nonce.end(), ctx.begin() + kNonceBytes);
  put_u64(ctx.data() + 2 * kNonceBytes, session_id);
  SessionKeys k;
  k.udp_c2s = hmac_sha256(psk, "hemm-v1 udp c2s", ctx);
  k.udp_s2c = hmac_sha256(psk, "hemm-v1 udp s2c", ctx);
  k.tcp_c2s = hmac_sha256(psk, "hemm-v1 tcp c2s", ctx);
  k.tcp_s2c = hmac_sha256(psk, "hemm-v1 tcp s2c", ctx);
  return k;
}

}  // namespace hemm::net
