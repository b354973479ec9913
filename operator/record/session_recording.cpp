#include "operator/record/session_recording.h"

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "operator/record/mcap_file.h"
#include "operator/record/session_mcap.h"

namespace hemm::op {

std::uint32_t record_checksum(const char* data, std::size_t n) noexcept {
  // CRC-32C, reflected polynomial 0x82f63b78, one table lookup per byte.
  static constexpr auto kTable = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? (c >> 1) ^ 0x82f63b78u : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t crc = 0xffffffffu;
  for (std::size_t i = 0; i < n; ++i) crc = kTable[(crc ^ static_cast<unsigned char>(data[i])) & 0xffu] ^ (crc >> 8);
  return crc ^ 0xffffffffu;
}

namespace {

template <class Vec>
void put(const Vec& v, google::protobuf::RepeatedField<double>* out) {
  out->Clear();
  for (Eigen::Index i = 0; i < v.size(); ++i) out->Add(v[i]);
}

bool finite_of_size(const google::protobuf::RepeatedField<double>& f, int n) {
  if (f.size() != n) return false;
  for (double x : f)
    if (!std::isfinite(x)) return false;
  return true;
}

void append_varint(std::uint64_t v, std::string* out) {
  while (v >= 0x80) {
    out->push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out->push_back(static_cast<char>(v));
}

constexpr char kCrcTag = 0x7d;  // field 15, wire type 5 (fixed32)
constexpr std::size_t kCrcBytes = 5;

// The record's bytes, its checksum field appended (r has none set), behind
// its length.
std::string delimited(const rec::Record& r) {
  std::string body = r.SerializeAsString();
  const std::uint32_t crc = record_checksum(body.data(), body.size());
  body.push_back(kCrcTag);
  for (int i = 0; i < 4; ++i) body.push_back(static_cast<char>((crc >> (8 * i)) & 0xff));
  std::string out;
  out.reserve(body.size() + 5);
  append_varint(body.size(), &out);
  out += body;
  return out;
}

// Format 2: the record's last 5 bytes are the checksum field, and the
// checksum matches the bytes before it.
std::optional<std::string> check_checksum(const char* data, std::size_t len) {
  if (len < kCrcBytes || data[len - kCrcBytes] != kCrcTag) return "no checksum at the record's end (corrupt)";
  std::uint32_t stored = 0;
  for (int i = 0; i < 4; ++i)
    stored |= static_cast<std::uint32_t>(static_cast<unsigned char>(data[len - 4 + static_cast<std::size_t>(i)]))
              << (8 * i);
  const std::uint32_t computed = record_checksum(data, len - kCrcBytes);
  if (stored != computed) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "checksum mismatch: stored %08x, computed %08x (corrupt)", stored, computed);
    return std::string(buf);
  }
  return std::nullopt;
}

}  // namespace

void to_proto(const ServoTickRecord& r, rec::ServoTick* out) {
  out->Clear();
  out->set_tick(r.tick);
  out->set_t_ns(r.in.t_ns);
  out->set_model_version(r.model_version);
  out->set_view_presses(r.view_presses);
  out->set_mode(r.mode);
  out->set_remote_seq(r.remote_seq);
  for (int k = 0; k < r.in.end_effectors && k < device::kMaxEndEffectors; ++k) {
    const device::EndEffectorSample& s = r.in.ee[static_cast<std::size_t>(k)];
    rec::EndEffectorSample* e = out->add_ee();
    put(s.position_H, e->mutable_position());
    put(Eigen::Vector4d(s.orientation_H.w(), s.orientation_H.x(), s.orientation_H.y(), s.orientation_H.z()),
        e->mutable_orientation());
    put(s.velocity_H, e->mutable_velocity());
    put(s.angular_velocity_H, e->mutable_angular_velocity());
    e->set_buttons(s.handle.buttons);
    e->set_inputs(device::handle_input_bits(s.handle));
    e->set_deadman(s.handle.deadman);
    e->set_grip_position(s.handle.grip_position);
    e->set_grip_velocity(s.handle.grip_velocity);
    put(s.handle.joystick, e->mutable_joystick());
    e->set_switch_on(s.handle.switch_on);
    e->set_attached(s.handle.attached);
    e->set_enabled(s.enabled);
    const device::EndEffectorCommand& c = r.command.ee[static_cast<std::size_t>(k)];
    rec::Wrench* w = out->add_command();
    put(c.force_H, w->mutable_force());
    put(c.torque_H, w->mutable_torque());
    w->set_grip_force(c.grip_force);
  }
}

