#include "operator/record/session_mcap.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <functional>
#include <set>
#include <sstream>
#include <stdexcept>

#include "operator/record/mcap_file.h"

namespace hemm::op {
namespace {

namespace pb = google::protobuf;

constexpr const char* kHeaderTopic = "/hemm/recording";
constexpr const char* kServoTopic = "/operator/servo";
constexpr const char* kDeviceTopic = "/operator/device";
constexpr const char* kStepTopic = "/operator/model_step";
constexpr const char* kStateTopic = "/robot/state";
constexpr const char* kScanTopic = "/robot/scan";
constexpr const char* kDepthTopic = "/robot/depth";
constexpr const char* kCommandTopic = "/operator/command";
constexpr const char* kStreamTopic = "/link/stream";
constexpr const char* kSessionTopic = "/link/session";

// The binary FileDescriptorSet of `d`'s file and everything it imports,
// imports first (the MCAP "protobuf" schema encoding).
std::string descriptor_set(const pb::Descriptor* d) {
  pb::FileDescriptorSet set;
  std::set<std::string> seen;
  std::function<void(const pb::FileDescriptor*)> add = [&](const pb::FileDescriptor* f) {
    if (!seen.insert(f->name()).second) return;
    for (int i = 0; i < f->dependency_count(); ++i) add(f->dependency(i));
    f->CopyTo(set.add_file());
  };
  add(d->file());
  return set.SerializeAsString();
}

// Which channel a stream message goes to: the robot's streams and the
// operator's commands on their own (as their wire type), the rest as events.
const char* stream_topic(const rec::StreamEvent& e) {
  switch (e.message().body_case()) {
    case wire::StreamMessage::kRobotState: return e.outgoing() ? kStreamTopic : kStateTopic;
    case wire::StreamMessage::kRangeScan: return e.outgoing() ? kStreamTopic : kScanTopic;
    case wire::StreamMessage::kDepthChunk: return e.outgoing() ? kStreamTopic : kDepthTopic;
    case wire::StreamMessage::kCommand: return e.outgoing() ? kCommandTopic : kStreamTopic;
    default: return kStreamTopic;
  }
}

class Export {
 public:
  explicit Export(const std::string& path) : w_(path, options()) {}

  void put(const char* topic, const pb::Message& m, std::uint64_t t, std::uint32_t seq) {
    auto [it, added] = channels_.try_emplace(topic, Channel{});
    Channel& c = it->second;
    if (added) {
      const pb::Descriptor* d = m.GetDescriptor();
      auto s = schemas_.find(d->full_name());
      if (s == schemas_.end()) s = schemas_.emplace(d->full_name(), w_.add_schema(d->full_name(), "protobuf", descriptor_set(d))).first;
      c.id = w_.add_channel(s->second, topic, "protobuf", {{"clock", "operator steady clock, ns"}});
    }
    w_.write(c.id, seq, t, t, m.SerializeAsString());
    ++c.count;
  }
  std::uint32_t next_seq(const char* topic) const {
    const auto it = channels_.find(topic);
    return it == channels_.end() ? 0 : static_cast<std::uint32_t>(it->second.count);
  }

  McapExport close() {
    const mcap::WriterStats s = w_.close();
    McapExport e;
    e.messages = s.messages;
    e.chunks = s.chunks;
    e.bytes = s.bytes;
    e.uncompressed_bytes = s.uncompressed_bytes;
    for (const auto& [topic, c] : channels_) e.topics[topic] = c.count;
    return e;
  }

