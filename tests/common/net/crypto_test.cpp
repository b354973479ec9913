// Key files and the key rules: libsodium hex parsing, weak keys refused, the
// committed demo key recognised, permissions reported.
#include "common/net/crypto.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <fstream>
#include <random>

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
  const std::string path = ::testing::TempDir() + name;
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

}  // namespace
}  // namespace hemm::net