std::optional<std::string> from_proto(const rec::ServoTick& t, int end_effectors, ServoTickRecord* out) {
  if (t.ee_size() != end_effectors || t.command_size() != end_effectors)
    return "tick " + std::to_string(t.tick()) + ": " + std::to_string(t.ee_size()) + " end-effector samples and " +
           std::to_string(t.command_size()) + " wrenches, the header says " + std::to_string(end_effectors);
  for (int k = 0; k < end_effectors; ++k) {
    const rec::EndEffectorSample& e = t.ee(k);
    const rec::Wrench& w = t.command(k);
    if (!finite_of_size(e.position(), 3) || !finite_of_size(e.orientation(), 4) || !finite_of_size(e.velocity(), 3) ||
        !finite_of_size(e.angular_velocity(), 3) || !finite_of_size(e.joystick(), 2) ||
        !std::isfinite(e.grip_position()) || !std::isfinite(e.grip_velocity()))
      return "tick " + std::to_string(t.tick()) + ": end-effector " + std::to_string(k) +
             " sample has a field of the wrong size or a non-finite number";
    if (!finite_of_size(w.force(), 3) || !finite_of_size(w.torque(), 3) || !std::isfinite(w.grip_force()))
      return "tick " + std::to_string(t.tick()) + ": end-effector " + std::to_string(k) +
             " wrench has a field of the wrong size or a non-finite number";
  }
  ServoTickRecord r;
  r.tick = t.tick();
  r.in.t_ns = t.t_ns();
  r.in.end_effectors = end_effectors;
  r.model_version = t.model_version();
  r.view_presses = t.view_presses();
  r.mode = t.mode();
  r.remote_seq = t.remote_seq();
  for (int k = 0; k < end_effectors; ++k) {
    const rec::EndEffectorSample& e = t.ee(k);
    device::EndEffectorSample& s = r.in.ee[static_cast<std::size_t>(k)];
    s.position_H = Eigen::Vector3d(e.position(0), e.position(1), e.position(2));
    s.orientation_H = Eigen::Quaterniond(e.orientation(0), e.orientation(1), e.orientation(2), e.orientation(3));
    s.velocity_H = Eigen::Vector3d(e.velocity(0), e.velocity(1), e.velocity(2));
    s.angular_velocity_H = Eigen::Vector3d(e.angular_velocity(0), e.angular_velocity(1), e.angular_velocity(2));
    s.handle.buttons = e.buttons();
    s.handle.has_deadman = (e.inputs() & device::kHasDeadman) != 0;
    s.handle.has_grip = (e.inputs() & device::kHasGrip) != 0;
    s.handle.has_joystick = (e.inputs() & device::kHasJoystick) != 0;
    s.handle.has_clutch = (e.inputs() & device::kHasClutch) != 0;
    s.handle.deadman = e.deadman();
    s.handle.grip_position = e.grip_position();
    s.handle.grip_velocity = e.grip_velocity();
    s.handle.joystick = Eigen::Vector2d(e.joystick(0), e.joystick(1));
    s.handle.switch_on = e.switch_on();
    s.handle.attached = e.attached();
    s.enabled = e.enabled();
    const rec::Wrench& w = t.command(k);
    device::EndEffectorCommand& c = r.command.ee[static_cast<std::size_t>(k)];
    c.force_H = Eigen::Vector3d(w.force(0), w.force(1), w.force(2));
    c.torque_H = Eigen::Vector3d(w.torque(0), w.torque(1), w.torque(2));
    c.grip_force = w.grip_force();
  }
  *out = r;
  return std::nullopt;
}

void to_proto(const ModelThread::StepInputs& in, std::uint64_t version, rec::ModelStep* out) {
  out->Clear();
  out->set_version(version);
  out->set_now_ns(in.now_ns);
  out->set_clock_offset_ns(in.offset_ns);
  out->set_command_delay_ns(in.delay_ns);
  for (const SentCommand& c : in.commands) {
    rec::SentCommand* o = out->add_commands();
    o->set_t_ns(c.t_ns);
    o->set_v(c.v);
    o->set_omega(c.omega);
  }
  if (in.state) *out->mutable_state() = *in.state;
  for (const auto& s : in.scans)
    if (s) *out->add_scans() = *s;
}

// ------------------------------------------------------------------ writer

