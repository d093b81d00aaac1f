#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "firmware/hal/camera.h"

namespace mirrorscan::hal {

struct PgmHeader {
  int width = 0, height = 0, maxval = 0;
  std::streamoff data_offset = 0;  // where the pixels start
};

// Reads the header of a binary 8-bit PGM (P5, maxval <= 255, '#' comments allowed).
// Throws HardwareError kIo "<file>: problem" if it cannot be read or is not such a file.
PgmHeader ReadPgmHeader(const std::filesystem::path& file);
// Reads the pixels of `file` (header already checked to be width x height) into `pixels`.
void ReadPgmPixels(const std::filesystem::path& file, const PgmHeader& header, uint8_t* pixels);
// Writes an 8-bit P5 PGM (for tests and tools); throws HardwareError kIo.
void WritePgm(const std::filesystem::path& file, int width, int height, const uint8_t* pixels);

struct ReplayOptions {
  std::filesystem::path directory;  // plays every *.pgm in it, in file name order
  bool loop = false;                // start again after the last file
};

// A Camera that plays recorded frames: the *.pgm files (P5, 8-bit) of a directory in
// name order, at the configured fps, or with fps == 0 as fast as the consumer releases
// buffers (then nothing is ever dropped). Frame k of the stream is file k % n; a frame
// dropped for want of a buffer skips its file, as a live camera would lose it. Without
// looping the stream ends after the last file (end callback with nullptr).
//
// PGM only: the board has no PNG decoder. `mirrorscan sim scan --pgm` writes its frames
// as PGM; its PNGs convert with any tool, e.g. `convert in.png -depth 8 out.pgm`
// (ImageMagick) or `pngtopnm in.png > out.pgm` (netpbm).
//
// Start() lists the directory and checks every file's header, so a missing directory, no
// files, a file that is not an 8-bit P5 PGM, or a size other than the configured one is a
// HardwareError (kIo, or kInvalidArgument for the size) naming the file before anything
// streams. A file that becomes unreadable later ends the stream with that error.
class ReplayCamera final : public ThreadedCamera {
 public:
  explicit ReplayCamera(ReplayOptions options);
  ~ReplayCamera() override;

  const std::vector<std::filesystem::path>& files() const { return files_; }

 protected:
  void BeginStream() override;
  Produced Plan(uint64_t sequence) override;
  Produced Produce(uint64_t sequence, int64_t timestamp_ns, uint8_t* pixels) override;

 private:
  ReplayOptions options_;
  std::vector<std::filesystem::path> files_;
  std::vector<PgmHeader> headers_;
};

}  // namespace mirrorscan::hal
