// MCAP writing and reading (operator/record/mcap_file.h): what is written
// reads back in order on its channels, across several chunks; the file's
// frame (magic, header, data end, footer) sits where the specification puts
// it; a flipped byte in a chunk, a cut file, a message before its channel
// and a foreign file are refused with the byte offset. The independent
// check of the format (a reader written from the specification in Python)
// is tests/integration/record/mcap_export_test.cpp.
#include "operator/record/mcap_file.h"

#include "tests/integration/link/child_process.h"

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

namespace hm = hemm::mcap;

namespace {

using hemm::test::read_file;

// A file in this process's own temporary directory.
std::string temp_path(const std::string& name) {
  static const std::string dir = hemm::test::make_temp_dir();
  return dir + "/" + name;
}
void write_bytes(const std::string& p, const std::string& b) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
}
std::uint64_t le64(const std::string& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
  return v;
}

struct Read {
  std::vector<hm::Schema> schemas;
  std::vector<hm::Channel> channels;
  std::vector<hm::Message> messages;
  std::optional<std::string> error;
};
Read read(const std::string& path) {
  Read r;
  hm::ReadCallbacks cb;
  cb.on_schema = [&](const hm::Schema& s) { r.schemas.push_back(s); };
  cb.on_channel = [&](const hm::Channel& c) { r.channels.push_back(c); };
  cb.on_message = [&](const hm::Message& m) { r.messages.push_back(m); };
  r.error = hm::read_file(path, cb);
  return r;
}

// Two channels, 3000 messages of 100 bytes: several chunks of 64 kB.
std::string small_file(hm::WriterStats* stats = nullptr) {
  const std::string path = temp_path("small.mcap");
  hm::WriterOptions o;
  o.chunk_bytes = 64 * 1024;
  hm::Writer w(path, o);
  const auto s = w.add_schema("pkg.Type", "protobuf", std::string("\x0a\x03\x61\x62\x63", 5));
  const auto a = w.add_channel(s, "/a", "protobuf", {{"k", "v"}});
  const auto b = w.add_channel(s, "/b", "protobuf");
  for (std::uint32_t i = 0; i < 3000; ++i)
    w.write(i % 3 == 0 ? b : a, i, 1'000'000'000ull + i * 1000ull, 2'000'000'000ull + i,
            std::string(100, static_cast<char>('a' + i % 26)));
  const hm::WriterStats st = w.close();
  if (stats) *stats = st;
  return path;
}

