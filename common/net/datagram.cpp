#include "common/net/datagram.h"

#include "common/net/bytes.h"

namespace hemm::net {

bool encode_datagram(const Key& key, const DatagramHeader& h, std::span<const uint8_t> payload,
                     std::vector<uint8_t>* out) {
  out->clear();
  if (payload.size() > kMaxDatagramPayloadBytes) return false;
  out->resize(kDatagramHeaderBytes + payload.size() + kTagBytes);
  uint8_t* p = out->data();
  p[0] = 'H';
  p[1] = 'M';
  p[2] = kDatagramVersion;
  p[3] = 0;
  put_u64(p + 4, h.session_id);
  put_u64(p + 12, h.seq);
  put_u64(p + 20, static_cast<uint64_t>(h.send_time_ns));
  aead_seal(key, h.seq, std::span<const uint8_t>(p, kDatagramHeaderBytes), payload, p + kDatagramHeaderBytes);
  return true;
}

const char* to_string(DatagramError e) {
  switch (e) {
    case DatagramError::kOk: return "ok";
    case DatagramError::kBadSize: return "bad size";
    case DatagramError::kBadMagic: return "bad magic";
    case DatagramError::kBadVersion: return "bad version";
    case DatagramError::kUnknownSession: return "unknown session";
    case DatagramError::kBadTag: return "bad tag";
  }
  return "?";
}

DatagramError parse_datagram_header(std::span<const uint8_t> b, DatagramHeader* h) {
  if (b.size() < kDatagramOverheadBytes || b.size() > kMaxDatagramBytes) return DatagramError::kBadSize;
  if (b[0] != 'H' || b[1] != 'M' || b[3] != 0) return DatagramError::kBadMagic;
  if (b[2] != kDatagramVersion) return DatagramError::kBadVersion;
  h->session_id = get_u64(b.data() + 4);
  h->seq = get_u64(b.data() + 12);
  h->send_time_ns = static_cast<int64_t>(get_u64(b.data() + 20));
  return DatagramError::kOk;
}

DatagramError decode_datagram(std::span<const uint8_t> b, uint64_t expected_session, const Key& key,
                              DatagramHeader* h, std::vector<uint8_t>* payload) {
  DatagramHeader tmp;
  const DatagramError e = parse_datagram_header(b, &tmp);
  if (e != DatagramError::kOk) return e;
  if (tmp.session_id != expected_session || expected_session == 0) return DatagramError::kUnknownSession;
  // Open into a buffer of the right size without touching *payload on failure.
  uint8_t plain[kMaxDatagramPayloadBytes];
  const auto sealed = b.subspan(kDatagramHeaderBytes);
  if (!aead_open(key, tmp.seq, b.first(kDatagramHeaderBytes), sealed, plain)) return DatagramError::kBadTag;
  *h = tmp;
  payload->assign(plain, plain + (sealed.size() - kTagBytes));
  return DatagramError::kOk;
}

}  // namespace hemm::net
