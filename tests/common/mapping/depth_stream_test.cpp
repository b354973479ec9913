// Depth images through the wire: chunking within the datagram payload and the
// stated bandwidth, exact round trip (to the depth unit), newest cloud wins,
// loss and duplicates counted, and every malformed chunk rejected with a
// reason, a counter and no state change.
#include "common/mapping/depth_stream.h"

#include <cmath>
#include <functional>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "common/net/datagram.h"

namespace hm = hemm::mapping;

namespace {

hm::DepthImage test_image(std::uint32_t id) {
  hm::DepthImage img;
  img.cloud_id = id;
  img.stamp_ns = 1'000'000'000 + id;
  img.K = hm::intrinsics_from_hfov(80, 60, 60.0 * std::numbers::pi / 180.0, 0.2, 3.0);
  img.T_W_S = Eigen::Translation3d(1.0, -2.0, 0.9) * Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized());
  img.T_W_S_truth = Eigen::Translation3d(1.01, -2.0, 0.9) * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());
  const std::size_t n = 80 * 60;
  img.depth.assign(n, 0.0f);
  img.status.assign(n, hm::DepthStatus::kDropout);
  std::mt19937_64 rng(id);
  std::uniform_real_distribution<double> z(0.2, 2.9);
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = rng() % 10;
    if (k < 7) {
      img.status[i] = hm::DepthStatus::kValid;
      img.depth[i] = static_cast<float>(z(rng));
    } else if (k < 9) {
      img.status[i] = hm::DepthStatus::kNoReturn;
    }
  }
  return img;
}

std::vector<hemm::wire::DepthChunk> encode(const hm::DepthImage& img) {
  std::vector<hemm::wire::DepthChunk> c;
  EXPECT_FALSE(hm::encode_depth_chunks(img, "depth", hm::DepthStreamParams{}, &c));
  return c;
}

}  // namespace

TEST(DepthStream, ChunksFitADatagramAndTheBandwidthBudget) {
  const auto img = test_image(1);
  const auto chunks = encode(img);
  ASSERT_EQ(chunks.size(), 12u);  // 5 rows of 80 pixels each, after a ~250-byte header
  double bytes = 0;
  for (const auto& c : chunks) {
    hemm::wire::StreamMessage m;
    *m.mutable_depth_chunk() = c;
    EXPECT_LE(m.ByteSizeLong(), hm::DepthStreamParams{}.max_message_bytes);
    EXPECT_LE(m.ByteSizeLong(), hemm::net::kMaxDatagramPayloadBytes);
    bytes += static_cast<double>(m.ByteSizeLong() + hemm::net::kDatagramOverheadBytes + 28);  // + UDP/IPv4 headers
  }
  const double mbit_s = bytes * 8 * 15.0 / 1e6;  // at the camera's 15 Hz
  EXPECT_LT(mbit_s, 2.0);
  EXPECT_GT(mbit_s, 1.0);  // 9.6 kB of depth per frame cannot be sent in less
}

TEST(DepthStream, RoundTripIsExactToTheDepthUnit) {
  const auto img = test_image(42);
  hm::DepthStreamReceiver rx;
  std::vector<int> seen(60, 0);
  for (const auto& c : encode(img)) {
    hm::DepthChunkData d;
    ASSERT_EQ(rx.receive(c, 500, &d), hm::DepthStreamReceiver::Verdict::kAccepted) << rx.last_error();
    EXPECT_EQ(d.cloud_id, 42u);
    EXPECT_EQ(d.stamp_local_ns, img.stamp_ns - 500);
    EXPECT_TRUE(d.T_W_S.isApprox(img.T_W_S, 1e-12));
    EXPECT_TRUE(d.has_truth);
    EXPECT_TRUE(d.T_W_S_truth.isApprox(img.T_W_S_truth, 1e-12));
    EXPECT_DOUBLE_EQ(d.K.fx, img.K.fx);
    EXPECT_DOUBLE_EQ(d.K.range_max, 3.0);
    for (int r = 0; r < d.row_count; ++r) {
      ++seen[static_cast<std::size_t>(d.first_row + r)];
      for (int u = 0; u < 80; ++u) {
        const std::size_t k = static_cast<std::size_t>(r) * 80 + u;
        const std::size_t i = static_cast<std::size_t>(d.first_row + r) * 80 + u;
        ASSERT_EQ(d.status[k], img.status[i]);
        if (img.status[i] == hm::DepthStatus::kValid) {
          EXPECT_NEAR(d.depth[k], img.depth[i], 0.00025 + 1e-7);
        }
      }
    }
  }
  for (int s : seen) EXPECT_EQ(s, 1);
  EXPECT_EQ(rx.counters().clouds_complete, 1u);
  EXPECT_EQ(rx.counters().rows_received, 60u);
}

