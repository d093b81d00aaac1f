#include "firmware/service/preview_image.h"

#include <zlib.h>

#include <map>
#include <string>

#include <gtest/gtest.h>

namespace mirrorscan::service {
namespace {

uint32_t U32(const std::string& s, size_t at) {
  return (uint32_t{static_cast<uint8_t>(s[at])} << 24) |
         (uint32_t{static_cast<uint8_t>(s[at + 1])} << 16) |
         (uint32_t{static_cast<uint8_t>(s[at + 2])} << 8) |
         uint32_t{static_cast<uint8_t>(s[at + 3])};
}

// The PNG's chunks by type, each CRC checked with zlib's crc32.
std::map<std::string, std::string> Chunks(const std::string& png) {
  std::map<std::string, std::string> chunks;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  for (size_t at = 8; at + 12 <= png.size();) {
    const uint32_t length = U32(png, at);
    const std::string type = png.substr(at + 4, 4);
    const std::string body = png.substr(at + 4, 4 + length);
    EXPECT_EQ(U32(png, at + 8 + length),
              crc32(0, reinterpret_cast<const Bytef*>(body.data()), body.size()))
        << type;
    chunks[type] += png.substr(at + 8, length);
    at += 12 + length;
  }
  return chunks;
}

TEST(PreviewImage, ShrinksTheFrameAndDrawsThePeaksInRed) {
  const int width = 64, height = 48;
  std::vector<uint8_t> frame(width * height);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) frame[y * width + x] = static_cast<uint8_t>(x < 32 ? 40 : 200);
  frame[0] = 255;  // a saturated pixel must not turn red
  frame[1] = 255;
  frame[width] = 255;
  frame[width + 1] = 255;
  Peak peak;
  peak.u = 21;
  peak.v = 30.4f;  // row 30 -> preview row 15, column 10
  const std::string png = RenderPreviewPng(frame, width, height, {peak}, 2);
  auto chunks = Chunks(png);
  ASSERT_EQ(chunks.count("IHDR"), 1u);
  EXPECT_EQ(U32(chunks["IHDR"], 0), 32u);
  EXPECT_EQ(U32(chunks["IHDR"], 4), 24u);
  EXPECT_EQ(chunks["IHDR"].substr(8), std::string("\x08\x03\x00\x00\x00", 5));
  ASSERT_EQ(chunks["PLTE"].size(), 256u * 3);
  EXPECT_EQ(chunks["PLTE"].substr(255 * 3), "\xff\x20\x20");     // red
  EXPECT_EQ(chunks["PLTE"].substr(254 * 3, 3), "\xff\xff\xff");  // white
  EXPECT_EQ(chunks.count("IEND"), 1u);
  std::string raw(33 * 24, '\0');
  uLongf size = raw.size();
  ASSERT_EQ(
      uncompress(reinterpret_cast<Bytef*>(raw.data()), &size,
                 reinterpret_cast<const Bytef*>(chunks["IDAT"].data()), chunks["IDAT"].size()),
      Z_OK);
  ASSERT_EQ(size, raw.size());
  auto at = [&](int x, int y) { return static_cast<uint8_t>(raw[y * 33 + 1 + x]); };
  for (int y = 0; y < 24; ++y) EXPECT_EQ(raw[y * 33], '\0');  // filter: none
  EXPECT_EQ(at(0, 0), 254);  // saturated white, not the peak colour
  EXPECT_EQ(at(5, 5), 40);
  EXPECT_EQ(at(20, 5), 200);
  EXPECT_EQ(at(10, 15), kPreviewPeakIndex);
  EXPECT_EQ(at(11, 15), 40);
}

TEST(PreviewImage, RefusesMalformedFrames) {
  EXPECT_THROW(RenderPreviewPng(std::vector<uint8_t>(10), 4, 4, {}, 1), std::invalid_argument);
  EXPECT_THROW(RenderPreviewPng(std::vector<uint8_t>(16), 4, 4, {}, 0), std::invalid_argument);
}

}  // namespace
}  // namespace mirrorscan::service
