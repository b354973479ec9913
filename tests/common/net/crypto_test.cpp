// Key files and the key rules: libsodium hex parsing, weak keys refused, the
// committed demo key recognised, permissions reported; the AEAD against RFC
// 8439's published vectors and the nonce layout of datagrams and frames.
#include "common/net/crypto.h"

#include <gtest/gtest.h>
#include <sodium.h>
#include <sys/stat.h>

#include <algorithm>
#include <fstream>
#include <random>
#include <string_view>

#include "common/net/datagram.h"
#include "common/net/framing.h"
#include "tests/temp_dir.h"

namespace hemm::net {
namespace {

const std::string kDemoKeyFile = std::string(HEMM_SOURCE_DIR) + "/deploy/configs/demo.key";

std::string hex(const Key& k) {
  static const char* d = "0123456789abcdef";
  std::string s;
  for (uint8_t b : k) {
    s.push_back(d[b >> 4]);
    s.push_back(d[b & 15]);
  }
  return s;
}

Key random_key(std::mt19937_64& rng) {
  Key k{};
  for (auto& b : k) b = static_cast<uint8_t>(rng());
  return k;
}

std::string temp_file(const std::string& name, const std::string& text, mode_t mode) {
  static const std::string dir = hemm::test::make_temp_dir();
  const std::string path = dir + "/" + name;
  std::ofstream(path) << text;
  ::chmod(path.c_str(), mode);
  return path;
}

TEST(KeyParsing, ReadsHexWithWhitespaceBetweenBytesOnly) {
  std::string err;
  Key k{};
  for (size_t i = 0; i < k.size(); ++i) k[i] = static_cast<uint8_t>(0xf0 ^ (i * 37));
  const std::string h = hex(k);
  ASSERT_EQ(parse_key_hex("  " + h + "\n", &err), k) << err;
  std::string spaced;
  for (size_t i = 0; i < h.size(); i += 2) spaced += h.substr(i, 2) + (i % 8 == 6 ? "\n" : " ");
  EXPECT_EQ(parse_key_hex(spaced, &err), k) << err;
  std::string upper = h;
  for (char& c : upper) c = static_cast<char>(std::toupper(c));
  EXPECT_EQ(parse_key_hex(upper, &err), k);
  // A space inside a byte, a stray character, a wrong length.
  EXPECT_FALSE(parse_key_hex(h.substr(0, 1) + " " + h.substr(1), &err));
  EXPECT_NE(err.find("pairs"), std::string::npos) << err;
  EXPECT_FALSE(parse_key_hex(h.substr(0, 63) + "g", &err));
  EXPECT_NE(err.find("non-hexadecimal character at offset 63"), std::string::npos) << err;
  EXPECT_FALSE(parse_key_hex(h + "00", &err));
  EXPECT_NE(err.find("64 hexadecimal characters"), std::string::npos) << err;
  EXPECT_FALSE(parse_key_hex("", &err));
}

TEST(WeakKeys, AllZeroRepeatedCountingAndPeriodicKeysAreRefused) {
  Key zero{};
  EXPECT_TRUE(weak_key_reason(zero));
  Key aa{};
  aa.fill(0xaa);
  EXPECT_TRUE(weak_key_reason(aa));
  Key counting{};
  for (size_t i = 0; i < counting.size(); ++i) counting[i] = static_cast<uint8_t>(i);
  EXPECT_TRUE(weak_key_reason(counting));
  Key stepping{};
  for (size_t i = 0; i < stepping.size(); ++i) stepping[i] = static_cast<uint8_t>(17 * i + 3);
  EXPECT_TRUE(weak_key_reason(stepping));
  // A random 16-byte block twice: 16 distinct values, but period 16.
  std::mt19937_64 rng(3);
  std::array<uint8_t, 256> all{};
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<uint8_t>(i);
  std::shuffle(all.begin(), all.end(), rng);
  Key twice{};
  for (size_t i = 0; i < twice.size(); ++i) twice[i] = all[i % 16];
  const auto why = weak_key_reason(twice);
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("repeats a pattern of 16 bytes"), std::string::npos) << *why;
  // ASCII text as a key ("passwordpassword..."): few distinct bytes.
  Key text{};
  const std::string pw = "password";
  for (size_t i = 0; i < text.size(); ++i) text[i] = static_cast<uint8_t>(pw[i % pw.size()]);
  EXPECT_TRUE(weak_key_reason(text));
}

TEST(WeakKeys, RandomKeysAndTheDemoKeyPass) {
  // The rules' false-positive rate for random keys is below 1e-14
  // (crypto.h); 200,000 keys must all pass.
  std::mt19937_64 rng(20261123);
  for (int i = 0; i < 200000; ++i) {
    const Key k = random_key(rng);
    ASSERT_FALSE(weak_key_reason(k)) << hex(k) << ": " << *weak_key_reason(k);
  }
  std::string err;
  KeyFileInfo info;
  const auto demo = load_key_file(kDemoKeyFile, &err, &info);
  ASSERT_TRUE(demo) << err;
  EXPECT_TRUE(is_demo_key(*demo)) << "is_demo_key() must match deploy/configs/demo.key";
  EXPECT_FALSE(is_demo_key(random_key(rng)));
}

TEST(KeyFiles, WeakKeyFileIsRefusedInOneLineNamingTheFile) {
  const std::string path = temp_file("zero.key", std::string(64, '0') + "\n", 0600);
  std::string err;
  EXPECT_FALSE(load_key_file(path, &err));
  EXPECT_EQ(err.rfind(path + ": key is weak", 0), 0u) << err;
  EXPECT_EQ(err.find('\n'), std::string::npos) << err;
}

TEST(KeyFiles, PermissionsThatLetOthersReadAreReported) {
  std::mt19937_64 rng(5);
  const std::string text = hex(random_key(rng)) + "\n";
  KeyFileInfo info;
  std::string err;
  ASSERT_TRUE(load_key_file(temp_file("private.key", text, 0600), &err, &info)) << err;
  EXPECT_FALSE(info.readable_by_others);
  EXPECT_EQ(info.mode, 0600u);
  ASSERT_TRUE(load_key_file(temp_file("group.key", text, 0640), &err, &info)) << err;
  EXPECT_TRUE(info.readable_by_others);
  ASSERT_TRUE(load_key_file(temp_file("world.key", text, 0604), &err, &info)) << err;
  EXPECT_TRUE(info.readable_by_others);
  EXPECT_EQ(info.mode, 0604u);
}

TEST(Aead, OpensOnlyWithTheSameKeyCounterAndAssociatedData) {
  Key k{};
  k[3] = 1;
  const std::vector<uint8_t> plain = {1, 2, 3, 4, 5}, ad = {9, 9};
  std::vector<uint8_t> sealed(plain.size() + kTagBytes), out(plain.size());
  aead_seal(k, 7, ad, plain, sealed.data());
  ASSERT_TRUE(aead_open(k, 7, ad, sealed, out.data()));
  EXPECT_EQ(out, plain);
  EXPECT_FALSE(aead_open(k, 8, ad, sealed, out.data()));
  EXPECT_FALSE(aead_open(k, 7, std::vector<uint8_t>{9, 8}, sealed, out.data()));
  Key other = k;
  other[0] ^= 1;
  EXPECT_FALSE(aead_open(other, 7, ad, sealed, out.data()));
  EXPECT_FALSE(aead_open(k, 7, ad, std::span(sealed).first(kTagBytes - 1), out.data()));
}

// ---- RFC 8439 known answers and the nonce layout ---------------------------
// The AEAD (crypto.h) is libsodium's crypto_aead_chacha20poly1305_ietf_*, the
// AEAD_CHACHA20_POLY1305 of RFC 8439 (96-bit nonce, 16-byte tag); the code
// uses ChaCha20 and Poly1305 only through it, so the AEAD vectors cover both.

std::vector<uint8_t> unhex(std::string_view h) {
  std::vector<uint8_t> out(h.size() / 2);
  size_t len = 0;
  EXPECT_EQ(sodium_hex2bin(out.data(), out.size(), h.data(), h.size(), nullptr, &len, nullptr), 0) << h;
  EXPECT_EQ(len, out.size()) << h;
  return out;
}

Key key_of(std::string_view h) {
  const auto b = unhex(h);
  Key k{};
  EXPECT_EQ(b.size(), k.size());
  std::copy_n(b.begin(), std::min(b.size(), k.size()), k.begin());
  return k;
}

// RFC 8439, section 2.8.2 (its nonce: constant 07 00 00 00, IV 40..47).
constexpr std::string_view k282Key = "808182838485868788898a8b8c8d8e8f909192939495969798999a9b9c9d9e9f";
constexpr std::string_view k282Nonce = "070000004041424344454647";
constexpr std::string_view k282Aad = "50515253c0c1c2c3c4c5c6c7";
constexpr std::string_view k282Plain =
    "Ladies and Gentlemen of the class of '99: If I could offer you only one tip for the future, sunscreen would be "
    "it.";
constexpr std::string_view k282Cipher =
    "d31a8d34648e60db7b86afbc53ef7ec2a4aded51296e08fea9e2b5a736ee62d63dbea45e8ca9671282fafb69da92728b1a71de0a9e060b29"
    "05d6a5b67ecd3b3692ddbd7f2d778b8c9803aee328091b58fab324e4fad675945585808b4831d7bc3ff4def08e4b7a9de576d26586cec64b"
    "6116";
constexpr std::string_view k282Tag = "1ae10b594f09e26a7e902ecbd0600691";

// RFC 8439, appendix A.5 (decryption): its nonce 00 00 00 00 01 02 .. 08 is
// exactly the link's layout, 0(4) || counter(8, BE), with counter
// 0x0102030405060708.
constexpr std::string_view kA5Key = "1c9240a5eb55d38af333888604f6b5f0473917c1402b80099dca5cbc207075c0";
constexpr uint64_t kA5Counter = 0x0102030405060708ull;
constexpr std::string_view kA5Aad = "f33388860000000000004e91";
constexpr std::string_view kA5Cipher =
    "64a0861575861af460f062c79be643bd5e805cfd345cf389f108670ac76c8cb24c6cfc18755d43eea09ee94e382d26b0bdb7b73c321b0100"
    "d4f03b7f355894cf332f830e710b97ce98c8a84abd0b948114ad176e008d33bd60f982b1ff37c8559797a06ef4f0ef61c186324e2b350638"
    "3606907b6a7c02b0f9f6157b53c867e4b9166c767b804d46a59b5216cde7a4e99040c5a40433225ee282a1b0a06c523eaf4534d7f83fa115"
    "5b0047718cbc546a0d072b04b3564eea1b422273f548271a0bb2316053fa76991955ebd63159434ecebb4e466dae5a1073a6727627097a10"
    "49e617d91d361094fa68f0ff77987130305beaba2eda04df997b714d6c6f2c29a6ad5cb4022b02709b";
constexpr std::string_view kA5Tag = "eead9d67890cbb22392336fea1851f38";
constexpr std::string_view kA5Plain =
    "Internet-Drafts are draft documents valid for a maximum of six months and may be updated, replaced, or obsoleted "
    "by other documents at any time. It is inappropriate to use Internet-Drafts as reference material or to cite them "
    "other than as /\xe2\x80\x9cwork in progress./\xe2\x80\x9d";

std::vector<uint8_t> bytes_of(std::string_view s) { return std::vector<uint8_t>(s.begin(), s.end()); }

TEST(AeadKnownAnswer, TheLibraryPrimitiveIsRfc8439Section282) {
  // The primitive aead_seal/aead_open call, with the RFC's own nonce (its
  // constant part is not ours, so not through aead_seal: see A.5 below).
  ASSERT_TRUE(crypto_init());
  const Key k = key_of(k282Key);
  const auto nonce = unhex(k282Nonce), ad = unhex(k282Aad), plain = bytes_of(k282Plain);
  ASSERT_EQ(nonce.size(), crypto_aead_chacha20poly1305_IETF_NPUBBYTES);
  std::vector<uint8_t> cipher(plain.size()), tag(kTagBytes);
  crypto_aead_chacha20poly1305_ietf_encrypt_detached(cipher.data(), tag.data(), nullptr, plain.data(), plain.size(),
                                                     ad.data(), ad.size(), nullptr, nonce.data(), k.data());
  EXPECT_EQ(cipher, unhex(k282Cipher));
  EXPECT_EQ(tag, unhex(k282Tag));
}

TEST(AeadKnownAnswer, AeadOpenAndSealReproduceRfc8439AppendixA5) {
  const Key k = key_of(kA5Key);
  const auto ad = unhex(kA5Aad), plain = bytes_of(kA5Plain);
  std::vector<uint8_t> sealed = unhex(kA5Cipher);
  ASSERT_EQ(sealed.size(), 265u);
  ASSERT_EQ(plain.size(), 265u);
  const auto tag = unhex(kA5Tag);
  sealed.insert(sealed.end(), tag.begin(), tag.end());
  std::vector<uint8_t> out(plain.size());
  ASSERT_TRUE(aead_open(k, kA5Counter, ad, sealed, out.data()));
  EXPECT_EQ(out, plain);
  std::vector<uint8_t> again(sealed.size());
  aead_seal(k, kA5Counter, ad, plain, again.data());
  EXPECT_EQ(again, sealed);
  // One bit anywhere (ciphertext, tag, associated data, counter) and it does not open.
  for (const size_t at : {size_t{0}, size_t{131}, sealed.size() - 1}) {
    std::vector<uint8_t> bad = sealed;
    bad[at] ^= 0x01;
    EXPECT_FALSE(aead_open(k, kA5Counter, ad, bad, out.data())) << at;
  }
  std::vector<uint8_t> bad_ad = ad;
  bad_ad[11] ^= 0x80;
  EXPECT_FALSE(aead_open(k, kA5Counter, bad_ad, sealed, out.data()));
  EXPECT_FALSE(aead_open(k, kA5Counter + 1, ad, sealed, out.data()));
}

// The nonce as crypto.h and docs/protocol.md define it: bytes
// 0-3 zero, bytes 4-11 the counter big-endian.
std::array<uint8_t, 12> link_nonce(uint64_t counter) {
  std::array<uint8_t, 12> n{};
  for (int i = 0; i < 8; ++i) n[static_cast<size_t>(11 - i)] = static_cast<uint8_t>(counter >> (8 * i));
  return n;
}

std::vector<uint8_t> seal_with_nonce(const Key& k, const std::array<uint8_t, 12>& nonce, std::span<const uint8_t> ad,
                                     std::span<const uint8_t> plain) {
  std::vector<uint8_t> out(plain.size() + kTagBytes);
  crypto_aead_chacha20poly1305_ietf_encrypt_detached(out.data(), out.data() + plain.size(), nullptr, plain.data(),
                                                     plain.size(), ad.data(), ad.size(), nullptr, nonce.data(),
                                                     k.data());
  return out;
}

TEST(AeadNonce, CounterIsBigEndianInBytes4To11AndBytes0To3AreZero) {
  ASSERT_TRUE(crypto_init());
  const Key k = key_of(kA5Key);
  const std::vector<uint8_t> ad = {1, 2, 3}, plain = bytes_of("nonce layout");
  for (const uint64_t c : {uint64_t{0}, uint64_t{1}, uint64_t{0x100}, kA5Counter, uint64_t{0xfedcba9876543210ull},
                           ~uint64_t{0}}) {
    SCOPED_TRACE(c);
    std::vector<uint8_t> mine(plain.size() + kTagBytes);
    aead_seal(k, c, ad, plain, mine.data());
    EXPECT_EQ(mine, seal_with_nonce(k, link_nonce(c), ad, plain));
    // Neither little-endian, nor in bytes 0-7, nor with a non-zero prefix.
    std::array<uint8_t, 12> le{}, front{}, prefix = link_nonce(c);
    for (int i = 0; i < 8; ++i) {
      le[static_cast<size_t>(4 + i)] = static_cast<uint8_t>(c >> (8 * i));
      front[static_cast<size_t>(7 - i)] = static_cast<uint8_t>(c >> (8 * i));
    }
    prefix[0] = 1;
    if (le != link_nonce(c)) {
      EXPECT_NE(mine, seal_with_nonce(k, le, ad, plain));
    }
    if (front != link_nonce(c)) {
      EXPECT_NE(mine, seal_with_nonce(k, front, ad, plain));
    }
    EXPECT_NE(mine, seal_with_nonce(k, prefix, ad, plain));
  }
}

TEST(AeadNonce, DatagramNonceIsItsHeaderSequenceNumber) {
  // A datagram (sequence number 0x0102030405060708) carrying RFC 8439 A.5's
  // plaintext under A.5's key: its ciphertext is A.5's (ChaCha20's stream
  // depends on key and nonce only); its tag covers the header, bytes [0, 28).
  const Key k = key_of(kA5Key);
  const auto plain = bytes_of(kA5Plain);
  DatagramHeader h;
  h.session_id = 0x1122334455667788ull;
  h.seq = kA5Counter;
  h.send_time_ns = 123456789;
  std::vector<uint8_t> d;
  ASSERT_TRUE(encode_datagram(k, h, plain, &d));
  ASSERT_EQ(d.size(), kDatagramHeaderBytes + plain.size() + kTagBytes);
  const std::vector<uint8_t> seq_bytes(d.begin() + 12, d.begin() + 20);
  EXPECT_EQ(seq_bytes, unhex("0102030405060708"));  // bytes 12-19 of the header
  EXPECT_EQ(std::vector<uint8_t>(d.begin() + kDatagramHeaderBytes, d.end() - kTagBytes), unhex(kA5Cipher));
  const std::span<const uint8_t> header(d.data(), kDatagramHeaderBytes);
  EXPECT_EQ(std::vector<uint8_t>(d.begin() + kDatagramHeaderBytes, d.end()),
            seal_with_nonce(k, link_nonce(kA5Counter), header, plain));
}

TEST(AeadNonce, SessionFrameNonceIsTheImplicitFrameCounterFromZero) {
  ASSERT_TRUE(crypto_init());
  const Key k = key_of(kA5Key);
  FrameSealer sealer(k);
  for (uint64_t c = 0; c < 3; ++c) {
    const std::vector<uint8_t> payload = {static_cast<uint8_t>(c), 7, 7};
    const std::vector<uint8_t> sealed = sealer.seal(payload);
    // Associated data: the frame's 4-byte length header (big-endian).
    const std::vector<uint8_t> len = {0, 0, 0, static_cast<uint8_t>(payload.size() + kTagBytes)};
    EXPECT_EQ(sealed, seal_with_nonce(k, link_nonce(c), len, payload)) << c;
  }
}

}  // namespace
}  // namespace hemm::net
