#include "operator/record/mcap_file.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <tuple>

namespace hemm::mcap {
namespace {

// CRC-32 (the one of zlib, PNG and the MCAP specification), continued from `crc`.
std::uint32_t crc32_of(const char* data, std::size_t n, std::uint32_t crc = 0) {
  uLong c = crc;
  while (n > 0) {  // zlib takes a uInt length
    const uInt step = n > (1u << 30) ? (1u << 30) : static_cast<uInt>(n);
    c = ::crc32(c, reinterpret_cast<const Bytef*>(data), step);
    data += step;
    n -= step;
  }
  return static_cast<std::uint32_t>(c);
}

// Little-endian serialization (MCAP "Serialization").
template <typename T>
void put_le(std::string* out, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) out->push_back(static_cast<char>((static_cast<std::uint64_t>(v) >> (8 * i)) & 0xff));
}
void put_string(std::string* out, const std::string& s) {
  put_le<std::uint32_t>(out, static_cast<std::uint32_t>(s.size()));
  *out += s;
}
void put_string_map(std::string* out, const std::map<std::string, std::string>& m) {
  std::string entries;
  for (const auto& [k, v] : m) {
    put_string(&entries, k);
    put_string(&entries, v);
  }
  put_string(out, entries);  // a uint32 byte length, then the entries
}
void put_count_map(std::string* out, const std::map<std::uint16_t, std::uint64_t>& m) {
  put_le<std::uint32_t>(out, static_cast<std::uint32_t>(m.size() * 10));
  for (const auto& [k, v] : m) {
    put_le<std::uint16_t>(out, k);
    put_le<std::uint64_t>(out, v);
  }
}

}  // namespace

// ---------------------------------------------------------------- writer

Writer::Writer(const std::string& path, const WriterOptions& o) : path_(path), o_(o) {
  if (o_.chunk_bytes == 0) throw std::invalid_argument("mcap::Writer: chunk_bytes must be positive");
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr) throw std::runtime_error("cannot open " + path + " for writing");
  std::string head(kMagic, sizeof kMagic);
  std::string header;
  put_string(&header, o_.profile);
  put_string(&header, o_.library);
  append_record(&head, kHeader, header);
  put(head);
  if (failed_) {
    std::fclose(file_);
    file_ = nullptr;
    throw std::runtime_error("cannot write to " + path);
  }
}

Writer::~Writer() {
  try {
    close();
  } catch (...) {
  }
}

void Writer::append_record(std::string* out, Opcode op, const std::string& body) const {
  out->push_back(static_cast<char>(op));
  put_le<std::uint64_t>(out, body.size());
  *out += body;
}

void Writer::put(const std::string& bytes) {
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) failed_ = true;
  data_crc_ = crc32_of(bytes.data(), bytes.size(), data_crc_);
  offset_ += bytes.size();
}

std::uint16_t Writer::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  if (closed_) throw std::logic_error("mcap::Writer: add_schema after close");
  if (schemas_.size() >= 0xffff) throw std::length_error("mcap::Writer: too many schemas");
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);
  std::string body;
  put_le<std::uint16_t>(&body, id);
  put_string(&body, name);
  put_string(&body, encoding);
  put_string(&body, data);  // uint32 length-prefixed bytes
  append_record(&chunk_, kSchema, body);
  schemas_.push_back(std::move(body));
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                                  const std::map<std::string, std::string>& metadata) {
  if (closed_) throw std::logic_error("mcap::Writer: add_channel after close");
  if (schema_id > schemas_.size()) throw std::invalid_argument("mcap::Writer: unknown schema " + std::to_string(schema_id));
  if (channels_.size() >= 0xffff) throw std::length_error("mcap::Writer: too many channels");
  const auto id = static_cast<std::uint16_t>(channels_.size() + 1);
  std::string body;
  put_le<std::uint16_t>(&body, id);
  put_le<std::uint16_t>(&body, schema_id);
  put_string(&body, topic);
  put_string(&body, message_encoding);
  put_string_map(&body, metadata);
  append_record(&chunk_, kChannel, body);
  channels_.push_back(std::move(body));
  return id;
}

