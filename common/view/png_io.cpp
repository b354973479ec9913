#include "common/view/png_io.h"

#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <memory>
#include <vector>

namespace hemm::view {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const {
    if (f != nullptr) std::fclose(f);
  }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// libpng reports errors through longjmp (set up in each function); its
// warnings are not errors for us.
void ignore_warning(png_structp, png_const_charp) {}


// libpng reports errors by longjmp to the setjmp in these functions: they
// hold only plain C data, so the jump skips no destructor and clobbers
// nothing that is read after it.
bool write_image_c(png_structp png, png_infop info, std::FILE* f, const std::uint8_t* rgb, int w, int h,
                   png_text* text, int ntext) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  png_set_compression_level(png, 1);
  png_set_IHDR(png, info, static_cast<png_uint_32>(w), static_cast<png_uint_32>(h), 8, PNG_COLOR_TYPE_RGB,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (ntext > 0) png_set_text(png, info, text, ntext);
  png_write_info(png, info);
  for (int y = 0; y < h; ++y) png_write_row(png, rgb + static_cast<std::size_t>(y) * w * 3);
  png_write_end(png, nullptr);
  return true;
}

bool read_info_c(png_structp png, png_infop info, std::FILE* f, png_uint_32* w, png_uint_32* h, int* depth,
                 int* type) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_init_io(png, f);
  png_set_sig_bytes(png, 8);
  png_read_info(png, info);
  *w = png_get_image_width(png, info);
  *h = png_get_image_height(png, info);
  *depth = png_get_bit_depth(png, info);
  *type = png_get_color_type(png, info);
  return true;
}

bool read_rows_c(png_structp png, png_infop info, std::uint8_t* rgb, png_uint_32 w, png_uint_32 h, int strip_alpha) {
  if (setjmp(png_jmpbuf(png))) return false;
  if (strip_alpha) png_set_strip_alpha(png);
  png_read_update_info(png, info);
  for (png_uint_32 y = 0; y < h; ++y) png_read_row(png, rgb + static_cast<std::size_t>(y) * w * 3, nullptr);
  png_read_end(png, info);
  return true;
}

}  // namespace

std::optional<std::string> write_png(const std::string& path, const Image& image, const TextChunks& text) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * image.height * 3)
    return "write_png: bad image size";
  File f(std::fopen(path.c_str(), "wb"));
  if (!f) return "cannot open " + path + " for writing";
  std::vector<png_text> chunks(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    chunks[i] = png_text{};
    chunks[i].compression = PNG_TEXT_COMPRESSION_NONE;
    chunks[i].key = const_cast<char*>(text[i].first.c_str());
    chunks[i].text = const_cast<char*>(text[i].second.c_str());
    chunks[i].text_length = text[i].second.size();
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, ignore_warning);
  if (png == nullptr) return "png_create_write_struct failed";
  png_infop info = png_create_info_struct(png);
  const bool ok = info != nullptr && write_image_c(png, info, f.get(), image.rgb.data(), image.width, image.height,
                                                   chunks.data(), static_cast<int>(chunks.size()));
  png_destroy_write_struct(&png, info != nullptr ? &info : nullptr);
  if (!ok || std::fflush(f.get()) != 0) return "write failed: " + path;
  return std::nullopt;
}

std::optional<std::string> read_png(const std::string& path, Image* image, TextChunks* text) {
  File f(std::fopen(path.c_str(), "rb"));
  if (!f) return "cannot open " + path;
  unsigned char sig[8];
  if (std::fread(sig, 1, 8, f.get()) != 8 || png_sig_cmp(sig, 0, 8) != 0) return path + ": not a PNG file";
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, ignore_warning);
  if (png == nullptr) return "png_create_read_struct failed";
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return "png_create_info_struct failed";
  }
  png_uint_32 w = 0, h = 0;
  int depth = 0, type = 0;
  std::optional<std::string> error;
  Image out;
  if (!read_info_c(png, info, f.get(), &w, &h, &depth, &type)) {
    error = path + ": corrupt or truncated PNG";
  } else if (depth != 8 || (type != PNG_COLOR_TYPE_RGB && type != PNG_COLOR_TYPE_RGB_ALPHA) || w == 0 || h == 0 ||
             w > 16384 || h > 16384) {
    error = path + ": not an 8-bit RGB(A) PNG of at most 16384 x 16384";
  } else {
    out.width = static_cast<int>(w);
    out.height = static_cast<int>(h);
    out.rgb.resize(static_cast<std::size_t>(w) * h * 3);
    if (!read_rows_c(png, info, out.rgb.data(), w, h, type == PNG_COLOR_TYPE_RGB_ALPHA ? 1 : 0))
      error = path + ": corrupt or truncated PNG";
  }
  if (!error && text != nullptr) {
    text->clear();
    png_textp chunks = nullptr;
    int n = 0;
    png_get_text(png, info, &chunks, &n);
    for (int i = 0; i < n; ++i) text->emplace_back(chunks[i].key, std::string(chunks[i].text, chunks[i].text_length));
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (error) return error;
  *image = std::move(out);
  return std::nullopt;
}

std::optional<std::string> find_text(const TextChunks& text, const std::string& key) {
  for (const auto& [k, v] : text)
    if (k == key) return v;
  return std::nullopt;
}

}  // namespace hemm::view
