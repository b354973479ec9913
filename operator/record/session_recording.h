// Recorded operator sessions (hemm-operator --record FILE; the format is
// proto/record.proto: length-delimited Record messages, a Header first).
//
// Why length-delimited Protocol Buffers, with MCAP as an export
// (session_mcap.h): the recorder appends one record at a time from a writer
// thread and a file cut by a crash keeps every record before the cut, with
// no index or summary to finish; the framing is the one protobuf's own
// libraries read and write (C++ util::ParseDelimitedFromCodedStream, Java
// parseDelimitedFrom, Python _DecodeVarint + ParseFromString), so any
// protobuf user reads a recording with the schema in proto/. Robotics tools
// (Foxglove Studio, any MCAP reader) open its MCAP export.
//
// SessionRecorder writes on its own thread. Producers never wait on the
// file: the servo thread pushes ServoTickRecords into a preallocated ring
// (ServoTickTap, no lock or allocation), the model and network threads hand
// serialized records over under a mutex the servo thread never takes.
//
// load_recording validates as it reads: the Header's magic and version,
// every record's length, checksum and parse; it stops at the first bad record with an
// error naming the record and byte offset, and keeps the records before it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "operator/model/model_thread.h"
#include "operator/station/operator_task.h"
#include "record.pb.h"

namespace hemm::op {

inline constexpr const char* kRecordingMagic = "hemm-recording";
// 2: every record ends with its CRC-32C (Record.crc32c); 1 (no checksums)
// is still read.
inline constexpr std::uint32_t kRecordingFormatVersion = 2;

// CRC-32C (Castagnoli) of n bytes: the checksum of a format-2 record.
std::uint32_t record_checksum(const char* data, std::size_t n) noexcept;
// A record longer than this is corrupt (the largest real ones, model steps
// with a few scans, are tens of kB).
inline constexpr std::uint64_t kMaxRecordBytes = 64u << 20;

// Conversions between the servo's fixed-size types and the record messages.
void to_proto(const ServoTickRecord& r, rec::ServoTick* out);
// Checks sizes and finiteness; a one-line error, *out unchanged on error.
std::optional<std::string> from_proto(const rec::ServoTick& t, int end_effectors, ServoTickRecord* out);
void to_proto(const ModelThread::StepInputs& in, std::uint64_t version, rec::ModelStep* out);

class SessionRecorder {
 public:
  // Opens `path` (truncating) and writes the header. Throws
  // std::runtime_error if the file cannot be written.
  SessionRecorder(const std::string& path, const rec::Header& header, std::size_t tick_capacity = 16384);
  ~SessionRecorder();  // stop()
  SessionRecorder(const SessionRecorder&) = delete;
  SessionRecorder& operator=(const SessionRecorder&) = delete;

  void start();  // the writer thread
  // Drains everything, closes the file, joins. Idempotent.
  void stop();

  // ---- servo thread ----
  ServoTickTap& ticks() noexcept { return ticks_; }
  // ---- model thread (ModelThread::set_step_tap) ----
  void model_step(const ModelThread::StepInputs& in, std::uint64_t version);
  // ---- network thread ----
  // seq: a received message's datagram sequence (telemanip's replay hands
  // each tick the ArmsState it took by it), 0 if not kept.
  void stream(std::int64_t t_ns, bool outgoing, const wire::StreamMessage& m, std::uint64_t seq = 0);
  void session(std::int64_t t_ns, bool outgoing, const wire::SessionFrame& f);

  // ---- any thread ----
  std::uint64_t records() const noexcept { return records_.load(std::memory_order_relaxed); }
  std::uint64_t ticks_dropped() const noexcept { return ticks_.dropped.load(std::memory_order_relaxed); }
  bool write_failed() const noexcept { return write_failed_.load(std::memory_order_relaxed); }

 private:
  void enqueue(const rec::Record& r);
  void write(const std::string& bytes);  // writer thread (or before start / after stop)
  void drain();
  void run();

  std::FILE* file_ = nullptr;
  ServoTickTap ticks_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::string> pending_;  // under mu_
  bool stop_ = false;                 // under mu_
  std::thread thread_;
  int end_effectors_;
  std::atomic<std::uint64_t> records_{0};
  std::atomic<bool> write_failed_{false};
};

// A recording as read: every complete, valid record up to the first bad one.
struct Recording {
  rec::Header header;
  std::vector<rec::ServoTick> ticks;       // in file order (= tick order)
  std::vector<rec::ModelStep> steps;       // in file order (= version order)
  std::vector<rec::StreamEvent> streams;
  std::vector<rec::SessionEvent> sessions;
  std::uint64_t records = 0;               // read, header included
  std::uint64_t bytes = 0;                 // of the records read
};

// The checks load_recording makes, for another container of the same
// records (the MCAP export, session_mcap.h): the header's magic, version and
// fields; one record after the header (sizes, finiteness, tick and version
// order), appended to *r unless it is refused.
std::optional<std::string> check_recording_header(const rec::Header& h);
std::optional<std::string> append_record(const rec::Record& record, Recording* r);

// Reads `path` (a recording, or its MCAP export: session_mcap.h). A file that is not a recording (unreadable, no valid header)
// gives an error and leaves *out untouched. A recording that breaks later
// (truncated, corrupt) gives an error "record N at byte B: why" and *out
// holds the records before it. No error: the whole file was read.
std::optional<std::string> load_recording(const std::string& path, Recording* out);
// True if the file starts like a recording or an MCAP file (for --replay's
// format choice; load_recording tells an MCAP file that is not a session's).
bool looks_like_recording(const std::string& path);

}  // namespace hemm::op