 private:
  static mcap::WriterOptions options() {
    mcap::WriterOptions o;
    o.library = "hemm-operator --export-mcap";
    return o;
  }
  struct Channel {
    std::uint16_t id = 0;
    std::uint64_t count = 0;
  };
  mcap::Writer w_;
  std::map<std::string, std::uint16_t> schemas_;
  std::map<std::string, Channel> channels_;
};

}  // namespace

namespace {

McapExport write_export(const Recording& rec, const std::string& path) {
  Export x(path);
  x.put(kHeaderTopic, rec.header, static_cast<std::uint64_t>(rec.header.start_ns()), 0);
  // The four record sequences merged by time; each keeps its own order (a
  // merge, not a sort), so every channel holds its records in file order.
  std::size_t ti = 0, si = 0, ei = 0, fi = 0;
  rec::ServoTick tick;
  rec::DeviceSample device;
  const auto none = std::numeric_limits<std::int64_t>::max();
  while (true) {
    const std::int64_t tt = ti < rec.ticks.size() ? rec.ticks[ti].t_ns() : none;
    const std::int64_t ts = si < rec.steps.size() ? rec.steps[si].now_ns() : none;
    const std::int64_t te = ei < rec.streams.size() ? rec.streams[ei].t_ns() : none;
    const std::int64_t tf = fi < rec.sessions.size() ? rec.sessions[fi].t_ns() : none;
    const std::int64_t t = std::min({tt, ts, te, tf});
    if (ti == rec.ticks.size() && si == rec.steps.size() && ei == rec.streams.size() && fi == rec.sessions.size()) break;
    const auto ut = static_cast<std::uint64_t>(t);
    if (si < rec.steps.size() && ts == t) {  // a tick follows the step it rendered with
      x.put(kStepTopic, rec.steps[si], ut, x.next_seq(kStepTopic));
      ++si;
    } else if (ti < rec.ticks.size() && tt == t) {
      tick = rec.ticks[ti];
      device.Clear();
      device.set_tick(tick.tick());
      device.set_t_ns(tick.t_ns());
      device.mutable_ee()->Swap(tick.mutable_ee());
      const auto seq = static_cast<std::uint32_t>(tick.tick());
      x.put(kDeviceTopic, device, ut, seq);  // before its tick: a reader joins them by tick
      x.put(kServoTopic, tick, ut, seq);
      ++ti;
    } else if (ei < rec.streams.size() && te == t) {
      const rec::StreamEvent& e = rec.streams[ei];
      const char* topic = stream_topic(e);
      const wire::StreamMessage& m = e.message();
      const pb::Message* body = &e;
      switch (m.body_case()) {
        case wire::StreamMessage::kRobotState: body = topic == kStateTopic ? static_cast<const pb::Message*>(&m.robot_state()) : body; break;
        case wire::StreamMessage::kRangeScan: body = topic == kScanTopic ? static_cast<const pb::Message*>(&m.range_scan()) : body; break;
        case wire::StreamMessage::kDepthChunk: body = topic == kDepthTopic ? static_cast<const pb::Message*>(&m.depth_chunk()) : body; break;
        case wire::StreamMessage::kCommand: body = topic == kCommandTopic ? static_cast<const pb::Message*>(&m.command()) : body; break;
        default: break;
      }
      x.put(topic, *body, ut, x.next_seq(topic));
      ++ei;
    } else {
      x.put(kSessionTopic, rec.sessions[fi], ut, x.next_seq(kSessionTopic));
      ++fi;
    }
  }
  return x.close();
}

}  // namespace

McapExport export_mcap(const Recording& rec, const std::string& path) {
  try {
    return write_export(rec, path);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(path, ec);  // no half-written file left behind
    throw;
  }
}

std::optional<std::string> load_mcap_recording(const std::string& path, Recording* out) {
  Recording r;
  std::map<std::uint16_t, std::string> topics;
  std::map<std::uint64_t, rec::DeviceSample> devices;  // waiting for their tick
  std::optional<std::string> bad;                      // the first bad message: the rest is ignored
  bool have_header = false;
  std::uint64_t index = 0;
  rec::Record record;
  auto message = [&](const mcap::Message& m) {
    if (bad) return;
    const auto topic_it = topics.find(m.channel_id);
    const std::string& topic = topic_it->second;  // read_file checked the channel came first
    auto fail = [&](const std::string& why) {
      bad = "message " + std::to_string(index) + " (" + topic + ", log time " + std::to_string(m.log_time) + "): " + why;
    };
    auto parse = [&](pb::Message* into) {
      if (into->ParseFromString(m.data)) return true;
      fail("does not parse as " + into->GetTypeName() + " (corrupt)");
      return false;
    };
    const auto t = static_cast<std::int64_t>(m.log_time);
    ++index;
    if (topic == kHeaderTopic) {
      if (have_header) return fail("a second header");
      rec::Header h;
      if (!parse(&h)) return;
      if (auto e = check_recording_header(h)) return fail(*e);
      r.header = h;
      have_header = true;
      r.records = 1;
      return;
    }
    const bool known = topic == kServoTopic || topic == kDeviceTopic || topic == kStepTopic || topic == kStateTopic ||
                       topic == kScanTopic || topic == kDepthTopic || topic == kCommandTopic ||
                       topic == kStreamTopic || topic == kSessionTopic;
    if (!known) return;  // another tool's channel
    if (!have_header) return fail(std::string("before the ") + kHeaderTopic + " header (not a hemm session export)");
    record.Clear();
    if (topic == kDeviceTopic) {
      rec::DeviceSample d;
      if (!parse(&d)) return;
      devices[d.tick()] = std::move(d);
      return;
    }
    if (topic == kServoTopic) {
      if (!parse(record.mutable_tick())) return;
      auto d = devices.find(record.tick().tick());
      if (d == devices.end())
        return fail("tick " + std::to_string(record.tick().tick()) + " has no " + kDeviceTopic + " sample before it");
      record.mutable_tick()->mutable_ee()->Swap(d->second.mutable_ee());
      devices.erase(d);
    } else if (topic == kStepTopic) {
      if (!parse(record.mutable_model_step())) return;
    } else if (topic == kStreamTopic) {
      if (!parse(record.mutable_stream())) return;
    } else if (topic == kSessionTopic) {
      if (!parse(record.mutable_session())) return;
    } else {
      rec::StreamEvent* e = record.mutable_stream();
      e->set_t_ns(t);
      e->set_outgoing(topic == kCommandTopic);
      wire::StreamMessage* w = e->mutable_message();
      const bool ok = topic == kStateTopic   ? parse(w->mutable_robot_state())
                      : topic == kScanTopic  ? parse(w->mutable_range_scan())
                      : topic == kDepthTopic ? parse(w->mutable_depth_chunk())
                                             : parse(w->mutable_command());
      if (!ok) return;
    }
    if (auto e = append_record(record, &r)) return fail(*e);
    ++r.records;
  };
  mcap::ReadCallbacks cb;
  cb.on_channel = [&](const mcap::Channel& c) { topics[c.id] = c.topic; };
  cb.on_message = message;
  std::optional<std::string> e = mcap::read_file(path, cb);
  if (bad && !e) e = path + ": " + *bad;
  if (!e && !have_header) e = path + ": an MCAP file without a " + kHeaderTopic + " header: not a hemm session export";
  if (e) {
    if (!have_header) return e;  // nothing of a recording: *out unchanged
    *out = std::move(r);
    return *e + " (the " + std::to_string(out->records) + " records before it are kept)";
  }
  std::error_code ec;
  r.bytes = std::filesystem::file_size(path, ec);
  *out = std::move(r);
  return std::nullopt;
}

std::string to_string(const McapExport& e) {
  std::ostringstream s;
  for (const auto& [topic, n] : e.topics) s << "  " << topic << ": " << n << " messages\n";
  s << "mcap: " << e.messages << " messages on " << e.topics.size() << " channels in " << e.chunks
    << " zstd chunks, " << e.bytes << " bytes (" << e.uncompressed_bytes << " uncompressed)\n";
  return s.str();
}

}  // namespace hemm::op
