#include "firmware/service/preview_image.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mirrorscan::service {
namespace {

void PutU32(std::string& out, uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<char>(value >> shift));
}

void PutChunk(std::string& out, const char type[5], const std::string& data) {
  PutU32(out, static_cast<uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  out += body;
  PutU32(out, static_cast<uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(body.data()),
                                          static_cast<uInt>(body.size()))));
}

}  // namespace

std::string RenderPreviewPng(const std::vector<uint8_t>& pixels, int width, int height,
                             const std::vector<Peak>& peaks, int scale) {
  if (width <= 0 || height <= 0 || scale < 1 ||
      pixels.size() != static_cast<size_t>(width) * static_cast<size_t>(height)) {
    throw std::invalid_argument("preview: malformed frame");
  }
  const int w = std::max(1, width / scale);
  const int h = std::max(1, height / scale);
  // Gray levels 0..254 (255 is the peaks' red), box-averaged over scale x scale.
  std::vector<uint8_t> image(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      uint32_t sum = 0;
      int count = 0;
      for (int dy = 0; dy < scale && y * scale + dy < height; ++dy) {
        for (int dx = 0; dx < scale && x * scale + dx < width; ++dx) {
          sum += pixels[static_cast<size_t>(y * scale + dy) * width + x * scale + dx];
          ++count;
        }
      }
      image[static_cast<size_t>(y) * w + x] =
          static_cast<uint8_t>(std::min<uint32_t>(254, (sum + count / 2) / count));
    }
  }
  for (const Peak& peak : peaks) {
    const int x = peak.u / scale;
    const int y = static_cast<int>(std::lround(peak.v)) / scale;
    if (x >= 0 && x < w && y >= 0 && y < h)
      image[static_cast<size_t>(y) * w + x] = kPreviewPeakIndex;
  }

  std::string raw;  // each row after its filter byte (0: none)
  raw.reserve(static_cast<size_t>(w + 1) * h);
  for (int y = 0; y < h; ++y) {
    raw.push_back('\0');
    raw.append(reinterpret_cast<const char*>(&image[static_cast<size_t>(y) * w]), w);
  }
  uLongf compressed_size = compressBound(static_cast<uLong>(raw.size()));
  std::string compressed(compressed_size, '\0');
  // Level 1: the frame is mostly smooth background; speed matters more on the board.
  if (compress2(reinterpret_cast<Bytef*>(compressed.data()), &compressed_size,
                reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()),
                1) != Z_OK) {
    throw std::runtime_error("preview: zlib failed");
  }
  compressed.resize(compressed_size);

  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::string header;
  PutU32(header, static_cast<uint32_t>(w));
  PutU32(header, static_cast<uint32_t>(h));
  header +=
      std::string("\x08\x03\x00\x00\x00", 5);  // 8-bit, palette, deflate, no filter, no interlace
  PutChunk(png, "IHDR", header);
  std::string palette;
  for (int i = 0; i < 255; ++i) {
    const char level = static_cast<char>((i * 255 + 127) / 254);
    palette += std::string(3, level);
  }
  palette += std::string("\xff\x20\x20", 3);  // kPreviewPeakIndex
  PutChunk(png, "PLTE", palette);
  PutChunk(png, "IDAT", compressed);
  PutChunk(png, "IEND", "");
  return png;
}

}  // namespace mirrorscan::service
