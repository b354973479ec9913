// PNG files of the live views: a picture and its text chunks come back
// exactly; a truncated or foreign file is refused with a reason and leaves
// the output untouched; the sequence numbers its pictures and paces them.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "common/view/png_io.h"
#include "common/view/png_sequence.h"

namespace hv = hemm::view;

namespace {

std::string temp_dir() {
  char tmpl[] = "/tmp/hemm_png_XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d ? d : "/tmp";
}

hv::Image gradient(int w, int h) {
  hv::Image img;
  img.width = w;
  img.height = h;
  img.rgb.resize(static_cast<std::size_t>(w) * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      std::uint8_t* p = &img.rgb[(static_cast<std::size_t>(y) * w + x) * 3];
      p[0] = static_cast<std::uint8_t>(x * 7);
      p[1] = static_cast<std::uint8_t>(y * 13);
      p[2] = static_cast<std::uint8_t>((x ^ y) * 3);
    }
  return img;
}

TEST(Png, RoundTripKeepsEveryPixelAndText) {
  const std::string dir = temp_dir();
  const hv::Image img = gradient(37, 23);
  ASSERT_FALSE(hv::write_png(dir + "/a.png", img, {{"hemm:camera", "1 2 3"}, {"k", ""}}));
  hv::Image back;
  hv::TextChunks text;
  ASSERT_FALSE(hv::read_png(dir + "/a.png", &back, &text));
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 23);
  EXPECT_EQ(back.rgb, img.rgb);
  EXPECT_EQ(hv::find_text(text, "hemm:camera").value_or("?"), "1 2 3");
  EXPECT_EQ(hv::find_text(text, "k").value_or("?"), "");
  EXPECT_FALSE(hv::find_text(text, "absent"));
  EXPECT_EQ(back.at(5, 2)[0], 35);  // rows top first: (x 5, y 2)
  EXPECT_EQ(back.at(5, 2)[1], 26);
  std::filesystem::remove_all(dir);
}

TEST(Png, TruncatedOrForeignFilesAreRefusedAndChangeNothing) {
  const std::string dir = temp_dir();
  ASSERT_FALSE(hv::write_png(dir + "/a.png", gradient(64, 64)));
  const auto size = std::filesystem::file_size(dir + "/a.png");
  std::filesystem::copy_file(dir + "/a.png", dir + "/cut.png");
  std::filesystem::resize_file(dir + "/cut.png", size / 2);
  {
    std::ofstream f(dir + "/text.png");
    f << "not a picture at all";
  }
  hv::Image out = gradient(2, 2);
  const auto before = out.rgb;
  const auto cut = hv::read_png(dir + "/cut.png", &out);
  ASSERT_TRUE(cut);
  EXPECT_NE(cut->find("truncated"), std::string::npos) << *cut;
  const auto foreign = hv::read_png(dir + "/text.png", &out);
  ASSERT_TRUE(foreign);
  EXPECT_NE(foreign->find("not a PNG"), std::string::npos) << *foreign;
  EXPECT_TRUE(hv::read_png(dir + "/missing.png", &out));
  EXPECT_EQ(out.rgb, before);
  EXPECT_EQ(out.width, 2);
  hv::Image bad;
  bad.width = 3;
  bad.height = 3;  // no pixels
  EXPECT_TRUE(hv::write_png(dir + "/bad.png", bad));
  std::filesystem::remove_all(dir);
}

TEST(PngSequence, NumbersPicturesAndPacesThem) {
  const std::string dir = temp_dir() + "/sub/dir";
  hv::PngSequence seq(dir, 1'000'000'000);
  EXPECT_TRUE(seq.due(5));  // the first at once
  ASSERT_FALSE(seq.write(gradient(8, 8), {}, 5));
  EXPECT_FALSE(seq.due(999'999'999));
  EXPECT_TRUE(seq.due(1'000'000'005));
  ASSERT_FALSE(seq.write(gradient(8, 8), {}, 3'500'000'000));  // late: the next one an interval after now
  EXPECT_EQ(seq.next_due_ns(), 4'500'000'000);
  ASSERT_FALSE(seq.write_last(gradient(8, 8), {}));
  EXPECT_EQ(seq.written(), 2u);
  EXPECT_TRUE(std::filesystem::exists(dir + "/view_00000.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/view_00001.png"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/view_last.png"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/view_00002.png"));
  EXPECT_THROW(hv::PngSequence("/proc/hemm_no/such", 1), std::runtime_error);
}

}  // namespace
