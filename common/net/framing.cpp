#include "common/net/framing.h"

#include "common/net/bytes.h"

namespace hemm::net {

void encode_frame(std::span<const uint8_t> payload, std::vector<uint8_t>* out) {
  uint8_t h[kFrameHeaderBytes];
  put_u32(h, static_cast<uint32_t>(payload.size()));
  out->insert(out->end(), h, h + kFrameHeaderBytes);
  out->insert(out->end(), payload.begin(), payload.end());
}

bool FrameDecoder::feed(std::span<const uint8_t> bytes) {
  if (failed_) return false;
  // Compact lazily so long-lived connections do not grow the buffer.
  if (pos_ > 0 && pos_ >= buf_.size() / 2) {
    buf_.erase(buf_.begin(), buf_.begin() + static_cast<std::ptrdiff_t>(pos_));
    pos_ = 0;
  }
  buf_.insert(buf_.end(), bytes.begin(), bytes.end());
  return true;
}

FrameDecoder::Status FrameDecoder::next(std::vector<uint8_t>* payload) {
  if (failed_) return Status::kError;
  if (buffered() < kFrameHeaderBytes) return Status::kNeedMore;
  const uint32_t len = get_u32(buf_.data() + pos_);
  if (len == 0 || len > max_frame_bytes_) {
    failed_ = true;
    error_ = len == 0 ? "empty frame" : "frame of " + std::to_string(len) + " bytes exceeds the maximum of " +
                                            std::to_string(max_frame_bytes_);
    buf_.clear();
    pos_ = 0;
    return Status::kError;
  }
  if (buffered() < kFrameHeaderBytes + len) return Status::kNeedMore;
  const auto* b = buf_.data() + pos_ + kFrameHeaderBytes;
  payload->assign(b, b + len);
  pos_ += kFrameHeaderBytes + len;
  if (pos_ == buf_.size()) {
    buf_.clear();
    pos_ = 0;
  }
  return Status::kFrame;
}

std::vector<uint8_t> FrameSealer::seal(std::span<const uint8_t> payload) {
  std::vector<uint8_t> out(payload.size() + kTagBytes);
  uint8_t len[kFrameHeaderBytes];
  put_u32(len, static_cast<uint32_t>(out.size()));
  aead_seal(key_, counter_, len, payload, out.data());
  ++counter_;
  return out;
}

bool FrameOpener::open(std::span<const uint8_t> sealed, std::vector<uint8_t>* inner) {
  if (sealed.size() < kTagBytes) return false;
  uint8_t len[kFrameHeaderBytes];
  put_u32(len, static_cast<uint32_t>(sealed.size()));
  std::vector<uint8_t> plain(sealed.size() - kTagBytes);
  if (!aead_open(key_, counter_, len, sealed, plain.data())) return false;
  inner->swap(plain);
  ++counter_;
  return true;
}

}  // namespace hemm::net