TEST(DepthStream, NewestCloudWinsAndLossIsCounted) {
  hm::DepthStreamReceiver rx;
  hm::DepthChunkData d;
  using V = hm::DepthStreamReceiver::Verdict;
  const auto a = encode(test_image(7)), b = encode(test_image(8));
  // Cloud 7 loses its chunks 3 and 4 (10 rows); cloud 8 starts.
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (k != 3 && k != 4) {
      ASSERT_EQ(rx.receive(a[k], 0, &d), V::kAccepted);
    }
  }
  EXPECT_EQ(rx.receive(a[0], 0, &d), V::kDuplicate);
  ASSERT_EQ(rx.receive(b[1], 0, &d), V::kAccepted);
  EXPECT_EQ(rx.counters().rows_lost, 10u);
  // A late chunk of cloud 7 is stale and leaves *out alone.
  d.cloud_id = 99;
  EXPECT_EQ(rx.receive(a[3], 0, &d), V::kStale);
  EXPECT_EQ(d.cloud_id, 99u);
  EXPECT_EQ(rx.rows_of_current(), 5);
  const auto& n = rx.counters();
  EXPECT_EQ(n.accepted, 11u);
  EXPECT_EQ(n.stale, 1u);
  EXPECT_EQ(n.duplicate, 1u);
  EXPECT_EQ(n.clouds, 2u);
  EXPECT_EQ(n.clouds_complete, 0u);
  // The id wraps: 0 follows 0xffffffff.
  hm::DepthStreamReceiver w;
  EXPECT_EQ(w.receive(encode(test_image(0xffffffffu))[0], 0, &d), V::kAccepted);
  EXPECT_EQ(w.receive(encode(test_image(0))[0], 0, &d), V::kAccepted);
  EXPECT_EQ(w.receive(encode(test_image(0xfffffffeu))[0], 0, &d), V::kStale);
}

TEST(DepthStream, MalformedChunksAreRejectedWithoutStateChange) {
  using V = hm::DepthStreamReceiver::Verdict;
  using M = hemm::wire::DepthChunk;
  const auto good = encode(test_image(3));
  const std::vector<std::pair<const char*, std::function<void(M*)>>> bad = {
      {"width 0", [](M* m) { m->set_width(0); }},
      {"huge height", [](M* m) { m->set_height(5000); }},
      {"rows outside", [](M* m) { m->set_first_row(58); }},
      {"no rows", [](M* m) { m->set_row_count(0); }},
      {"short payload", [](M* m) { m->mutable_depth()->pop_back(); }},
      {"nan fx", [](M* m) { m->set_fx(std::nan("")); }},
      {"negative fy", [](M* m) { m->set_fy(-10); }},
      {"range inverted", [](M* m) { m->set_range_min(4.0); }},
      {"range huge", [](M* m) { m->set_range_max(1e9); }},
      {"unit zero", [](M* m) { m->set_depth_unit(0); }},
      {"no pose", [](M* m) { m->clear_t_w_s(); }},
      {"pose not unit", [](M* m) { m->mutable_t_w_s()->mutable_orientation()->set_w(3); }},
      {"pose inf", [](M* m) { m->mutable_t_w_s()->mutable_position()->set_x(INFINITY); }},
      {"truth not unit", [](M* m) { m->mutable_t_w_s_truth()->mutable_orientation()->set_w(0); }},
      {"depth beyond range", [](M* m) { (*m->mutable_depth())[0] = '\xfe', (*m->mutable_depth())[1] = '\xff'; }},
  };
  hm::DepthStreamReceiver rx;
  hm::DepthChunkData d;
  ASSERT_EQ(rx.receive(good[0], 0, &d), V::kAccepted);
  const auto before = rx.counters();
  std::uint64_t k = 0;
  for (const auto& [name, mutate] : bad) {
    M m = good[1];
    mutate(&m);
    d.cloud_id = 77;
    EXPECT_EQ(rx.receive(m, 0, &d), V::kMalformed) << name;
    EXPECT_FALSE(rx.last_error().empty()) << name;
    EXPECT_EQ(rx.last_error().find('\n'), std::string::npos);
    EXPECT_EQ(d.cloud_id, 77u) << name;
    EXPECT_EQ(rx.counters().malformed, ++k) << name;
    EXPECT_EQ(rx.counters().accepted, before.accepted) << name;
    EXPECT_EQ(rx.rows_of_current(), 5) << name;
  }
  // A bad chunk of a newer cloud does not supersede the current one.
  M newer = good[1];
  newer.set_cloud_id(4);
  newer.set_width(0);
  EXPECT_EQ(rx.receive(newer, 0, &d), V::kMalformed);
  EXPECT_EQ(rx.receive(good[1], 0, &d), V::kAccepted);  // still cloud 3
  EXPECT_EQ(rx.counters().clouds, 1u);
}

TEST(DepthStream, EncoderRejectsInconsistentImages) {
  auto img = test_image(1);
  std::vector<hemm::wire::DepthChunk> c(3);
  img.depth.pop_back();
  EXPECT_TRUE(hm::encode_depth_chunks(img, "d", {}, &c));
  EXPECT_TRUE(c.empty());
  img = test_image(1);
  hm::DepthStreamParams tiny;
  tiny.max_message_bytes = 200;  // one 160-byte row plus the header cannot fit
  EXPECT_TRUE(hm::encode_depth_chunks(img, "d", tiny, &c));
  EXPECT_TRUE(c.empty());
}
