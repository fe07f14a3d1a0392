// tools/png: what write_png writes, read_png reads back exactly; the file is compressed; a file
// that is not a PNG of ours gets an error naming it.
#include "common/png/png.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace {

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("grotto-png-" + std::to_string(getpid()) + "-" + name))
      .string();
}

TEST(Png, round_trips_an_image_and_compresses_it) {
  const int w = 320, h = 200;
  std::vector<unsigned char> rgb(static_cast<size_t>(w) * h * 3);
  for (int y = 0; y < h; ++y)  // a dark gradient with a bright square: like a screenshot
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        rgb[(static_cast<size_t>(y) * w + x) * 3 + c] = static_cast<unsigned char>(
            (x > 100 && x < 150 && y > 50 && y < 90) ? 230 - 20 * c : (x + y * c) / 8);
  const std::string path = temp_path("round.png");
  ASSERT_TRUE(grotto::png::write_png(path, rgb, w, h).ok());
  const auto size = std::filesystem::file_size(path);
  auto back = grotto::png::read_png(path);
  std::filesystem::remove(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back.value().width, w);
  EXPECT_EQ(back.value().height, h);
  EXPECT_EQ(back.value().rgb, rgb);
  EXPECT_LT(size, rgb.size() / 10) << "a smooth picture compresses well";
}

TEST(Png, refuses_a_size_that_does_not_match_the_pixels) {
  EXPECT_FALSE(
      grotto::png::write_png(temp_path("x.png"), std::vector<unsigned char>(5), 2, 2).ok());
}

TEST(Png, a_file_that_is_not_a_png_gets_an_error_naming_it) {
  const std::string path = temp_path("not.png");
  std::ofstream(path) << "GIF89a this is not a PNG at all, just some bytes long enough";
  auto r = grotto::png::read_png(path);
  EXPECT_FALSE(r.ok());
  if (!r.ok()) {
    EXPECT_NE(r.error().message.find(path + ": not a PNG"), std::string::npos);
  }
  // A truncated PNG: the image data does not inflate to the size its header promises.
  std::vector<unsigned char> rgb(64 * 64 * 3, 90);
  ASSERT_TRUE(grotto::png::write_png(path, rgb, 64, 64).ok());
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - 30);
  r = grotto::png::read_png(path);
  EXPECT_FALSE(r.ok());
  std::filesystem::remove(path);
  EXPECT_FALSE(grotto::png::read_png(path).ok()) << "a missing file";
}

}  // namespace