void Writer::write(std::uint16_t channel_id, std::uint32_t sequence, std::uint64_t log_time,
                   std::uint64_t publish_time, const std::string& data) {
  if (closed_) throw std::logic_error("mcap::Writer: write after close");
  if (channel_id == 0 || channel_id > channels_.size())
    throw std::invalid_argument("mcap::Writer: unknown channel " + std::to_string(channel_id));
  chunk_index_[channel_id].emplace_back(log_time, chunk_.size());
  std::string body;
  body.reserve(22 + data.size());
  put_le<std::uint16_t>(&body, channel_id);
  put_le<std::uint32_t>(&body, sequence);
  put_le<std::uint64_t>(&body, log_time);
  put_le<std::uint64_t>(&body, publish_time);
  body += data;
  append_record(&chunk_, kMessage, body);
  if (!chunk_has_messages_) {
    chunk_start_ = chunk_end_ = log_time;
    chunk_has_messages_ = true;
  } else {
    chunk_start_ = std::min(chunk_start_, log_time);
    chunk_end_ = std::max(chunk_end_, log_time);
  }
  if (stats_.messages == 0) {
    start_time_ = end_time_ = log_time;
  } else {
    start_time_ = std::min(start_time_, log_time);
    end_time_ = std::max(end_time_, log_time);
  }
  ++stats_.messages;
  ++stats_.channel_messages[channel_id];
  if (chunk_.size() >= o_.chunk_bytes) flush_chunk();
}

void Writer::flush_chunk() {
  if (chunk_.empty()) return;
  std::string compressed(ZSTD_compressBound(chunk_.size()), '\0');
  const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_.data(), chunk_.size(), o_.zstd_level);
  if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
  compressed.resize(n);
  std::string body;
  put_le<std::uint64_t>(&body, chunk_has_messages_ ? chunk_start_ : 0);
  put_le<std::uint64_t>(&body, chunk_has_messages_ ? chunk_end_ : 0);
  put_le<std::uint64_t>(&body, chunk_.size());
  put_le<std::uint32_t>(&body, crc32_of(chunk_.data(), chunk_.size()));
  put_string(&body, "zstd");
  put_le<std::uint64_t>(&body, compressed.size());
  body += compressed;
  std::string record;
  append_record(&record, kChunk, body);
  ChunkIndexEntry e{};
  e.start_time = chunk_has_messages_ ? chunk_start_ : 0;
  e.end_time = chunk_has_messages_ ? chunk_end_ : 0;
  e.offset = offset_;
  e.length = record.size();
  e.compressed = compressed.size();
  e.uncompressed = chunk_.size();
  put(record);
  // One Message Index per channel with messages in the chunk, right after it.
  const std::uint64_t index_start = offset_;
  for (const auto& [channel, entries] : chunk_index_) {
    std::string ib;
    put_le<std::uint16_t>(&ib, channel);
    put_le<std::uint32_t>(&ib, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [t, off] : entries) {
      put_le<std::uint64_t>(&ib, t);
      put_le<std::uint64_t>(&ib, off);
    }
    std::string ir;
    append_record(&ir, kMessageIndex, ib);
    e.index_offsets[channel] = offset_;
    put(ir);
  }
  e.index_length = offset_ - index_start;
  chunk_entries_.push_back(std::move(e));
  stats_.uncompressed_bytes += chunk_.size();
  ++stats_.chunks;
  chunk_.clear();
  chunk_index_.clear();
  chunk_has_messages_ = false;
}

WriterStats Writer::close() {
  if (closed_) return stats_;
  closed_ = true;
  flush_chunk();
  std::string data_end;
  {
    std::string body;
    put_le<std::uint32_t>(&body, data_crc_);  // every byte before this record
    append_record(&data_end, kDataEnd, body);
  }
  put(data_end);
  // The summary: records grouped by opcode, each group found by a Summary Offset.
  const std::uint64_t summary_start = offset_;
  std::string summary;
  std::vector<std::tuple<Opcode, std::uint64_t, std::uint64_t>> groups;
  auto group = [&](Opcode op, const std::vector<std::string>& bodies) {
    if (bodies.empty()) return;
    const std::uint64_t start = summary_start + summary.size();
    for (const std::string& b : bodies) append_record(&summary, op, b);
    groups.emplace_back(op, start, summary_start + summary.size() - start);
  };
  group(kSchema, schemas_);
  group(kChannel, channels_);
  {
    std::string s;
    put_le<std::uint64_t>(&s, stats_.messages);
    put_le<std::uint16_t>(&s, static_cast<std::uint16_t>(schemas_.size()));
    put_le<std::uint32_t>(&s, static_cast<std::uint32_t>(channels_.size()));
    put_le<std::uint32_t>(&s, 0);  // attachments
    put_le<std::uint32_t>(&s, 0);  // metadata
    put_le<std::uint32_t>(&s, stats_.chunks);
    put_le<std::uint64_t>(&s, start_time_);
    put_le<std::uint64_t>(&s, end_time_);
    put_count_map(&s, stats_.channel_messages);
    group(kStatistics, {s});
  }
  std::vector<std::string> chunk_index;
  for (const ChunkIndexEntry& e : chunk_entries_) {
    std::string b;
    put_le<std::uint64_t>(&b, e.start_time);
    put_le<std::uint64_t>(&b, e.end_time);
    put_le<std::uint64_t>(&b, e.offset);
    put_le<std::uint64_t>(&b, e.length);
    put_count_map(&b, e.index_offsets);
    put_le<std::uint64_t>(&b, e.index_length);
    put_string(&b, "zstd");
    put_le<std::uint64_t>(&b, e.compressed);
    put_le<std::uint64_t>(&b, e.uncompressed);
    chunk_index.push_back(std::move(b));
  }
  group(kChunkIndex, chunk_index);
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const auto& [op, start, length] : groups) {
    std::string b;
    put_le<std::uint8_t>(&b, op);
    put_le<std::uint64_t>(&b, start);
    put_le<std::uint64_t>(&b, length);
    append_record(&summary, kSummaryOffset, b);
  }
  // The footer; its CRC covers the summary, the summary offsets and the
  // footer up to the CRC field.
  std::string tail = summary;
  tail.push_back(static_cast<char>(kFooter));
  put_le<std::uint64_t>(&tail, 20);
  put_le<std::uint64_t>(&tail, summary_start);
  put_le<std::uint64_t>(&tail, summary_offset_start);
  put_le<std::uint32_t>(&tail, crc32_of(tail.data(), tail.size()));
  tail.append(kMagic, sizeof kMagic);
  put(tail);
  stats_.bytes = offset_;
  if (std::fclose(file_) != 0) failed_ = true;
  file_ = nullptr;
  if (failed_) throw std::runtime_error("writing " + path_ + " failed");
  return stats_;
}

