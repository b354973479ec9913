#include "common/net/stream_receiver.h"

#include <algorithm>

namespace hemm::net {

StreamReceiver::StreamReceiver(uint32_t replay_window) : window_size_(replay_window), window_(replay_window) {
  plain_.reserve(kMaxDatagramPayloadBytes);  // decode_datagram never allocates after this
}

void StreamReceiver::open(uint64_t session_id, const Key& rx_key) {
  session_id_ = session_id;
  key_ = rx_key;
  window_ = ReplayWindow(window_size_);
  newest_by_kind_.fill(0);
  chunks_.fill(ChunkStream{});
}

StreamReceiver::Verdict StreamReceiver::receive(std::span<const uint8_t> d, DatagramHeader* h,
                                                wire::StreamMessage* msg) {
  ++c_.received;
  DatagramHeader hd;
  const DatagramError e = decode_datagram(d, session_id_, key_, &hd, &plain_);
  last_error_ = to_string(e);
  switch (e) {
    case DatagramError::kOk: break;
    case DatagramError::kBadSize: ++c_.rejected_bad_size; return Verdict::kRejected;
    case DatagramError::kBadMagic: ++c_.rejected_bad_magic; return Verdict::kRejected;
    case DatagramError::kBadVersion: ++c_.rejected_bad_version; return Verdict::kRejected;
    case DatagramError::kUnknownSession: ++c_.rejected_unknown_session; return Verdict::kRejected;
    case DatagramError::kBadTag: ++c_.rejected_bad_tag; return Verdict::kRejected;
  }
  const uint64_t prev_highest = window_.highest();
  switch (window_.check(hd.seq)) {
    case ReplayWindow::Verdict::kDuplicate:
      ++c_.duplicated;
      last_error_ = "duplicate";
      return Verdict::kDuplicate;
    case ReplayWindow::Verdict::kTooOld:
      ++c_.rejected_replay;
      last_error_ = "replay (behind the window)";
      return Verdict::kRejected;
    case ReplayWindow::Verdict::kNewHighest:
    case ReplayWindow::Verdict::kInWindow: break;
  }
  // The sender authenticated this sequence number: it is used up whatever the payload holds.
  const ReplayWindow::Verdict v = window_.accept(hd.seq);
  if (v == ReplayWindow::Verdict::kNewHighest) {
    // The first datagram of a session does not count earlier numbers as lost.
    if (prev_highest > 0) c_.lost += hd.seq - prev_highest - 1;
  } else {
    ++c_.reordered;
    if (c_.lost > 0) --c_.lost;
  }
  wire::StreamMessage m;
  if (!m.ParseFromArray(plain_.data(), static_cast<int>(plain_.size())) ||
      m.body_case() == wire::StreamMessage::BODY_NOT_SET || static_cast<size_t>(m.body_case()) >= kKinds) {
    ++c_.rejected_bad_payload;
    last_error_ = "bad payload";
    return Verdict::kRejected;
  }
  ChunkStream* chunk = nullptr;
  uint32_t frame = 0;
  if (m.has_range_scan()) {
    chunk = &chunks_[std::min<size_t>(static_cast<size_t>(std::max(0, static_cast<int>(m.range_scan().sensor()))), 3)];
    frame = m.range_scan().scan_id();
  } else if (m.has_depth_chunk()) {
    chunk = &chunks_[4];
    frame = m.depth_chunk().cloud_id();
  }
  if (chunk != nullptr) {
    // Newest-wins by frame: older than the newest chunk, but of its frame, is not late.
    if (hd.seq < chunk->newest_seq && frame != chunk->frame) {
      ++c_.late;
      last_error_ = "late";
      return Verdict::kLate;
    }
    if (hd.seq > chunk->newest_seq) {
      chunk->newest_seq = hd.seq;
      chunk->frame = frame;
    }
  } else {
    uint64_t& newest = newest_by_kind_[static_cast<size_t>(m.body_case())];
    if (hd.seq < newest) {
      ++c_.late;
      last_error_ = "late";
      return Verdict::kLate;
    }
    newest = hd.seq;
  }
  ++c_.delivered;
  *h = hd;
  msg->Swap(&m);
  last_error_ = "";
  return Verdict::kDeliver;
}

}  // namespace hemm::net
