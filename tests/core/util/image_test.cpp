// EXR and PNG output: written, read back, and never left half-written.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/util/error.h"
#include "core/util/image.h"
#include "tests/test_util.h"

namespace sl {
namespace {

Image test_image() {
  Image img(7, 5);
  for (int y = 0; y < 5; ++y)
    for (int x = 0; x < 7; ++x) img.at(x, y) = vec4(x / 7.0f, y / 5.0f, 0.25f, 0.5f + 0.1f * x / 7.0f);
  auto& s = img.channel("samples");
  for (std::size_t i = 0; i < s.size(); ++i) s[i] = float(i * 3);
  return img;
}

TEST(ImageIo, ExrRoundTripKeepsRgbaAndExtraChannels) {
  const auto dir = test::scratch_dir();
  const Image img = test_image();
  write_exr((dir / "a.exr").string(), img);
  const Image back = read_exr((dir / "a.exr").string());
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  for (std::size_t i = 0; i < img.rgba.size(); ++i) EXPECT_EQ(back.rgba[i], img.rgba[i]);
  ASSERT_TRUE(back.channels.count("samples"));
  EXPECT_EQ(back.channels.at("samples"), img.channels.at("samples"));
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    EXPECT_EQ(e.path().filename(), "a.exr");  // no temporary left behind
  }
}

TEST(ImageIo, PngIsSrgbOverBlack) {
  const auto dir = test::scratch_dir();
  Image img(2, 1);
  img.at(0, 0) = vec4(0.5f, 0.0f, 1.0f, 1.0f);
  img.at(1, 0) = vec4(0.0f);
  write_png((dir / "a.png").string(), img);
  const Image back = read_png((dir / "a.png").string());
  EXPECT_NEAR(back.at(0, 0).x, linear_to_srgb(0.5f), 1.0f / 255.0f);
  EXPECT_NEAR(back.at(0, 0).x, 0.7354f, 1.0f / 255.0f);
  EXPECT_EQ(back.at(0, 0).y, 0.0f);
  EXPECT_EQ(back.at(0, 0).z, 1.0f);
  EXPECT_EQ(back.at(1, 0).x, 0.0f);
}

TEST(ImageIo, UnwritablePathThrowsAndLeavesNothing) {
  const auto dir = test::scratch_dir();
  const Image img = test_image();
  EXPECT_THROW(write_png((dir / "missing" / "a.png").string(), img), InputError);
  EXPECT_THROW(write_exr((dir / "missing" / "a.exr").string(), img), InputError);
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  EXPECT_THROW(check_output_prefix((dir / "missing" / "out").string()), InputError);
  EXPECT_NO_THROW(check_output_prefix((dir / "out").string()));
}

TEST(ImageIo, CorruptExrIsAClearError) {
  const auto dir = test::scratch_dir();
  test::write_text(dir / "bad.exr", "not an exr file at all");
  try {
    read_exr((dir / "bad.exr").string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.exr"), std::string::npos);
  }
}

}  // namespace
}  // namespace sl
