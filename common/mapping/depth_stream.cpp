#include "common/mapping/depth_stream.h"

#include <algorithm>
#include <cmath>

#include "common/math/finite.h"

namespace hemm::mapping {
namespace {
bool finite_pos(double x) { return std::isfinite(x) && x > 0.0; }
}  // namespace

void pose3_to_wire(const Eigen::Isometry3d& T, proto::Pose3* out) {
  const Eigen::Quaterniond n = Eigen::Quaterniond(T.linear()).normalized();
  out->mutable_position()->set_x(T.translation().x());
  out->mutable_position()->set_y(T.translation().y());
  out->mutable_position()->set_z(T.translation().z());
  auto* o = out->mutable_orientation();
  o->set_w(n.w());
  o->set_x(n.x());
  o->set_y(n.y());
  o->set_z(n.z());
}

std::optional<std::string> pose3_from_wire(const proto::Pose3& p, Eigen::Isometry3d* out) {
  if (!math::finite3(p.position())) return "pose3 position not finite";
  const auto& o = p.orientation();
  const Eigen::Quaterniond q(o.w(), o.x(), o.y(), o.z());
  if (!q.coeffs().allFinite() || std::abs(q.norm() - 1.0) > 1e-6) return "pose3 quaternion not unit";
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() << p.position().x(), p.position().y(), p.position().z();
  *out = T;
  return std::nullopt;
}

std::optional<std::string> encode_depth_chunks(const DepthImage& img, const std::string& sensor_name,
                                               const DepthStreamParams& params, std::vector<wire::DepthChunk>* out) {
  out->clear();
  const DepthIntrinsics& K = img.K;
  if (K.width < 1 || K.height < 1 || K.width > kMaxDepthImageSide || K.height > kMaxDepthImageSide)
    return "depth encode: image size out of range";
  const auto n = static_cast<std::size_t>(K.width) * static_cast<std::size_t>(K.height);
  if (img.depth.size() != n || img.status.size() != n) return "depth encode: depth/status size mismatch";
  if (!(params.depth_unit > 0.0) || !(K.range_max / params.depth_unit < kDepthCountNoReturn - 1))
    return "depth encode: depth_unit too small for range_max";
  wire::DepthChunk head;
  head.set_stamp_ns(img.stamp_ns);
  head.set_cloud_id(img.cloud_id);
  head.set_sensor_name(sensor_name);
  pose3_to_wire(img.T_W_S, head.mutable_t_w_s());
  pose3_to_wire(img.T_W_S_truth, head.mutable_t_w_s_truth());
  head.set_width(static_cast<std::uint32_t>(K.width));
  head.set_height(static_cast<std::uint32_t>(K.height));
  head.set_fx(K.fx);
  head.set_fy(K.fy);
  head.set_cx(K.cx);
  head.set_cy(K.cy);
  head.set_range_min(K.range_min);
  head.set_range_max(K.range_max);
  head.set_depth_unit(params.depth_unit);
  // Rows per chunk from the size of a message with the largest row fields;
  // shrunk below if varints make a message longer.
  wire::StreamMessage probe;
  *probe.mutable_depth_chunk() = head;
  probe.mutable_depth_chunk()->set_first_row(static_cast<std::uint32_t>(K.height));
  probe.mutable_depth_chunk()->set_row_count(static_cast<std::uint32_t>(K.height));
  const std::size_t header = probe.ByteSizeLong() + 4;  // + tag and length of the depth field
  const std::size_t row_bytes = 2 * static_cast<std::size_t>(K.width);
  if (header + row_bytes > params.max_message_bytes) return "depth encode: one row does not fit a message";
  const int rows_per_chunk = static_cast<int>((params.max_message_bytes - header) / row_bytes);
  for (int r0 = 0; r0 < K.height; r0 += rows_per_chunk) {
    const int rows = std::min(rows_per_chunk, K.height - r0);
    wire::DepthChunk c = head;
    c.set_first_row(static_cast<std::uint32_t>(r0));
    c.set_row_count(static_cast<std::uint32_t>(rows));
    std::string bytes(2 * static_cast<std::size_t>(rows) * K.width, '\0');
    for (std::size_t k = 0; k < static_cast<std::size_t>(rows) * K.width; ++k) {
      const std::size_t i = static_cast<std::size_t>(r0) * K.width + k;
      std::uint16_t count = kDepthCountDropout;
      if (img.status[i] == DepthStatus::kNoReturn) {
        count = kDepthCountNoReturn;
      } else if (img.status[i] == DepthStatus::kValid && std::isfinite(img.depth[i]) && img.depth[i] > 0.0f) {
        const double q = std::round(img.depth[i] / params.depth_unit);
        count = static_cast<std::uint16_t>(std::clamp(q, 1.0, static_cast<double>(kDepthCountNoReturn - 1)));
      }
      bytes[2 * k] = static_cast<char>(count & 0xff);
      bytes[2 * k + 1] = static_cast<char>(count >> 8);
    }
    c.set_depth(std::move(bytes));
    out->push_back(std::move(c));
  }
  return std::nullopt;
}

std::optional<std::string> decode_depth_chunk(const wire::DepthChunk& m, std::int64_t clock_offset_ns,
                                              DepthChunkData* out) {
  DepthChunkData d;
  if (m.width() < 1 || m.height() < 1 || m.width() > kMaxDepthImageSide || m.height() > kMaxDepthImageSide)
    return "depth chunk: image size not in 1..1024";
  if (m.row_count() < 1 || m.first_row() >= m.height() || m.row_count() > m.height() - m.first_row())
    return "depth chunk: rows outside the image";
  if (!finite_pos(m.fx()) || !finite_pos(m.fy()) || !std::isfinite(m.cx()) || !std::isfinite(m.cy()) ||
      std::abs(m.cx()) > 4.0 * kMaxDepthImageSide || std::abs(m.cy()) > 4.0 * kMaxDepthImageSide)
    return "depth chunk: bad intrinsics";
  if (!finite_pos(m.range_min()) || !(m.range_max() > m.range_min()) || !(m.range_max() <= 100.0))
    return "depth chunk: need 0 < range_min < range_max <= 100 m";
  if (!(m.depth_unit() >= 1e-5 && m.depth_unit() <= 0.01)) return "depth chunk: depth_unit not in [1e-5, 0.01] m";
  const std::size_t n = static_cast<std::size_t>(m.row_count()) * m.width();
  if (m.depth().size() != 2 * n) return "depth chunk: payload length does not match rows x width";
  if (!m.has_t_w_s()) return "depth chunk: no sensor pose";
  if (auto e = pose3_from_wire(m.t_w_s(), &d.T_W_S)) return "depth chunk: T_W_S: " + *e;
  if (m.has_t_w_s_truth()) {
    if (auto e = pose3_from_wire(m.t_w_s_truth(), &d.T_W_S_truth)) return "depth chunk: T_W_S_truth: " + *e;
    d.has_truth = true;
  }
  d.K.width = static_cast<int>(m.width());
  d.K.height = static_cast<int>(m.height());
  d.K.fx = m.fx();
  d.K.fy = m.fy();
  d.K.cx = m.cx();
  d.K.cy = m.cy();
  d.K.range_min = m.range_min();
  d.K.range_max = m.range_max();
  d.first_row = static_cast<int>(m.first_row());
  d.row_count = static_cast<int>(m.row_count());
  d.depth.assign(n, 0.0f);
  d.status.assign(n, DepthStatus::kDropout);
  const auto* b = reinterpret_cast<const unsigned char*>(m.depth().data());
  // z can never exceed the range along the ray.
  const double z_max = m.range_max() + m.depth_unit();
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint16_t count = static_cast<std::uint16_t>(b[2 * k] | (b[2 * k + 1] << 8));
    if (count == kDepthCountNoReturn) {
      d.status[k] = DepthStatus::kNoReturn;
    } else if (count != kDepthCountDropout) {
      const double z = count * m.depth_unit();
      if (z > z_max) return "depth chunk: depth beyond range_max at pixel " + std::to_string(k);
      d.depth[k] = static_cast<float>(z);
      d.status[k] = DepthStatus::kValid;
    }
  }
  d.cloud_id = m.cloud_id();
  d.stamp_local_ns = m.stamp_ns() - clock_offset_ns;
  *out = std::move(d);
  return std::nullopt;
}