TEST(McapFile, WhatIsWrittenReadsBackInOrder) {
  hm::WriterStats st;
  const std::string path = small_file(&st);
  EXPECT_EQ(st.messages, 3000u);
  EXPECT_GT(st.chunks, 3u);
  EXPECT_EQ(st.channel_messages.at(1), 2000u);
  EXPECT_EQ(st.channel_messages.at(2), 1000u);
  EXPECT_EQ(st.bytes, std::filesystem::file_size(path));
  EXPECT_LT(st.bytes, st.uncompressed_bytes / 4) << "zstd on repeated bytes";
  const Read r = read(path);
  ASSERT_FALSE(r.error) << *r.error;
  ASSERT_EQ(r.schemas.size(), 1u);
  EXPECT_EQ(r.schemas[0].name, "pkg.Type");
  EXPECT_EQ(r.schemas[0].encoding, "protobuf");
  EXPECT_EQ(r.schemas[0].data, std::string("\x0a\x03\x61\x62\x63", 5));
  ASSERT_EQ(r.channels.size(), 2u);
  EXPECT_EQ(r.channels[0].topic, "/a");
  EXPECT_EQ(r.channels[0].metadata.at("k"), "v");
  EXPECT_EQ(r.channels[1].schema_id, 1);
  ASSERT_EQ(r.messages.size(), 3000u);
  for (std::uint32_t i = 0; i < 3000; ++i) {
    const hm::Message& m = r.messages[i];
    ASSERT_EQ(m.sequence, i);
    EXPECT_EQ(m.channel_id, i % 3 == 0 ? 2 : 1);
    EXPECT_EQ(m.log_time, 1'000'000'000ull + i * 1000ull);
    EXPECT_EQ(m.publish_time, 2'000'000'000ull + i);
    EXPECT_EQ(m.data, std::string(100, static_cast<char>('a' + i % 26)));
  }
  std::filesystem::remove(path);
}

TEST(McapFile, FrameIsWhereTheSpecificationPutsIt) {
  const std::string path = small_file();
  const std::string b = read_file(path);
  ASSERT_GT(b.size(), 100u);
  EXPECT_EQ(b.substr(0, 8), std::string(hm::kMagic, 8));
  EXPECT_EQ(b.substr(b.size() - 8), std::string(hm::kMagic, 8));
  EXPECT_EQ(b[8], hm::kHeader);
  // The footer: opcode, length 20, two offsets and a CRC, before the magic.
  const std::size_t footer = b.size() - 8 - 29;
  EXPECT_EQ(b[footer], hm::kFooter);
  EXPECT_EQ(le64(b, footer + 1), 20u);
  const std::uint64_t summary_start = le64(b, footer + 9), summary_offsets = le64(b, footer + 17);
  ASSERT_LT(summary_start, summary_offsets);
  ASSERT_LT(summary_offsets, footer);
  // Data End (opcode, length 4, CRC) right before the summary; the summary
  // starts with the schema group and its offsets with a Summary Offset.
  EXPECT_EQ(b[summary_start - 13], hm::kDataEnd);
  EXPECT_EQ(le64(b, summary_start - 12), 4u);
  EXPECT_EQ(b[summary_start], hm::kSchema);
  EXPECT_EQ(b[summary_offsets], hm::kSummaryOffset);
  std::filesystem::remove(path);
}

TEST(McapFile, FlippedByteInAChunkIsRefusedWithItsOffset) {
  const std::string path = small_file();
  std::string b = read_file(path);
  // The first chunk follows the header record; flip a byte of its
  // compressed records (past the chunk's fixed fields).
  const std::size_t header_len = 9 + le64(b, 9);
  const std::size_t chunk = 8 + header_len;
  ASSERT_EQ(b[chunk], hm::kChunk);
  b[chunk + 9 + 50 + 200] ^= 0x10;
  const std::string bad = temp_path("flipped.mcap");
  write_bytes(bad, b);
  const Read r = read(bad);
  ASSERT_TRUE(r.error);
  EXPECT_NE(r.error->find("byte " + std::to_string(chunk)), std::string::npos) << *r.error;
  // zstd notices some corruptions itself, the CRC the rest.
  EXPECT_TRUE(r.error->find("CRC mismatch") != std::string::npos || r.error->find("zstd") != std::string::npos ||
              r.error->find("decompressed to") != std::string::npos)
      << *r.error;
  EXPECT_TRUE(r.messages.empty()) << "nothing of the bad chunk is handed over";
  std::filesystem::remove(path);
  std::filesystem::remove(bad);
}

TEST(McapFile, CutFileAndForeignFileAreRefused) {
  const std::string path = small_file();
  const std::string b = read_file(path);
  const std::string cut = temp_path("cut.mcap");
  write_bytes(cut, b.substr(0, b.size() / 2));
  Read r = read(cut);
  ASSERT_TRUE(r.error);
  EXPECT_NE(r.error->find("runs past the end"), std::string::npos) << *r.error;
  EXPECT_LT(r.messages.size(), 3000u);
  write_bytes(cut, "hemm-recording, not mcap");
  EXPECT_FALSE(hm::looks_like_mcap(cut));
  r = read(cut);
  ASSERT_TRUE(r.error);
  EXPECT_NE(r.error->find("not an MCAP file"), std::string::npos) << *r.error;
  EXPECT_TRUE(hm::looks_like_mcap(path));
  std::filesystem::remove(path);
  std::filesystem::remove(cut);
}

TEST(McapFile, EveryFlippedByteBeforeDataEndIsRefused) {
  // Hostile input: 300 copies, each with one byte flipped somewhere. Before
  // the Data End record every byte is under a CRC (a chunk's or the data
  // section's) or a length, so each copy is refused; after it (the summary,
  // which this reader does not need) a copy may read. None may crash (the
  // sanitizer build runs this too).
  const std::string path = small_file();
  const std::string b = read_file(path);
  const std::size_t footer = b.size() - 8 - 29;
  const std::size_t summary_start = static_cast<std::size_t>(le64(b, footer + 9));
  const std::size_t data_end = summary_start - 13;
  const std::string bad = temp_path("flip.mcap");
  std::uint64_t state = 12345;
  for (int i = 0; i < 300; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const std::size_t at = static_cast<std::size_t>((state >> 33) % b.size());
    std::string c = b;
    c[at] = static_cast<char>(c[at] ^ (1 << ((state >> 20) % 8)));
    write_bytes(bad, c);
    const Read r = read(bad);
    if (at < data_end + 13) {
      EXPECT_TRUE(r.error.has_value()) << "byte " << at << " flipped, file read";
    }
  }
  std::filesystem::remove(path);
  std::filesystem::remove(bad);
}

TEST(McapFile, WriterRefusesUnknownChannelsAndSchemas) {
  const std::string path = temp_path("refuse.mcap");
  hm::Writer w(path);
  EXPECT_THROW(w.add_channel(3, "/x", "protobuf"), std::invalid_argument);
  EXPECT_THROW(w.write(1, 0, 0, 0, "x"), std::invalid_argument);
  const auto c = w.add_channel(0, "/schemaless", "json");
  w.write(c, 0, 5, 5, "{}");
  w.close();
  EXPECT_THROW(w.write(c, 1, 6, 6, "{}"), std::logic_error);
  const Read r = read(path);
  ASSERT_FALSE(r.error) << *r.error;
  ASSERT_EQ(r.messages.size(), 1u);
  EXPECT_EQ(r.channels[0].schema_id, 0);
  EXPECT_THROW(hm::Writer("/nonexistent-dir/x.mcap"), std::runtime_error);
  std::filesystem::remove(path);
}

}  // namespace
