#include "common/view/png_sequence.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <system_error>

namespace hemm::view {

PngSequence::PngSequence(std::string dir, std::int64_t interval_ns) : dir_(std::move(dir)), interval_ns_(interval_ns) {
  if (interval_ns_ <= 0) throw std::invalid_argument("PngSequence: interval must be positive");
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec || !std::filesystem::is_directory(dir_)) throw std::runtime_error("cannot create directory " + dir_);
}

std::optional<std::string> PngSequence::write(const Image& image, const TextChunks& text, std::int64_t now_ns) {
  char name[32];
  std::snprintf(name, sizeof name, "/view_%05llu.png", static_cast<unsigned long long>(written_));
  // The next one an interval after this one, or after now if we fell behind.
  next_ns_ = (next_ns_ == 0 ? now_ns : next_ns_) + interval_ns_;
  if (next_ns_ <= now_ns) next_ns_ = now_ns + interval_ns_;
  auto e = write_png(dir_ + name, image, text);
  if (!e) ++written_;
  return e;
}

std::optional<std::string> PngSequence::write_last(const Image& image, const TextChunks& text) {
  return write_png(dir_ + "/view_last.png", image, text);
}

TextChunks camera_text(const CameraSpec& c, double fovy_deg) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g", c.lookat.x(), c.lookat.y(), c.lookat.z(),
                c.distance, c.azimuth, c.elevation, fovy_deg);
  return {{"hemm:camera", buf}};
}

bool lower_this_thread_priority() {
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  return ::setpriority(PRIO_PROCESS, tid, 10) == 0;
}

}  // namespace hemm::view
