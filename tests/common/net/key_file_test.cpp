// Key files (issue 23 item 7): the size is checked before anything is read
// (a huge or endless file costs nothing), and the key's text never sits in a
// heap buffer that is freed without being wiped: it is read into one local
// buffer, which is wiped.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "common/net/crypto.h"
#include "tests/operator/servo/alloc_counter.h"

namespace hemm::net {
namespace {

const std::string kKeyText = "5d0c3a9e7b21f4866ac1d8e93f0b7254c6e18a2d9f3b5e07a4c92d61f8b0e375\n";

std::string temp_dir() {
  std::string t = ::testing::TempDir() + "hemm_key_file_XXXXXX";
  if (::mkdtemp(t.data()) == nullptr) ADD_FAILURE() << "mkdtemp failed";
  return t + "/";
}

std::string write_file(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  ::chmod(path.c_str(), 0600);
  return path;
}

// Bytes this process has read through read() and friends so far.
std::optional<unsigned long long> bytes_read() {
  std::FILE* f = std::fopen("/proc/self/io", "r");
  if (f == nullptr) return std::nullopt;
  unsigned long long rchar = 0;
  const int n = std::fscanf(f, "rchar: %llu", &rchar);
  std::fclose(f);
  if (n != 1) return std::nullopt;
  return rchar;
}

TEST(KeyFile, ASizeBeyondTheLimitIsRefusedBeforeAnyOfItIsRead) {
  const std::string path = write_file(temp_dir() + "huge.key", kKeyText);
  ASSERT_EQ(::truncate(path.c_str(), 64ll << 20), 0);  // 64 MiB, sparse: a valid key and then zeros
  std::string err;
  const auto before = bytes_read();
  ASSERT_TRUE(before) << "/proc/self/io is not readable";
  const auto key = load_key_file(path, &err);
  const auto after = bytes_read();
  std::printf("a 64 MiB key file: refused with \"%s\" after reading %llu bytes\n", err.c_str(), *after - *before);
  EXPECT_FALSE(key);
  EXPECT_NE(err.find("too large"), std::string::npos) << err;
  EXPECT_LT(*after - *before, 64u * 1024u);
}

TEST(KeyFile, IsReadWithoutACopyOfItsTextOnTheHeap) {
  const std::string path = write_file(temp_dir() + "station.key", kKeyText);
  std::string err;
  ASSERT_TRUE(load_key_file(path, &err)) << err;  // warm-up (libsodium's first use)
  KeyFileInfo info;
  test::count_allocations_on_this_thread(true);
  const uint64_t before = test::counted_allocations();
  const auto key = load_key_file(path, &err, &info);
  const uint64_t allocations = test::counted_allocations() - before;
  test::count_allocations_on_this_thread(false);
  ASSERT_TRUE(key) << err;
  EXPECT_EQ(allocations, 0u) << "the key file's text went through the heap";
  EXPECT_EQ(info.mode, 0600u);
}

// Not a regular file (a device that never ends, a FIFO that never opens for
// writing): refused before reading, at once.
TEST(KeyFile, ADeviceOrAFifoIsRefusedWithoutReadingIt) {
  std::string err;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(load_key_file("/dev/zero", &err));
  EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
  const std::string fifo = temp_dir() + "key.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_FALSE(load_key_file(fifo, &err));
  EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
}

}  // namespace
}  // namespace hemm::net
