#pragma once

// The .mscan scan archive (docs/scan-format.md): the device appends records while it
// scans; a cut or damaged archive still yields its valid prefix and a report saying so.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/scan_format/peak.h"

namespace mirrorscan {

// "MSCAN", NUL, format version, newline.
inline constexpr uint8_t kScanFormatVersion = 1;
inline constexpr std::array<uint8_t, 8> kScanMagic = {
    'M', 'S', 'C', 'A', 'N', 0, kScanFormatVersion, '\n'};
// A larger declared length is corruption, never a reason to wait for (or allocate) more.
inline constexpr uint32_t kMaxRecordPayload = 64u << 20;
inline constexpr size_t kRecordOverhead = 12;  // u32 type, u32 length, ..., u32 crc32
inline constexpr size_t kFrameFixedSize = 28;  // frame payload before the peaks
inline constexpr size_t kPeakSize = 18;        // one packed peak

enum class RecordType : uint32_t { kHeader = 1, kFrame = 2, kFooter = 3 };

// A missing or unreadable file, or bytes that are not an .mscan archive at all.
class ScanFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct FrameRecord {
  uint8_t camera = 0;
  bool lasers_on = false;
  uint32_t sequence = 0;
  int64_t timestamp_ns = 0;                                             // steady clock
  double slide_position_mm = std::numeric_limits<double>::quiet_NaN();  // NaN: no readback
  std::vector<Peak> peaks;
};

// One whole record (type, length, payload, crc32) ready to append.
std::vector<uint8_t> EncodeRecord(RecordType type, std::span<const uint8_t> payload);
std::vector<uint8_t> EncodeFramePayload(const FrameRecord& frame);
std::vector<uint8_t> EncodeFrame(const FrameRecord& frame);  // a whole frame record
// nullopt (and *error set, if given) when the payload is malformed.
std::optional<FrameRecord> DecodeFramePayload(std::span<const uint8_t> payload,
                                              std::string* error = nullptr);

// Where a ScanWriter's bytes go. Each record arrives in one Write call.
class ByteSink {
 public:
  virtual ~ByteSink() = default;
  virtual void Write(std::span<const uint8_t> bytes) = 0;
  // Make everything written so far durable (fsync for files).
  virtual void Sync() {}
};

class VectorSink : public ByteSink {
 public:
  void Write(std::span<const uint8_t> bytes) override;
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

// Writes one archive: Begin, any number of AppendFrame, Finish. Calls out of order throw
// std::logic_error; after a sink error the writer refuses further records, since the
// sink may hold a partial record that only the reader's recovery can deal with.
class ScanWriter {
 public:
  explicit ScanWriter(ByteSink& sink);  // the sink must outlive the writer

  void Begin(const nlohmann::json& header);  // magic + header record; header is an object
  void AppendFrame(const FrameRecord& frame);
  void Finish(const nlohmann::json& footer);  // footer record; footer is an object

  uint64_t bytes_written() const { return bytes_written_; }
  uint64_t frames_written() const { return frames_written_; }
  uint64_t peaks_written() const { return peaks_written_; }
  bool finished() const { return state_ == State::kFinished; }

 private:
  enum class State { kNew, kOpen, kFinished, kBroken };
  void Write(std::span<const uint8_t> bytes);

  ByteSink& sink_;
  State state_ = State::kNew;
  uint64_t bytes_written_ = 0;
  uint64_t frames_written_ = 0;
  uint64_t peaks_written_ = 0;
};

struct ScanFileWriterOptions {
  bool overwrite = false;           // refuse to replace an existing file (it may be a scan)
  bool fsync_on_finish = true;      // file and its directory entry
  uint32_t fsync_every_frames = 0;  // 0: never during the scan
};

// A ScanWriter onto a new file. Errors are ScanFormatError naming the file. Destroying it
// without Finish leaves a valid but incomplete archive (as a crash would).
class ScanFileWriter {
 public:
  explicit ScanFileWriter(const std::filesystem::path& path, ScanFileWriterOptions options = {});
  ~ScanFileWriter();
  ScanFileWriter(const ScanFileWriter&) = delete;
  ScanFileWriter& operator=(const ScanFileWriter&) = delete;

  void Begin(const nlohmann::json& header);
  void AppendFrame(const FrameRecord& frame);
  void Finish(const nlohmann::json& footer);
  uint64_t bytes_written() const { return writer_.bytes_written(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  class FileSink;
  std::filesystem::path path_;
  ScanFileWriterOptions options_;
  std::unique_ptr<FileSink> sink_;
  ScanWriter writer_;
};

// One CRC-checked record; offset is where it starts in the archive.
struct ScanRecord {
  uint32_t type = 0;
  uint64_t offset = 0;
  std::vector<uint8_t> payload;
};

// Incremental framing: feed bytes as they arrive, take complete, CRC-checked records out.
// It checks the magic, lengths and CRCs, not the record order or payloads (ReadScan does).
// After an error it ignores further input, so hostile streams cannot grow its buffer
// beyond one record's declared length (at most kMaxRecordPayload) plus what one Feed adds.
class ScanStreamReader {
 public:
  enum class Status { kOk, kBadMagic, kCorrupt };

  void Feed(std::span<const uint8_t> bytes);
  // The next complete record, or nullopt when more bytes are needed or the stream failed.
  std::optional<ScanRecord> Next();

  Status status() const { return status_; }
  const std::string& error() const { return error_; }  // "" while kOk
  bool magic_seen() const { return magic_seen_; }
  uint64_t bytes_fed() const { return bytes_fed_; }
  // End of the magic or of the last record returned: the valid prefix so far.
  uint64_t bytes_consumed() const { return consumed_; }
  // Why the bytes after bytes_consumed() are not a record yet ("" when there are none),
  // e.g. "frame record cut off after 20 of 58 bytes".
  std::string PendingDescription() const;

 private:
  void Fail(Status status, std::string error);
  std::span<const uint8_t> Pending() const;

  std::vector<uint8_t> buffer_;
  size_t start_ = 0;  // first unconsumed byte in buffer_
  Status status_ = Status::kOk;
  std::string error_;
  bool magic_seen_ = false;
  uint64_t bytes_fed_ = 0;
  uint64_t consumed_ = 0;
};

struct ScanReadReport {
  bool complete = false;  // header, frames and footer, and nothing after the footer
  size_t bytes_total = 0;
  size_t bytes_valid = 0;  // length of the prefix that was read and trusted
  size_t frames = 0;
  size_t peaks = 0;
  // "complete: 600 frames, 81234 peaks" or "recovered 412 frames (55012 peaks) of 1203456
  // bytes; stopped at byte 901234: record CRC mismatch (...)".
  std::string message;
};

struct ScanArchive {
  nlohmann::json header;  // null when no valid header was found
  std::vector<FrameRecord> frames;
  std::optional<nlohmann::json> footer;
  ScanReadReport report;
};

// Throws ScanFormatError only when the bytes do not start with the .mscan magic (or a
// prefix of it); anything after the magic yields the valid prefix and a report.
ScanArchive ReadScan(std::span<const uint8_t> bytes);
// As ReadScan; a missing or unreadable file is a ScanFormatError naming the file.
ScanArchive ReadScanFile(const std::filesystem::path& path);

}  // namespace mirrorscan
