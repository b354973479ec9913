// MCAP files (https://mcap.dev/spec, major version 0), written and read from
// the public specification: there is no MCAP library in Debian 12.
//
// The writer puts every Schema, Channel and Message record in zstd-compressed
// Chunks (each with the CRC-32 of its uncompressed records), follows each
// chunk with one Message Index per channel in it, ends the data section with
// Data End (the CRC-32 of every byte before it, leading magic included), and
// writes a summary section (Schema, Channel, Statistics, Chunk Index groups),
// a Summary Offset per group, and the Footer with the summary's CRC-32.
// Readers that skip the index (stream readers) and readers that seek through
// it (Foxglove Studio, the mcap CLI) both open it.
//
// The reader is the one the replay needs (hemm-operator --replay FILE.mcap):
// it walks the data section from the start, checks every CRC it meets and
// the record layout, and hands over schemas, channels and messages. Bad input
// (truncation, a wrong length, a bad CRC, a compression it does not know) is
// an error naming the byte offset; nothing is handed over past it.
//
// zstd and the CRC (zlib) stay in mcap_file.cpp: this header includes neither.
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hemm::mcap {

inline constexpr char kMagic[8] = {'\x89', 'M', 'C', 'A', 'P', '0', '\r', '\n'};

enum Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kStatistics = 0x0b,
  kSummaryOffset = 0x0e,
  kDataEnd = 0x0f,
};

struct WriterOptions {
  std::string profile;                     // "" : none of the well-known ones
  std::string library = "hemm";            // the Header's library field
  std::size_t chunk_bytes = 1u << 20;      // a chunk is closed past this many uncompressed bytes
  int zstd_level = 3;
};

// What a finished file holds (the Statistics record's figures).
struct WriterStats {
  std::uint64_t messages = 0;
  std::uint32_t chunks = 0;
  std::uint64_t bytes = 0;                 // the file's size
  std::uint64_t uncompressed_bytes = 0;    // of the chunks' records
  std::map<std::uint16_t, std::uint64_t> channel_messages;
};

class Writer {
 public:
  // Creates (truncates) `path` and writes the magic and Header. Throws
  // std::runtime_error if it cannot.
  Writer(const std::string& path, const WriterOptions& o = {});
  ~Writer();  // an unclosed file is closed (errors then are lost: call close())
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Ids from 1, in call order. `data`: for encoding "protobuf" a binary
  // FileDescriptorSet holding the message type `name` and its imports.
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  // Throws std::invalid_argument for a channel it did not add.
  void write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time, std::uint64_t publish_time,
             const std::string& data);
  // The last chunk, Data End, the summary, the footer, the closing magic.
  // Throws std::runtime_error on a write error. Idempotent.
  WriterStats close();

 private:
  struct ChunkIndexEntry {
    std::uint64_t start_time, end_time, offset, length;
    std::map<std::uint16_t, std::uint64_t> index_offsets;
    std::uint64_t index_length, compressed, uncompressed;
  };
  void flush_chunk();
  void put(const std::string& bytes);  // to the file, counted and checksummed
  void append_record(std::string* out, Opcode op, const std::string& body) const;

  std::FILE* file_ = nullptr;
  std::string path_;
  WriterOptions o_;
  std::uint64_t offset_ = 0;
  std::uint32_t data_crc_ = 0;  // running CRC-32 of the bytes before Data End
  bool failed_ = false, closed_ = false;
  std::vector<std::string> schemas_, channels_;  // their records' bodies, for the summary
  // The open chunk.
  std::string chunk_;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  bool chunk_has_messages_ = false;
  std::vector<ChunkIndexEntry> chunk_entries_;
  std::uint64_t start_time_ = 0, end_time_ = 0;
  WriterStats stats_;
};

// ---------------------------------------------------------------- reading

struct Schema {
  std::uint16_t id = 0;
  std::string name, encoding, data;
};
struct Channel {
  std::uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;
  std::map<std::string, std::string> metadata;
};
struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::uint64_t log_time = 0, publish_time = 0;
  std::string data;
};

struct ReadCallbacks {
  std::function<void(const Schema&)> on_schema;
  std::function<void(const Channel&)> on_channel;
  std::function<void(const Message&)> on_message;
};

// True if the file starts with the MCAP magic.
bool looks_like_mcap(const std::string& path);

// Reads the data section of `path` in file order (decompressing chunks),
// calling back for every schema, channel and message record; checks the
// magic, each record's length, each chunk's CRC, that every message's
// channel and every channel's schema came first, and the Data End CRC. An
// error ("FILE: byte B: why") stops it there.
std::optional<std::string> read_file(const std::string& path, const ReadCallbacks& cb);

}  // namespace hemm::mcap