SessionRecorder::SessionRecorder(const std::string& path, const rec::Header& header, std::size_t tick_capacity)
    : ticks_(tick_capacity), end_effectors_(header.end_effectors()) {
  file_ = std::fopen(path.c_str(), "wb");
  if (file_ == nullptr) throw std::runtime_error("cannot open " + path + " for writing");
  rec::Record r;
  *r.mutable_header() = header;
  r.mutable_header()->set_magic(kRecordingMagic);
  r.mutable_header()->set_format_version(kRecordingFormatVersion);
  write(delimited(r));
  if (write_failed()) {
    std::fclose(file_);
    file_ = nullptr;
    throw std::runtime_error("cannot write to " + path);
  }
}

SessionRecorder::~SessionRecorder() { stop(); }

void SessionRecorder::start() {
  if (thread_.joinable() || file_ == nullptr) throw std::logic_error("SessionRecorder: started twice or stopped");
  thread_ = std::thread([this] { run(); });
}

void SessionRecorder::stop() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    stop_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  if (file_ != nullptr) {
    drain();
    if (std::fclose(file_) != 0) write_failed_.store(true);
    file_ = nullptr;
  }
}

void SessionRecorder::enqueue(const rec::Record& r) {
  std::string bytes = delimited(r);
  {
    std::lock_guard<std::mutex> lk(mu_);
    pending_.push_back(std::move(bytes));
  }
}

void SessionRecorder::model_step(const ModelThread::StepInputs& in, std::uint64_t version) {
  rec::Record r;
  to_proto(in, version, r.mutable_model_step());
  enqueue(r);
}

void SessionRecorder::stream(std::int64_t t_ns, bool outgoing, const wire::StreamMessage& m, std::uint64_t seq) {
  rec::Record r;
  r.mutable_stream()->set_t_ns(t_ns);
  r.mutable_stream()->set_outgoing(outgoing);
  r.mutable_stream()->set_seq(seq);
  *r.mutable_stream()->mutable_message() = m;
  enqueue(r);
}

void SessionRecorder::session(std::int64_t t_ns, bool outgoing, const wire::SessionFrame& f) {
  rec::Record r;
  r.mutable_session()->set_t_ns(t_ns);
  r.mutable_session()->set_outgoing(outgoing);
  *r.mutable_session()->mutable_frame() = f;
  enqueue(r);
}

void SessionRecorder::write(const std::string& bytes) {
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) write_failed_.store(true);
  records_.fetch_add(1, std::memory_order_relaxed);
}

void SessionRecorder::drain() {
  // The ticks taken first, the model steps after them, but written the other
  // way round: a tick's snapshot was published (its step queued) before the
  // tick, so every tick follows the step it rendered with in the file, and a
  // cut file keeps the steps its ticks need.
  ServoTickRecord t;
  rec::Record r;
  std::vector<std::string> ticks;
  while (ticks_.ring.try_pop(t)) {
    to_proto(t, r.mutable_tick());
    ticks.push_back(delimited(r));
  }
  std::vector<std::string> batch;
  {
    std::lock_guard<std::mutex> lk(mu_);
    batch.swap(pending_);
  }
  for (const std::string& b : batch) write(b);
  for (const std::string& b : ticks) write(b);
}

void SessionRecorder::run() {
  std::unique_lock<std::mutex> lk(mu_);
  while (!stop_) {
    cv_.wait_for(lk, std::chrono::milliseconds(5));
    lk.unlock();
    drain();
    lk.lock();
  }
}

// ------------------------------------------------------------------ reader

namespace {

// A varint at data[pos..]: its value and length, or 0 bytes if it runs past
// the end or over 10 bytes.
std::size_t read_varint(const std::string& data, std::size_t pos, std::uint64_t* v) {
  std::uint64_t x = 0;
  for (std::size_t i = 0; i < 10; ++i) {
    if (pos + i >= data.size()) return 0;
    const auto b = static_cast<unsigned char>(data[pos + i]);
    x |= static_cast<std::uint64_t>(b & 0x7f) << (7 * i);
    if ((b & 0x80) == 0) {
      *v = x;
      return i + 1;
    }
  }
  return 0;
}

}  // namespace

