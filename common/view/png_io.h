// RGB images and PNG files (libpng) for the live views' screenshots: written
// by the views (deploy/demo.sh keeps them), read back by the tests that check
// what the pixels show. Text chunks carry what a picture stands for (frame
// time, camera), so a reader can project known points into it.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hemm::view {

// 8-bit RGB, rows top first (as an image file, not as OpenGL reads them).
struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  // width * height * 3

  const std::uint8_t* at(int x, int y) const { return &rgb[(static_cast<std::size_t>(y) * width + x) * 3]; }
};

using TextChunks = std::vector<std::pair<std::string, std::string>>;

// Writes `image` to `path` (fast compression: the views write while they
// run). Returns an error message, or nullopt on success.
std::optional<std::string> write_png(const std::string& path, const Image& image, const TextChunks& text = {});

// Reads an 8-bit RGB or RGBA PNG (alpha dropped). Returns an error message
// (unreadable, not a PNG, truncated, another pixel format), or nullopt.
std::optional<std::string> read_png(const std::string& path, Image* image, TextChunks* text = nullptr);

// The value of `key` in `text`, if present.
std::optional<std::string> find_text(const TextChunks& text, const std::string& key);

}  // namespace hemm::view