DepthStreamReceiver::Verdict DepthStreamReceiver::receive(const wire::DepthChunk& m, std::int64_t clock_offset_ns,
                                                          DepthChunkData* out) {
  // Decoded (validated) first; the state changes only on acceptance.
  DepthChunkData d;
  if (auto e = decode_depth_chunk(m, clock_offset_ns, &d)) {
    ++counters_.malformed;
    last_error_ = *e;
    return Verdict::kMalformed;
  }
  const bool newer = !have_cloud_ || static_cast<std::int32_t>(d.cloud_id - cloud_id_) > 0;
  if (have_cloud_ && !newer && d.cloud_id != cloud_id_) {
    ++counters_.stale;
    return Verdict::kStale;
  }
  if (!newer) {
    if (d.K.height != height_) {
      ++counters_.malformed;
      last_error_ = "depth chunk: image height changed within a cloud";
      return Verdict::kMalformed;
    }
    for (int r = d.first_row; r < d.first_row + d.row_count; ++r) {
      if (rows_.test(static_cast<std::size_t>(r))) {
        ++counters_.duplicate;
        return Verdict::kDuplicate;
      }
    }
  } else {
    if (have_cloud_) counters_.rows_lost += static_cast<std::uint64_t>(height_) - rows_.count();
    have_cloud_ = true;
    cloud_id_ = d.cloud_id;
    height_ = d.K.height;
    rows_.reset();
    ++counters_.clouds;
  }
  for (int r = d.first_row; r < d.first_row + d.row_count; ++r) rows_.set(static_cast<std::size_t>(r));
  ++counters_.accepted;
  counters_.rows_received += static_cast<std::uint64_t>(d.row_count);
  if (static_cast<int>(rows_.count()) == height_) ++counters_.clouds_complete;
  *out = std::move(d);
  return Verdict::kAccepted;
}

}  // namespace hemm::mapping
