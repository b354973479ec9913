#include "common/net/crypto.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <bitset>
#include <cerrno>
#include <cctype>
#include <cstdio>

#include "common/net/bytes.h"

namespace hemm::net {

bool crypto_init() {
  static const bool ok = sodium_init() >= 0;
  return ok;
}

std::optional<Key> parse_key_hex(std::string_view text, std::string* error) {
  crypto_init();
  const auto fail = [&](std::string why) -> std::optional<Key> {
    if (error) *error = std::move(why);
    return std::nullopt;
  };
  size_t digits = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (std::isspace(c)) continue;
    if (!std::isxdigit(c)) return fail("key contains a non-hexadecimal character at offset " + std::to_string(i));
    ++digits;
  }
  if (digits != 2 * kKeyBytes) {
    return fail("key must be 64 hexadecimal characters (32 bytes), got " + std::to_string(digits));
  }
  // Whitespace may separate bytes, not split one: sodium_hex2bin stops there.
  Key k{};
  size_t len = 0;
  const char* end = nullptr;
  const int rc = sodium_hex2bin(k.data(), k.size(), text.data(), text.size(), " \t\r\n", &len, &end);
  if (rc != 0 || len != kKeyBytes) {
    sodium_memzero(k.data(), k.size());
    return fail("key has whitespace inside a byte (hex digits must come in pairs)");
  }
  for (; end != text.data() + text.size(); ++end) {
    if (!std::isspace(static_cast<unsigned char>(*end))) {
      sodium_memzero(k.data(), k.size());
      return fail("key has whitespace inside a byte (hex digits must come in pairs)");
    }
  }
  return k;
}

std::optional<std::string> weak_key_reason(const Key& k) {
  std::bitset<256> values, steps;
  for (size_t i = 0; i < k.size(); ++i) {
    values.set(k[i]);
    if (i + 1 < k.size()) steps.set(static_cast<uint8_t>(k[i + 1] - k[i]));
  }
  if (values.count() < 16) {
    return "key is weak: " + std::to_string(values.count()) +
           " distinct byte values (at least 16 required; all-zero and repeated bytes are refused)";
  }
  if (steps.count() < 16) {
    return "key is weak: a counting or stepping pattern (" + std::to_string(steps.count()) +
           " distinct differences between neighbouring bytes, at least 16 required)";
  }
  for (size_t p = 1; p <= 16; ++p) {
    bool periodic = true;
    for (size_t i = 0; i + p < k.size() && periodic; ++i) periodic = k[i] == k[i + p];
    if (periodic) return "key is weak: it repeats a pattern of " + std::to_string(p) + " bytes";
  }
  return std::nullopt;
}

bool is_demo_key(const Key& k) {
  // deploy/configs/demo.key (a test checks that the file still holds it).
  static constexpr Key kDemo = {0x29, 0xfe, 0x59, 0x89, 0x4f, 0x88, 0x8f, 0xab, 0x6e, 0x4d, 0xba,
                                0x65, 0xea, 0xb3, 0xcf, 0x72, 0x98, 0x9c, 0x48, 0x47, 0x82, 0x47,
                                0x56, 0xf7, 0xf3, 0x03, 0x37, 0x7e, 0x50, 0x4d, 0x9f, 0x11};
  return equal_constant_time(k, kDemo);
}

std::optional<Key> load_key_file(const std::string& path, std::string* error, KeyFileInfo* info) {
  const auto fail = [&](const std::string& why) -> std::optional<Key> {
    if (error) *error = path + ": " + why;
    return std::nullopt;
  };
  // The size is checked on the file that was opened (not on the name, which
  // may meanwhile be another file), before anything is read.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) return fail("cannot open key file");
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return fail("cannot stat key file");
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return fail("not a regular file");
  }
  if (st.st_size > static_cast<off_t>(kMaxKeyFileBytes)) {
    ::close(fd);
    return fail("key file too large (" + std::to_string(st.st_size) + " bytes, at most " +
                std::to_string(kMaxKeyFileBytes) + ")");
  }
  if (info) {
    info->mode = static_cast<unsigned>(st.st_mode & 07777);
    info->readable_by_others = (st.st_mode & 077) != 0;
  }
  // One buffer on the stack, a byte more than allowed (a file that grew
  // since the check is refused, not cut), wiped before it goes.
  std::array<char, kMaxKeyFileBytes + 1> text;
  size_t n = 0;
  bool read_error = false;
  while (n < text.size()) {
    const ssize_t r = ::read(fd, text.data() + n, text.size() - n);
    if (r == 0) break;
    if (r < 0) {
      if (errno == EINTR) continue;
      read_error = true;
      break;
    }
    n += static_cast<size_t>(r);
  }
  ::close(fd);
  std::string why;
  std::optional<Key> k;
  if (read_error) {
    why = "cannot read key file";
  } else if (n > kMaxKeyFileBytes) {
    why = "key file too large (it grew while being read)";
  } else {
    k = parse_key_hex(std::string_view(text.data(), n), &why);
  }
  sodium_memzero(text.data(), text.size());
  if (k) {
    if (auto weak = weak_key_reason(*k)) {
      why = *weak + "; make one with: head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \\n' > FILE";
      sodium_memzero(k->data(), k->size());
      k.reset();
    }
  }
  if (!k) return fail(why);
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

namespace {
std::array<uint8_t, crypto_aead_chacha20poly1305_IETF_NPUBBYTES> aead_nonce(uint64_t counter) {
  std::array<uint8_t, crypto_aead_chacha20poly1305_IETF_NPUBBYTES> n{};
  static_assert(crypto_aead_chacha20poly1305_IETF_NPUBBYTES == 12);
  static_assert(crypto_aead_chacha20poly1305_IETF_ABYTES == kTagBytes);
  static_assert(crypto_aead_chacha20poly1305_IETF_KEYBYTES == kKeyBytes);
  put_u64(n.data() + 4, counter);
  return n;
}
}  // namespace

void aead_seal(const Key& key, uint64_t counter, std::span<const uint8_t> ad, std::span<const uint8_t> plain,
               uint8_t* out) {
  crypto_init();
  const auto n = aead_nonce(counter);
  crypto_aead_chacha20poly1305_ietf_encrypt_detached(out, out + plain.size(), nullptr, plain.data(), plain.size(),
                                                     ad.data(), ad.size(), nullptr, n.data(), key.data());
}

bool aead_open(const Key& key, uint64_t counter, std::span<const uint8_t> ad, std::span<const uint8_t> sealed,
               uint8_t* out) {
  if (sealed.size() < kTagBytes) return false;
  crypto_init();
  const auto n = aead_nonce(counter);
  const size_t len = sealed.size() - kTagBytes;
  return crypto_aead_chacha20poly1305_ietf_decrypt_detached(out, nullptr, sealed.data(), len, sealed.data() + len,
                                                            ad.data(), ad.size(), n.data(), key.data()) == 0;
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