std::optional<std::string> check_recording_header(const rec::Header& h) {
  if (h.magic() != kRecordingMagic) return std::string("not a hemm recording (no '") + kRecordingMagic + "' header)";
  if (h.format_version() < 1 || h.format_version() > kRecordingFormatVersion)
    return "recording format version " + std::to_string(h.format_version()) + ", this build reads versions 1 to " +
           std::to_string(kRecordingFormatVersion);
  if (h.end_effectors() < 1 || h.end_effectors() > device::kMaxEndEffectors)
    return "header: end_effectors " + std::to_string(h.end_effectors()) + " outside 1.." +
           std::to_string(device::kMaxEndEffectors);
  if (h.initial_mode() > static_cast<std::uint32_t>(math::Mode::kManipulation))
    return "header: initial_mode " + std::to_string(h.initial_mode()) + " is not a mode";
  if (h.servo_period_ns() < 100'000 || h.servo_period_ns() > 1'000'000'000)
    return "header: servo_period_ns " + std::to_string(h.servo_period_ns()) + " outside [100 us, 1 s]";
  return std::nullopt;
}

std::optional<std::string> append_record(const rec::Record& record, Recording* r) {
  ServoTickRecord scratch;
  switch (record.body_case()) {
    case rec::Record::kHeader: return "a second header";
    case rec::Record::kTick:
      if (auto e = from_proto(record.tick(), r->header.end_effectors(), &scratch)) return e;
      if (!r->ticks.empty() && record.tick().tick() <= r->ticks.back().tick())
        return "tick " + std::to_string(record.tick().tick()) + " does not follow tick " +
               std::to_string(r->ticks.back().tick());
      r->ticks.push_back(record.tick());
      return std::nullopt;
    case rec::Record::kModelStep:
      if (!r->steps.empty() && record.model_step().version() <= r->steps.back().version())
        return "model step version " + std::to_string(record.model_step().version()) + " does not follow version " +
               std::to_string(r->steps.back().version());
      r->steps.push_back(record.model_step());
      return std::nullopt;
    case rec::Record::kStream: r->streams.push_back(record.stream()); return std::nullopt;
    case rec::Record::kSession: r->sessions.push_back(record.session()); return std::nullopt;
    case rec::Record::BODY_NOT_SET: break;
  }
  return "an empty record (unknown kind: corrupt or from a newer build)";
}

std::optional<std::string> load_recording(const std::string& path, Recording* out) {
  if (mcap::looks_like_mcap(path)) return load_mcap_recording(path, out);
  std::ifstream f(path, std::ios::binary);
  if (!f) return "cannot open " + path;
  const std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) return "cannot read " + path;
  Recording r;
  std::size_t pos = 0;
  std::uint64_t index = 0;
  rec::Record record;
  auto broke = [&](const std::string& why) -> std::optional<std::string> {
    const std::string e = path + ": record " + std::to_string(index) + " at byte " + std::to_string(pos) + ": " + why;
    if (index == 0) return e;  // no header: not a recording, nothing changes
    r.bytes = pos;
    *out = std::move(r);
    return e + " (the " + std::to_string(index) + " records before it are kept)";
  };
  while (pos < data.size()) {
    std::uint64_t len = 0;
    const std::size_t n = read_varint(data, pos, &len);
    if (n == 0) return broke("truncated or corrupt length prefix");
    if (len > kMaxRecordBytes) return broke("length " + std::to_string(len) + " bytes is too large (corrupt)");
    if (len > data.size() - pos - n)
      return broke("truncated: the record has " + std::to_string(len) + " bytes, the file " +
                   std::to_string(data.size() - pos - n) + " left");
    const char* body = data.data() + pos + n;
    // After the header, a checksum is checked before the bytes are parsed.
    if (index > 0 && r.header.format_version() >= 2)
      if (auto e = check_checksum(body, static_cast<std::size_t>(len))) return broke(*e);
    if (!record.ParseFromArray(body, static_cast<int>(len)))
      return broke("does not parse as a hemm.rec.Record (corrupt)");
    if (index == 0) {
      if (!record.has_header()) return broke("not a hemm recording (the first record is not a header)");
      if (auto e = check_recording_header(record.header())) return broke(*e);
      if (record.header().format_version() >= 2)
        if (auto e = check_checksum(body, static_cast<std::size_t>(len))) return broke(*e);
      r.header = record.header();
    } else if (auto e = append_record(record, &r)) {
      return broke(*e);
    }
    pos += n + static_cast<std::size_t>(len);
    ++index;
    r.records = index;
  }
  if (index == 0) return path + ": empty file, not a hemm recording";
  r.bytes = pos;
  *out = std::move(r);
  return std::nullopt;
}

bool looks_like_recording(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::string head(64, '\0');
  f.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(f.gcount()));
  return head.find(kRecordingMagic) != std::string::npos || mcap::looks_like_mcap(path);
}

}  // namespace hemm::op
