#include "common/net/framing.h"

#include <gtest/gtest.h>

#include <sodium.h>

#include <algorithm>
#include <random>

namespace hemm::net {
namespace {

std::vector<uint8_t> bytes(const std::string& s) { return {s.begin(), s.end()}; }

TEST(FramingTest, HeaderIsBigEndianLength) {
  std::vector<uint8_t> out;
  encode_frame(bytes("abc"), &out);
  ASSERT_EQ(out.size(), 7u);
  EXPECT_EQ(out[0], 0);
  EXPECT_EQ(out[1], 0);
  EXPECT_EQ(out[2], 0);
  EXPECT_EQ(out[3], 3);
  EXPECT_EQ(std::string(out.begin() + 4, out.end()), "abc");
  out.clear();
  encode_frame(std::vector<uint8_t>(0x010203, 7), &out);
  EXPECT_EQ(out[0], 0x00);
  EXPECT_EQ(out[1], 0x01);
  EXPECT_EQ(out[2], 0x02);
  EXPECT_EQ(out[3], 0x03);
}

TEST(FramingTest, DecodesFramesSplitAtEveryByte) {
  std::vector<std::vector<uint8_t>> frames = {bytes("a"), bytes("hello"), std::vector<uint8_t>(1000, 0x5a),
                                              bytes("end")};
  std::vector<uint8_t> stream;
  for (auto& f : frames) encode_frame(f, &stream);
  FrameDecoder d(4096);
  std::vector<std::vector<uint8_t>> got;
  std::vector<uint8_t> p;
  for (uint8_t b : stream) {
    ASSERT_TRUE(d.feed(std::span<const uint8_t>(&b, 1)));
    while (d.next(&p) == FrameDecoder::Status::kFrame) got.push_back(p);
  }
  EXPECT_EQ(got, frames);
  EXPECT_EQ(d.buffered(), 0u);
}

TEST(FramingTest, DecodesManyFramesFedAtOnceAndInRandomChunks) {
  std::mt19937 rng(7);
  std::vector<std::vector<uint8_t>> frames;
  std::vector<uint8_t> stream;
  for (int i = 0; i < 200; ++i) {
    std::vector<uint8_t> f(1 + rng() % 300);
    for (auto& b : f) b = static_cast<uint8_t>(rng());
    encode_frame(f, &stream);
    frames.push_back(f);
  }
  FrameDecoder d(300);
  std::vector<std::vector<uint8_t>> got;
  std::vector<uint8_t> p;
  size_t i = 0;
  while (i < stream.size()) {
    const size_t n = std::min<size_t>(stream.size() - i, 1 + rng() % 700);
    d.feed(std::span<const uint8_t>(stream.data() + i, n));
    i += n;
    while (d.next(&p) == FrameDecoder::Status::kFrame) got.push_back(p);
  }
  EXPECT_EQ(got, frames);
}

TEST(FramingTest, MaximumSizeIsInclusiveAndLargerIsAStickyError) {
  FrameDecoder d(16);
  std::vector<uint8_t> s;
  encode_frame(std::vector<uint8_t>(16, 1), &s);
  encode_frame(std::vector<uint8_t>(17, 2), &s);
  encode_frame(std::vector<uint8_t>(3, 3), &s);
  d.feed(s);
  std::vector<uint8_t> p;
  ASSERT_EQ(d.next(&p), FrameDecoder::Status::kFrame);
  EXPECT_EQ(p.size(), 16u);
  EXPECT_EQ(d.next(&p), FrameDecoder::Status::kError);
  EXPECT_TRUE(d.failed());
  EXPECT_NE(d.error().find("exceeds"), std::string::npos);
  // No resynchronisation: the following valid frame is not returned.
  EXPECT_EQ(d.next(&p), FrameDecoder::Status::kError);
  EXPECT_FALSE(d.feed(s));
}

TEST(FramingTest, HugeLengthIsRejectedBeforeBuffering) {
  FrameDecoder d(1 << 20);
  const uint8_t h[4] = {0xff, 0xff, 0xff, 0xff};
  d.feed(h);
  std::vector<uint8_t> p;
  EXPECT_EQ(d.next(&p), FrameDecoder::Status::kError);
}

TEST(FramingTest, EmptyFrameIsAnError) {
  FrameDecoder d(16);
  const uint8_t h[4] = {0, 0, 0, 0};
  d.feed(h);
  std::vector<uint8_t> p;
  EXPECT_EQ(d.next(&p), FrameDecoder::Status::kError);
  EXPECT_EQ(d.error(), "empty frame");
}

TEST(FramingTest, SealedFramesOpenInOrderOnly) {
  Key k{};
  k[0] = 9;
  FrameSealer tx(k);
  FrameOpener rx(k);
  const auto a = tx.seal(bytes("first"));
  const auto b = tx.seal(bytes("second"));
  ASSERT_EQ(a.size(), 5 + kTagBytes);
  std::vector<uint8_t> inner;
  // Out of order: b carries counter 1, the opener expects 0.
  EXPECT_FALSE(rx.open(b, &inner));
  EXPECT_EQ(rx.counter(), 0u);
  ASSERT_TRUE(rx.open(a, &inner));
  EXPECT_EQ(inner, bytes("first"));
  // Replay of a.
  EXPECT_FALSE(rx.open(a, &inner));
  ASSERT_TRUE(rx.open(b, &inner));
  EXPECT_EQ(inner, bytes("second"));
  EXPECT_EQ(rx.counter(), 2u);
}

// Independent reference: libsodium's combined ChaCha20-Poly1305-IETF with
// nonce 0(4) || counter(8, BE) and the frame's length header as associated data.
TEST(FramingTest, SealedFramesAreChaCha20Poly1305WithTheLengthHeaderAsAssociatedData) {
  ASSERT_GE(sodium_init(), 0);
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(i * i + 1);
  FrameSealer tx(k);
  const auto plain = bytes("an e-stop, say");
  tx.seal(plain);  // counter 0
  const auto s = tx.seal(plain);  // counter 1
  uint8_t nonce[12] = {0};
  nonce[11] = 1;
  const uint8_t ad[4] = {0, 0, 0, static_cast<uint8_t>(plain.size() + 16)};
  std::vector<uint8_t> ref(plain.size() + 16);
  unsigned long long n = 0;
  crypto_aead_chacha20poly1305_ietf_encrypt(ref.data(), &n, plain.data(), plain.size(), ad, 4, nullptr, nonce,
                                            k.data());
  EXPECT_EQ(s, ref);
  EXPECT_EQ(std::search(s.begin(), s.end(), plain.begin(), plain.begin() + 4), s.end()) << "plaintext visible";
}

TEST(FramingTest, SealedFrameRejectsEveryBitFlipAndWrongKey) {
  Key k{};
  k[5] = 1;
  FrameSealer tx(k);
  const auto s = tx.seal(bytes("mode change"));
  for (size_t i = 0; i < s.size() * 8; ++i) {
    auto m = s;
    m[i / 8] ^= static_cast<uint8_t>(1u << (i % 8));
    FrameOpener rx(k);
    std::vector<uint8_t> inner;
    EXPECT_FALSE(rx.open(m, &inner)) << "bit " << i;
  }
  Key other = k;
  other[31] ^= 1;
  FrameOpener wrong(other);
  std::vector<uint8_t> inner;
  EXPECT_FALSE(wrong.open(s, &inner));
  FrameOpener right(k);
  EXPECT_TRUE(right.open(s, &inner));
  // Too short to hold a tag.
  FrameOpener r2(k);
  EXPECT_FALSE(r2.open(std::vector<uint8_t>(kTagBytes - 1, 0), &inner));
}

}  // namespace
}  // namespace hemm::net
