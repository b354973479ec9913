// The live views' pictures on disk: view_00000.png, view_00001.png, ... one
// every interval, and view_last.png at the end, each with text chunks that
// say what it shows (time, camera). Also: lowering the calling thread's CPU
// priority, so that rendering (software OpenGL on a 2-core machine) yields to
// the servo, simulation and network threads.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "common/view/png_io.h"
#include "common/view/primitives.h"

namespace hemm::view {

class PngSequence {
 public:
  // Creates `dir` (and parents) if missing; throws std::runtime_error if it
  // cannot. interval_ns > 0.
  PngSequence(std::string dir, std::int64_t interval_ns);
  // True when a picture is due at now_ns (the first one at once).
  bool due(std::int64_t now_ns) const { return now_ns >= next_ns_; }
  std::int64_t next_due_ns() const { return next_ns_; }
  // Writes the next numbered picture and schedules the one after.
  std::optional<std::string> write(const Image& image, const TextChunks& text, std::int64_t now_ns);
  std::optional<std::string> write_last(const Image& image, const TextChunks& text);
  std::uint64_t written() const { return written_; }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
  std::int64_t interval_ns_;
  std::int64_t next_ns_ = 0;
  std::uint64_t written_ = 0;
};

// Text chunks describing a camera ("hemm:camera" = "lookat_x lookat_y
// lookat_z distance azimuth elevation fovy", degrees) so a reader can project
// W points into the picture.
TextChunks camera_text(const CameraSpec& c, double fovy_deg);

// Nice value 10 for the calling thread (Linux: per thread); false if refused.
bool lower_this_thread_priority();

}  // namespace hemm::view