// ---------------------------------------------------------------- reader

namespace {

// Bounds-checked little-endian fields of one record.
struct Cursor {
  const char* p;
  std::size_t n, at = 0;
  bool ok = true;
  template <typename T>
  T le() {
    if (!ok || n - at < sizeof(T)) {
      ok = false;
      return T{};
    }
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(p[at + i])) << (8 * i);
    at += sizeof(T);
    return static_cast<T>(v);
  }
  std::string bytes(std::uint64_t len) {
    if (!ok || n - at < len) {
      ok = false;
      return {};
    }
    std::string s(p + at, static_cast<std::size_t>(len));
    at += static_cast<std::size_t>(len);
    return s;
  }
  std::string str() { return bytes(le<std::uint32_t>()); }
};

// The largest chunk this reader decompresses (a writer's chunk is ~1 MB).
constexpr std::uint64_t kMaxChunkBytes = 1ull << 30;

struct Reader {
  const ReadCallbacks& cb;
  std::map<std::uint16_t, bool> schemas, channels;

  std::optional<std::string> record(std::uint8_t op, const char* body, std::size_t n) {
    Cursor c{body, n};
    switch (op) {
      case kSchema: {
        Schema s;
        s.id = c.le<std::uint16_t>();
        s.name = c.str();
        s.encoding = c.str();
        s.data = c.str();
        if (!c.ok) return "a Schema record shorter than its fields";
        if (s.id == 0) return std::nullopt;  // invalid: ignored, as the specification says
        schemas[s.id] = true;
        if (cb.on_schema) cb.on_schema(s);
        return std::nullopt;
      }
      case kChannel: {
        Channel ch;
        ch.id = c.le<std::uint16_t>();
        ch.schema_id = c.le<std::uint16_t>();
        ch.topic = c.str();
        ch.message_encoding = c.str();
        const std::string meta = c.str();
        if (!c.ok) return "a Channel record shorter than its fields";
        Cursor m{meta.data(), meta.size()};
        while (m.ok && m.at < m.n) {
          std::string k = m.str(), v = m.str();
          if (m.ok) ch.metadata[k] = v;
        }
        if (!m.ok) return "channel " + std::to_string(ch.id) + ": a metadata map past its length";
        if (ch.schema_id != 0 && !schemas.count(ch.schema_id))
          return "channel " + std::to_string(ch.id) + " names schema " + std::to_string(ch.schema_id) +
                 ", not defined before it";
        channels[ch.id] = true;
        if (cb.on_channel) cb.on_channel(ch);
        return std::nullopt;
      }
      case kMessage: {
        Message m;
        m.channel_id = c.le<std::uint16_t>();
        m.sequence = c.le<std::uint32_t>();
        m.log_time = c.le<std::uint64_t>();
        m.publish_time = c.le<std::uint64_t>();
        if (!c.ok) return "a Message record shorter than its fields";
        if (!channels.count(m.channel_id))
          return "a message on channel " + std::to_string(m.channel_id) + ", not defined before it";
        m.data.assign(body + c.at, n - c.at);
        if (cb.on_message) cb.on_message(m);
        return std::nullopt;
      }
      default: return std::nullopt;  // index records, attachments, metadata, unknown opcodes: skipped
    }
  }

