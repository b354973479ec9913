#include "common/net/datagram.h"

#include <gtest/gtest.h>
#include <sodium.h>

#include <algorithm>
#include <cstring>

#include "common/net/bytes.h"

namespace hemm::net {
namespace {

Key test_key(uint8_t seed) {
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(seed + 3 * i);
  return k;
}

std::vector<uint8_t> make(const Key& k, uint64_t sid, uint64_t seq, size_t payload_bytes) {
  std::vector<uint8_t> payload(payload_bytes);
  for (size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<uint8_t>(i * 7);
  std::vector<uint8_t> d;
  EXPECT_TRUE(encode_datagram(k, DatagramHeader{sid, seq, -12345}, payload, &d));
  return d;
}

TEST(DatagramTest, LayoutIsAsDocumented) {
  const Key k = test_key(1);
  const auto d = make(k, 0x0102030405060708ull, 0x1112131415161718ull, 10);
  ASSERT_EQ(d.size(), 28u + 10u + 16u);
  EXPECT_EQ(d[0], 'H');
  EXPECT_EQ(d[1], 'M');
  EXPECT_EQ(d[2], 2);
  EXPECT_EQ(d[3], 0);
  EXPECT_EQ(get_u64(d.data() + 4), 0x0102030405060708ull);
  EXPECT_EQ(get_u64(d.data() + 12), 0x1112131415161718ull);
  EXPECT_EQ(static_cast<int64_t>(get_u64(d.data() + 20)), -12345);
}

// Independent reference: libsodium's combined-mode ChaCha20-Poly1305-IETF
// with the documented nonce (4 zero bytes, then the sequence number) and the
// 28-byte header as associated data.
TEST(DatagramTest, PayloadIsSealedWithChaCha20Poly1305UnderTheHeader) {
  ASSERT_GE(sodium_init(), 0);
  const Key k = test_key(2);
  const uint64_t seq = 0x0a0b0c0d0e0f1011ull;
  const auto d = make(k, 77, seq, 33);
  std::vector<uint8_t> payload(33);
  for (size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<uint8_t>(i * 7);
  uint8_t nonce[12] = {0, 0, 0, 0};
  put_u64(nonce + 4, seq);
  std::vector<uint8_t> ref(33 + 16);
  unsigned long long ref_len = 0;
  crypto_aead_chacha20poly1305_ietf_encrypt(ref.data(), &ref_len, payload.data(), payload.size(), d.data(), 28,
                                            nullptr, nonce, k.data());
  ASSERT_EQ(ref_len, ref.size());
  EXPECT_EQ(std::vector<uint8_t>(d.begin() + 28, d.end()), ref);
  // The payload is not in clear anywhere in the datagram.
  EXPECT_EQ(std::search(d.begin(), d.end(), payload.begin() + 1, payload.begin() + 9), d.end());
  // And the reference opens what the codec sealed.
  std::vector<uint8_t> plain(33);
  ASSERT_EQ(crypto_aead_chacha20poly1305_ietf_decrypt(plain.data(), nullptr, nullptr, d.data() + 28, d.size() - 28,
                                                      d.data(), 28, nonce, k.data()),
            0);
  EXPECT_EQ(plain, payload);
}

TEST(DatagramTest, RoundTrip) {
  const Key k = test_key(3);
  const auto d = make(k, 42, 9, 100);
  DatagramHeader h;
  std::vector<uint8_t> p;
  ASSERT_EQ(decode_datagram(d, 42, k, &h, &p), DatagramError::kOk);
  EXPECT_EQ(h.session_id, 42u);
  EXPECT_EQ(h.seq, 9u);
  EXPECT_EQ(h.send_time_ns, -12345);
  ASSERT_EQ(p.size(), 100u);
  EXPECT_EQ(p[10], 70);
}

TEST(DatagramTest, SizeLimits) {
  const Key k = test_key(4);
  std::vector<uint8_t> d;
  EXPECT_TRUE(encode_datagram(k, {1, 1, 0}, std::vector<uint8_t>(kMaxDatagramPayloadBytes), &d));
  EXPECT_EQ(d.size(), kMaxDatagramBytes);
  EXPECT_EQ(kMaxDatagramBytes, 1200u);
  EXPECT_FALSE(encode_datagram(k, {1, 1, 0}, std::vector<uint8_t>(kMaxDatagramPayloadBytes + 1), &d));
  EXPECT_TRUE(d.empty());
  DatagramHeader h;
  std::vector<uint8_t> p;
  // An empty payload is well-formed at the datagram layer.
  const auto e = make(k, 1, 1, 0);
  EXPECT_EQ(decode_datagram(e, 1, k, &h, &p), DatagramError::kOk);
  EXPECT_EQ(decode_datagram(std::span(e).first(e.size() - 1), 1, k, &h, &p), DatagramError::kBadSize);
  std::vector<uint8_t> big(kMaxDatagramBytes + 1, 0);
  big[0] = 'H';
  big[1] = 'M';
  big[2] = 1;
  EXPECT_EQ(decode_datagram(big, 1, k, &h, &p), DatagramError::kBadSize);
}

TEST(DatagramTest, RejectsMagicVersionSessionKey) {
  const Key k = test_key(5);
  const auto d = make(k, 10, 1, 20);
  DatagramHeader h{};
  std::vector<uint8_t> p = {1, 2, 3};
  auto m = d;
  m[0] = 'X';
  EXPECT_EQ(decode_datagram(m, 10, k, &h, &p), DatagramError::kBadMagic);
  m = d;
  m[3] = 1;
  EXPECT_EQ(decode_datagram(m, 10, k, &h, &p), DatagramError::kBadMagic);
  m = d;
  m[2] = 1;  // protocol 1's layout (payload in clear) is not read
  EXPECT_EQ(decode_datagram(m, 10, k, &h, &p), DatagramError::kBadVersion);
  EXPECT_EQ(decode_datagram(d, 11, k, &h, &p), DatagramError::kUnknownSession);
  EXPECT_EQ(decode_datagram(d, 0, k, &h, &p), DatagramError::kUnknownSession);
  EXPECT_EQ(decode_datagram(d, 10, test_key(6), &h, &p), DatagramError::kBadTag);
  EXPECT_EQ(h.seq, 0u) << "outputs untouched on failure";
  EXPECT_EQ(p, (std::vector<uint8_t>{1, 2, 3}));
}

TEST(DatagramTest, EveryBitFlipIsRejected) {
  const Key k = test_key(7);
  const auto d = make(k, 10, 3, 40);
  for (size_t i = 0; i < d.size() * 8; ++i) {
    auto m = d;
    m[i / 8] ^= static_cast<uint8_t>(1u << (i % 8));
    DatagramHeader h;
    std::vector<uint8_t> p;
    EXPECT_NE(decode_datagram(m, 10, k, &h, &p), DatagramError::kOk) << "bit " << i;
  }
}

}  // namespace
}  // namespace hemm::net
