// Depth chunk decoder and newest-cloud receiver on arbitrary bytes: whatever
// parses as a DepthChunk is either rejected with no state change, or accepted
// with a consistent, finite, in-range result.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "common/mapping/depth_stream.h"

using namespace hemm::mapping;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static DepthStreamReceiver rx;
  hemm::wire::DepthChunk m;
  if (!m.ParseFromArray(data, static_cast<int>(size))) return 0;
  const DepthStreamCounters before = rx.counters();
  const int rows_before = rx.rows_of_current();
  DepthChunkData d;
  d.row_count = -1;
  const auto v = rx.receive(m, 0, &d);
  if (v != DepthStreamReceiver::Verdict::kAccepted) {
    if (d.row_count != -1) abort();  // *out untouched
    if (rx.counters().accepted != before.accepted || rx.counters().clouds != before.clouds) abort();
    if (rx.rows_of_current() != rows_before) abort();
    return 0;
  }
  const auto n = static_cast<std::size_t>(d.row_count) * static_cast<std::size_t>(d.K.width);
  if (d.row_count < 1 || d.first_row + d.row_count > d.K.height || d.depth.size() != n || d.status.size() != n) abort();
  for (std::size_t k = 0; k < n; ++k) {
    const bool valid = d.status[k] == DepthStatus::kValid;
    if (!std::isfinite(d.depth[k]) || d.depth[k] < 0.0f) abort();
    if (valid && !(d.depth[k] > 0.0f && d.depth[k] <= d.K.range_max + 0.011)) abort();
    if (!valid && d.depth[k] != 0.0f) abort();
  }
  if (!d.T_W_S.matrix().allFinite()) abort();
  return 0;
}
