// Depth images on the wire: a frame is cut into chunks of whole rows
// (hemm.wire.DepthChunk), each small enough for one datagram and carrying the
// intrinsics and the sensor pose at acquisition, so every chunk can be placed
// on its own and a lost one costs only its rows. The receiver lets the newest
// cloud win: chunks of an older cloud id are dropped as stale, a repeated
// chunk as a duplicate, a malformed one with a reason; none of them changes
// its state. Pure functions and a small stateful filter, no I/O.
//
// Bandwidth: 80 x 60 pixels at 2 bytes is 9.6 kB per frame, 12 chunks of 5
// rows (~1.05 kB each, ~250 bytes of it the self-contained header); at 15 Hz
// about 1.6 Mbit/s with the datagram and UDP/IP overheads -- the stream's
// stated budget is 2 Mbit/s (depth_stream_test checks it).
#pragma once

#include <bitset>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/mapping/depth_image.h"
#include "wire.pb.h"

namespace hemm::mapping {

inline constexpr int kMaxDepthImageSide = 1024;
inline constexpr std::uint16_t kDepthCountDropout = 0;
inline constexpr std::uint16_t kDepthCountNoReturn = 65535;

struct DepthStreamParams {
  std::size_t max_message_bytes = 1100;  // serialised StreamMessage, below the datagram payload limit
  double depth_unit = 0.0005;            // m per count: 0.5 mm, well below the sensor noise; 32 m span
};

void pose3_to_wire(const Eigen::Isometry3d& T, proto::Pose3* out);
// Rejects non-finite positions and quaternions whose norm is not 1 within 1e-6.
std::optional<std::string> pose3_from_wire(const proto::Pose3& p, Eigen::Isometry3d* out);

// Cuts img into chunks (appended to *out after clearing it). Fails, leaving
// *out empty, if the image is inconsistent or one row does not fit a message.
std::optional<std::string> encode_depth_chunks(const DepthImage& img, const std::string& sensor_name,
                                               const DepthStreamParams& params, std::vector<wire::DepthChunk>* out);

// One validated chunk: rows [first_row, first_row + row_count) of its image.
struct DepthChunkData {
  std::int64_t stamp_local_ns = 0;  // mapped into the receiver's clock
  std::uint32_t cloud_id = 0;
  DepthIntrinsics K;
  Eigen::Isometry3d T_W_S = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_W_S_truth = Eigen::Isometry3d::Identity();  // SIMULATION ONLY
  bool has_truth = false;
  int first_row = 0;
  int row_count = 0;
  std::vector<float> depth;          // row_count * K.width, metres (z in S), 0 unless kValid
  std::vector<DepthStatus> status;
};

// Validates everything (sizes, intrinsics, limits, poses, payload length,
// every depth count within range_max) before writing *out; on error *out is
// untouched. clock_offset_ns is robot clock minus ours.
std::optional<std::string> decode_depth_chunk(const wire::DepthChunk& m, std::int64_t clock_offset_ns,
                                              DepthChunkData* out);

struct DepthStreamCounters {
  std::uint64_t accepted = 0;
  std::uint64_t malformed = 0;
  std::uint64_t stale = 0;       // chunk of a cloud older than the newest seen
  std::uint64_t duplicate = 0;   // rows of the current cloud already received
  std::uint64_t clouds = 0;      // clouds of which at least one chunk was accepted
  std::uint64_t clouds_complete = 0;
  std::uint64_t rows_received = 0;
  std::uint64_t rows_lost = 0;   // rows of superseded clouds that never arrived
};

// Newest-wins filter over cloud ids (serial-number order, so the id may wrap).
class DepthStreamReceiver {
 public:
  enum class Verdict { kAccepted, kMalformed, kStale, kDuplicate };
  Verdict receive(const wire::DepthChunk& m, std::int64_t clock_offset_ns, DepthChunkData* out);
  const DepthStreamCounters& counters() const { return counters_; }
  const std::string& last_error() const { return last_error_; }
  // Rows of the newest cloud received so far (0 before any).
  int rows_of_current() const { return static_cast<int>(rows_.count()); }
  // Forgets the newest cloud (its id, its rows), not the counters: a
  // restarted robot numbers its clouds afresh.
  void restart() {
    have_cloud_ = false;
    rows_.reset();
  }

 private:
  DepthStreamCounters counters_;
  std::string last_error_;
  bool have_cloud_ = false;
  std::uint32_t cloud_id_ = 0;
  int height_ = 0;
  std::bitset<kMaxDepthImageSide> rows_;
};

}  // namespace hemm::mapping
