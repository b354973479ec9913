#include "common/net/stream_receiver.h"

#include <gtest/gtest.h>

namespace hemm::net {
namespace {

const Key kKey = [] {
  Key k{};
  k.fill(0x33);
  return k;
}();
constexpr uint64_t kSession = 99;

std::vector<uint8_t> dgram(uint64_t seq, bool ping, const Key& k = kKey, uint64_t sid = kSession) {
  wire::StreamMessage m;
  if (ping) {
    m.mutable_ping()->set_id(seq);
  } else {
    m.mutable_heartbeat()->set_period_ms(50);
  }
  const std::string p = m.SerializeAsString();
  std::vector<uint8_t> d;
  encode_datagram(k, DatagramHeader{sid, seq, 1}, std::span(reinterpret_cast<const uint8_t*>(p.data()), p.size()),
                  &d);
  return d;
}

using ReceiverVerdict = StreamReceiver::Verdict;

TEST(StreamReceiverTest, CountsLossReorderLateAndDuplicates) {
  StreamReceiver r(64);
  r.open(kSession, kKey);
  DatagramHeader h;
  wire::StreamMessage m;
  EXPECT_EQ(r.receive(dgram(1, true), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_TRUE(m.has_ping());
  EXPECT_EQ(r.receive(dgram(2, false), &h, &m), ReceiverVerdict::kDeliver);
  // 3, 4 missing.
  EXPECT_EQ(r.receive(dgram(5, true), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.counters().lost, 2u);
  // 3 is a heartbeat: reordered but newer than the newest heartbeat (2): delivered.
  EXPECT_EQ(r.receive(dgram(3, false), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.counters().lost, 1u);
  // 4 is a ping older than ping 5: late, not delivered.
  EXPECT_EQ(r.receive(dgram(4, true), &h, &m), ReceiverVerdict::kLate);
  EXPECT_EQ(r.counters().lost, 0u);
  EXPECT_EQ(r.receive(dgram(5, true), &h, &m), ReceiverVerdict::kDuplicate);
  const auto& c = r.counters();
  EXPECT_EQ(c.received, 6u);
  EXPECT_EQ(c.delivered, 4u);
  EXPECT_EQ(c.reordered, 2u);
  EXPECT_EQ(c.late, 1u);
  EXPECT_EQ(c.duplicated, 1u);
  EXPECT_EQ(c.rejected_total(), 0u);
}

TEST(StreamReceiverTest, RejectionsAreCountedByCauseAndChangeNoState) {
  StreamReceiver r(64);
  r.open(kSession, kKey);
  DatagramHeader h;
  wire::StreamMessage m;
  ASSERT_EQ(r.receive(dgram(100, true), &h, &m), ReceiverVerdict::kDeliver);
  Key other = kKey;
  other[0] ^= 1;
  // A forged datagram with a fresh sequence number must not advance the window.
  EXPECT_EQ(r.receive(dgram(101, true, other), &h, &m), ReceiverVerdict::kRejected);
  EXPECT_EQ(r.receive(dgram(101, true, kKey, kSession + 1), &h, &m), ReceiverVerdict::kRejected);
  EXPECT_EQ(r.receive(dgram(20, true), &h, &m), ReceiverVerdict::kRejected);  // behind the 64 window
  auto bad_version = dgram(102, true);
  bad_version[2] = 9;
  EXPECT_EQ(r.receive(bad_version, &h, &m), ReceiverVerdict::kRejected);
  EXPECT_EQ(r.receive(std::vector<uint8_t>(10, 0), &h, &m), ReceiverVerdict::kRejected);
  auto bad_magic = dgram(102, true);
  bad_magic[0] = 0;
  EXPECT_EQ(r.receive(bad_magic, &h, &m), ReceiverVerdict::kRejected);
  // Authenticated but not a StreamMessage.
  std::vector<uint8_t> junk;
  const uint8_t garbage[3] = {0xff, 0xff, 0xff};
  encode_datagram(kKey, DatagramHeader{kSession, 103, 0}, garbage, &junk);
  EXPECT_EQ(r.receive(junk, &h, &m), ReceiverVerdict::kRejected);
  const auto& c = r.counters();
  EXPECT_EQ(c.rejected_bad_tag, 1u);
  EXPECT_EQ(c.rejected_unknown_session, 1u);
  EXPECT_EQ(c.rejected_replay, 1u);
  EXPECT_EQ(c.rejected_bad_version, 1u);
  EXPECT_EQ(c.rejected_bad_size, 1u);
  EXPECT_EQ(c.rejected_bad_magic, 1u);
  EXPECT_EQ(c.rejected_bad_payload, 1u);
  EXPECT_EQ(c.delivered, 1u);
  // 101 is still fresh: the forgeries did not consume it.
  EXPECT_EQ(r.receive(dgram(101, false), &h, &m), ReceiverVerdict::kDeliver);
}

TEST(StreamReceiverTest, ClosedReceiverAcceptsNothing) {
  StreamReceiver r(64);
  DatagramHeader h;
  wire::StreamMessage m;
  EXPECT_EQ(r.receive(dgram(1, true), &h, &m), ReceiverVerdict::kRejected);
  r.open(kSession, kKey);
  EXPECT_EQ(r.receive(dgram(1, true), &h, &m), ReceiverVerdict::kDeliver);
  r.close();
  EXPECT_EQ(r.receive(dgram(2, true), &h, &m), ReceiverVerdict::kRejected);
  EXPECT_EQ(r.counters().rejected_unknown_session, 2u);
}

// ---------------------------------------------------------------- issue 23 item 7
std::vector<uint8_t> seal(uint64_t seq, const wire::StreamMessage& m) {
  const std::string p = m.SerializeAsString();
  std::vector<uint8_t> d;
  encode_datagram(kKey, DatagramHeader{kSession, seq, 1}, std::span(reinterpret_cast<const uint8_t*>(p.data()), p.size()),
                  &d);
  return d;
}
std::vector<uint8_t> depth_chunk(uint64_t seq, uint32_t cloud, uint32_t first_row) {
  wire::StreamMessage m;
  m.mutable_depth_chunk()->set_cloud_id(cloud);
  m.mutable_depth_chunk()->set_first_row(first_row);
  m.mutable_depth_chunk()->set_row_count(10);
  return seal(seq, m);
}
std::vector<uint8_t> scan_chunk(uint64_t seq, wire::RangeSensorType sensor, uint32_t scan, uint32_t first_beam) {
  wire::StreamMessage m;
  m.mutable_range_scan()->set_sensor(sensor);
  m.mutable_range_scan()->set_scan_id(scan);
  m.mutable_range_scan()->set_first_beam(first_beam);
  return seal(seq, m);
}
std::vector<uint8_t> state(uint64_t seq) {
  wire::StreamMessage m;
  m.mutable_robot_state()->set_stamp_ns(static_cast<int64_t>(seq));
  return seal(seq, m);
}

// Newest wins per kind, but a chunk of the frame being assembled is part of
// the newest, not older than it: chunks of one depth frame arriving out of
// order, with robot states between them, are all delivered; a chunk of an
// older frame is late.
TEST(StreamReceiverTest, ReorderedChunksOfTheFrameBeingAssembledAreDelivered) {
  StreamReceiver r(64);
  r.open(kSession, kKey);
  DatagramHeader h;
  wire::StreamMessage m;
  // Cloud 6 (seq 1-3) was sent before cloud 7 (seq 4-6); states 7 and 8.
  EXPECT_EQ(r.receive(depth_chunk(4, 7, 0), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(state(7), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(depth_chunk(6, 7, 20), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(state(8), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(depth_chunk(5, 7, 10), &h, &m), ReceiverVerdict::kDeliver) << "a chunk of cloud 7 was dropped";
  EXPECT_EQ(m.depth_chunk().first_row(), 10u);
  EXPECT_EQ(r.receive(depth_chunk(3, 6, 20), &h, &m), ReceiverVerdict::kLate);  // cloud 6 is superseded
  EXPECT_EQ(r.receive(state(2), &h, &m), ReceiverVerdict::kLate);               // states: newest wins as before
  // Laser and sonar chunks share the RangeScan kind: each sensor's frame is its own.
  EXPECT_EQ(r.receive(scan_chunk(11, wire::RANGE_SENSOR_LASER, 30, 0), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(scan_chunk(13, wire::RANGE_SENSOR_SONAR, 9, 0), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(scan_chunk(12, wire::RANGE_SENSOR_LASER, 30, 91), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(scan_chunk(10, wire::RANGE_SENSOR_LASER, 29, 91), &h, &m), ReceiverVerdict::kLate);
  // The next cloud supersedes cloud 7: a straggler of 7 is late from then on.
  EXPECT_EQ(r.receive(depth_chunk(15, 8, 0), &h, &m), ReceiverVerdict::kDeliver);
  EXPECT_EQ(r.receive(depth_chunk(14, 7, 30), &h, &m), ReceiverVerdict::kLate);
  const auto& c = r.counters();
  EXPECT_EQ(c.delivered, 9u);
  EXPECT_EQ(c.late, 4u);
}

}  // namespace
}  // namespace hemm::net
