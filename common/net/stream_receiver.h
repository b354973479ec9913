// Receive side of the stream channel, without sockets: validates each
// datagram (size, magic, version, session, tag, replay window, payload) and
// keeps the counters of what arrived. Newest-wins per message kind: a
// datagram older (by sequence number) than the newest already delivered of
// its kind is counted late and not delivered. Chunked kinds are judged by
// frame: a RangeScan chunk per sensor (its scan_id), a DepthChunk by its
// cloud_id. A chunk of the frame the newest delivered chunk belongs to is
// delivered whatever its sequence number (reordered chunks of the frame
// being assembled are part of the newest); a chunk of an older frame is late.
//
// Counters:
//   lost       sequence numbers skipped and not (yet) filled in
//   reordered  arrived below the highest sequence number seen (fills a gap)
//   late       reordered and older than the newest of its kind: dropped
//   duplicated authenticated, already seen inside the replay window: dropped
//   rejected_* bad size / magic / version / unknown session / tag / payload,
//              and rejected_replay (authenticated, behind the replay window)
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "common/net/crypto.h"
#include "common/net/datagram.h"
#include "common/net/replay_window.h"
#include "wire.pb.h"

namespace hemm::net {

struct StreamCounters {
  uint64_t received = 0;   // datagrams handed to the receiver
  uint64_t delivered = 0;  // accepted and handed on
  uint64_t lost = 0;
  uint64_t reordered = 0;
  uint64_t late = 0;
  uint64_t duplicated = 0;
  uint64_t rejected_bad_size = 0;
  uint64_t rejected_bad_magic = 0;
  uint64_t rejected_bad_version = 0;
  uint64_t rejected_unknown_session = 0;
  uint64_t rejected_bad_tag = 0;
  uint64_t rejected_replay = 0;
  uint64_t rejected_bad_payload = 0;

  uint64_t rejected_total() const {
    return rejected_bad_size + rejected_bad_magic + rejected_bad_version + rejected_unknown_session +
           rejected_bad_tag + rejected_replay + rejected_bad_payload;
  }
};

class StreamReceiver {
 public:
  enum class Verdict {
    kDeliver,  // *h and *msg are set
    kLate,     // authenticated but superseded (counted), not delivered
    kDuplicate,
    kRejected,  // see counters / last_error()
  };

  explicit StreamReceiver(uint32_t replay_window = 1024);

  // Starts accepting a session (resets the replay window and per-kind state;
  // counters are cumulative over sessions).
  void open(uint64_t session_id, const Key& rx_key);
  void close() { session_id_ = 0; }
  uint64_t session_id() const { return session_id_; }

  Verdict receive(std::span<const uint8_t> datagram, DatagramHeader* h, wire::StreamMessage* msg);

  const StreamCounters& counters() const { return c_; }
  // Why the last kRejected happened (a short constant string).
  const char* last_error() const { return last_error_; }

 private:
  static constexpr size_t kKinds = 16;  // > largest StreamMessage body field number

  uint32_t window_size_;
  ReplayWindow window_;
  uint64_t session_id_ = 0;
  Key key_{};
  std::array<uint64_t, kKinds> newest_by_kind_{};
  // Chunked streams: RangeScan per sensor (RangeSensorType 0-2, others
  // together in slot 3), DepthChunk in slot 4. The newest chunk's sequence
  // number and frame.
  struct ChunkStream {
    uint64_t newest_seq = 0;
    uint32_t frame = 0;
  };
  static constexpr size_t kChunkStreams = 5;
  std::array<ChunkStream, kChunkStreams> chunks_{};
  StreamCounters c_;
  const char* last_error_ = "";
  std::vector<uint8_t> plain_;  // the opened payload of the datagram being received
};

}  // namespace hemm::net