  std::optional<std::string> chunk(const char* body, std::size_t n) {
    Cursor c{body, n};
    c.le<std::uint64_t>();  // start time
    c.le<std::uint64_t>();  // end time
    const std::uint64_t size = c.le<std::uint64_t>();
    const std::uint32_t crc = c.le<std::uint32_t>();
    const std::string compression = c.str();
    const std::uint64_t len = c.le<std::uint64_t>();
    if (!c.ok || n - c.at < len) return "a Chunk record shorter than its fields";
    if (size > kMaxChunkBytes) return "a chunk of " + std::to_string(size) + " bytes uncompressed (over 1 GiB)";
    const char* data = body + c.at;
    std::string plain;
    if (compression.empty()) {
      if (len != size) return "an uncompressed chunk whose size fields disagree";
      plain.assign(data, static_cast<std::size_t>(len));
    } else if (compression == "zstd") {
      plain.resize(static_cast<std::size_t>(size));
      const std::size_t got = ZSTD_decompress(plain.data(), plain.size(), data, static_cast<std::size_t>(len));
      if (ZSTD_isError(got)) return std::string("zstd: ") + ZSTD_getErrorName(got);
      if (got != size) return "a chunk that decompressed to " + std::to_string(got) + " bytes, not " + std::to_string(size);
    } else {
      return "chunk compression '" + compression + "' is not read here (zstd or none)";
    }
    if (crc != 0 && crc32_of(plain.data(), plain.size()) != crc) return "chunk CRC mismatch (corrupt)";
    std::size_t at = 0;
    while (at < plain.size()) {
      if (plain.size() - at < 9) return "a record inside a chunk cut short";
      Cursor h{plain.data() + at, 9};
      const auto op = h.le<std::uint8_t>();
      const std::uint64_t rlen = h.le<std::uint64_t>();
      if (rlen > plain.size() - at - 9) return "a record inside a chunk longer than the chunk";
      if (auto e = record(op, plain.data() + at + 9, static_cast<std::size_t>(rlen)))
        return "in the chunk's record at " + std::to_string(at) + ": " + *e;
      at += 9 + static_cast<std::size_t>(rlen);
    }
    return std::nullopt;
  }
};

}  // namespace

bool looks_like_mcap(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char head[sizeof kMagic] = {};
  f.read(head, sizeof head);
  return f.gcount() == sizeof head && std::memcmp(head, kMagic, sizeof head) == 0;
}

std::optional<std::string> read_file(const std::string& path, const ReadCallbacks& cb) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return "cannot open " + path;
  const std::string d((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) return "cannot read " + path;
  auto at = [&](std::size_t pos, const std::string& why) { return path + ": byte " + std::to_string(pos) + ": " + why; };
  if (d.size() < sizeof kMagic || std::memcmp(d.data(), kMagic, sizeof kMagic) != 0)
    return at(0, "not an MCAP file (no magic)");
  Reader r{cb, {}, {}};
  std::size_t pos = sizeof kMagic;
  bool first = true;
  while (true) {
    if (d.size() - pos < 9) return at(pos, "truncated: no Data End record (an unfinished file)");
    Cursor h{d.data() + pos, 9};
    const auto op = h.le<std::uint8_t>();
    const std::uint64_t len = h.le<std::uint64_t>();
    if (len > d.size() - pos - 9) return at(pos, "a record of " + std::to_string(len) + " bytes runs past the end");
    const char* body = d.data() + pos + 9;
    if (first && op != kHeader) return at(pos, "the first record is not a Header");
    first = false;
    if (op == kDataEnd) {
      Cursor c{body, static_cast<std::size_t>(len)};
      const auto crc = c.le<std::uint32_t>();
      if (!c.ok) return at(pos, "a Data End record shorter than its field");
      if (crc != 0 && crc != crc32_of(d.data(), pos)) return at(pos, "data section CRC mismatch (corrupt)");
      break;
    }
    if (op == kFooter) return at(pos, "a Footer before Data End");
    std::optional<std::string> e;
    if (op == kChunk)
      e = r.chunk(body, static_cast<std::size_t>(len));
    else if (op != kHeader)
      e = r.record(op, body, static_cast<std::size_t>(len));
    if (e) return at(pos, *e);
    pos += 9 + static_cast<std::size_t>(len);
  }
  if (d.size() < 2 * sizeof kMagic || std::memcmp(d.data() + d.size() - sizeof kMagic, kMagic, sizeof kMagic) != 0)
    return at(d.size(), "no closing magic (truncated)");
  return std::nullopt;
}

}  // namespace hemm::mcap
