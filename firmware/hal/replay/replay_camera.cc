#include "firmware/hal/replay/replay_camera.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <system_error>
#include <utility>

namespace mirrorscan::hal {
namespace {

[[noreturn]] void Fail(const std::filesystem::path& file, const std::string& problem) {
  throw HardwareError(HardwareError::Kind::kIo, file.string() + ": " + problem);
}

// Skips whitespace and '#' comments (to the end of the line) between header fields.
void SkipSpace(std::istream& in) {
  for (;;) {
    const int c = in.peek();
    if (c == '#') {
      std::string comment;
      std::getline(in, comment);
    } else if (c != EOF && std::isspace(c)) {
      in.get();
    } else {
      return;
    }
  }
}

int ReadField(std::istream& in, const std::filesystem::path& file, const char* what) {
  SkipSpace(in);
  long value = 0;
  int digits = 0;
  while (std::isdigit(in.peek()) && digits < 9) {
    value = value * 10 + (in.get() - '0');
    ++digits;
  }
  if (digits == 0 || std::isdigit(in.peek())) {
    Fail(file, std::string("not an 8-bit P5 PGM (bad ") + what + ")");
  }
  return static_cast<int>(value);
}

}  // namespace

PgmHeader ReadPgmHeader(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) Fail(file, "cannot open");
  char magic[2] = {};
  in.read(magic, 2);
  if (!in || magic[0] != 'P' || magic[1] != '5') Fail(file, "not an 8-bit P5 PGM (magic)");
  PgmHeader h;
  h.width = ReadField(in, file, "width");
  h.height = ReadField(in, file, "height");
  h.maxval = ReadField(in, file, "maxval");
  if (h.width <= 0 || h.height <= 0) Fail(file, "not an 8-bit P5 PGM (empty image)");
  if (h.maxval < 1 || h.maxval > 255) {
    Fail(file, "not an 8-bit P5 PGM (maxval " + std::to_string(h.maxval) + ", need <= 255)");
  }
  if (!std::isspace(in.get())) Fail(file, "not an 8-bit P5 PGM (no space after maxval)");
  h.data_offset = in.tellg();
  std::error_code ec;
  const auto size = std::filesystem::file_size(file, ec);
  if (ec) Fail(file, "cannot stat: " + ec.message());
  const auto need = static_cast<uintmax_t>(h.data_offset) +
                    static_cast<uintmax_t>(h.width) * static_cast<uintmax_t>(h.height);
  if (size < need) {
    Fail(file, "truncated: " + std::to_string(size) + " bytes, need " + std::to_string(need));
  }
  return h;
}

void ReadPgmPixels(const std::filesystem::path& file, const PgmHeader& header, uint8_t* pixels) {
  std::ifstream in(file, std::ios::binary);
  if (!in) Fail(file, "cannot open");
  in.seekg(header.data_offset);
  const auto n = static_cast<std::streamsize>(header.width) * header.height;
  in.read(reinterpret_cast<char*>(pixels), n);
  if (in.gcount() != n) Fail(file, "truncated pixel data");
}

void WritePgm(const std::filesystem::path& file, int width, int height, const uint8_t* pixels) {
  std::ofstream out(file, std::ios::binary);
  if (!out) Fail(file, "cannot create");
  out << "P5\n" << width << " " << height << "\n255\n";
  out.write(reinterpret_cast<const char*>(pixels), static_cast<std::streamsize>(width) * height);
  if (!out) Fail(file, "write failed");
}

ReplayCamera::ReplayCamera(ReplayOptions options) : options_(std::move(options)) {}

ReplayCamera::~ReplayCamera() { Stop(); }

void ReplayCamera::BeginStream() {
  const auto& dir = options_.directory;
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) Fail(dir, "replay: no such directory");
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.path().extension() == ".pgm") files.push_back(entry.path());
  }
  if (ec) Fail(dir, "replay: cannot list: " + ec.message());
  if (files.empty()) Fail(dir, "replay: no *.pgm files");
  std::sort(files.begin(), files.end());
  std::vector<PgmHeader> headers;
  for (const auto& file : files) {
    headers.push_back(ReadPgmHeader(file));
    const PgmHeader& h = headers.back();
    if (h.width != config().width || h.height != config().height) {
      throw HardwareError(HardwareError::Kind::kInvalidArgument,
                          file.string() + ": " + std::to_string(h.width) + "x" +
                              std::to_string(h.height) + ", camera configured for " +
                              std::to_string(config().width) + "x" +
                              std::to_string(config().height));
    }
  }
  files_ = std::move(files);
  headers_ = std::move(headers);
}

ThreadedCamera::Produced ReplayCamera::Plan(uint64_t sequence) {
  return !options_.loop && sequence >= files_.size() ? Produced::kEnd : Produced::kFrame;
}

ThreadedCamera::Produced ReplayCamera::Produce(uint64_t sequence, int64_t /*timestamp_ns*/,
                                               uint8_t* pixels) {
  const size_t i = static_cast<size_t>(sequence % files_.size());
  ReadPgmPixels(files_[i], headers_[i], pixels);
  return Produced::kFrame;
}

}  // namespace mirrorscan::hal
