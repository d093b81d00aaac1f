#include <algorithm>
#include <string>
#include <utility>

#include "common/scan_format/scan_format.h"
#include "common/scan_format/scan_format_internal.h"

namespace mirrorscan {

using internal::LoadU32;

namespace {

std::string TypeName(uint32_t type) {
  switch (type) {
    case static_cast<uint32_t>(RecordType::kHeader):
      return "header record";
    case static_cast<uint32_t>(RecordType::kFrame):
      return "frame record";
    case static_cast<uint32_t>(RecordType::kFooter):
      return "footer record";
    default:
      return "record of type " + std::to_string(type);
  }
}

}  // namespace

void ScanStreamReader::Fail(Status status, std::string error) {
  status_ = status;
  error_ = std::move(error);
  // Nothing after the failure is ever used, so drop it rather than keep growing.
  buffer_.clear();
  buffer_.shrink_to_fit();
  start_ = 0;
}

std::span<const uint8_t> ScanStreamReader::Pending() const {
  return std::span<const uint8_t>(buffer_).subspan(start_);
}

void ScanStreamReader::Feed(std::span<const uint8_t> bytes) {
  bytes_fed_ += bytes.size();
  if (status_ != Status::kOk) return;
  // Drop consumed bytes once they are at least half the buffer: amortised O(1) per byte.
  if (start_ > 0 && start_ >= buffer_.size() / 2) {
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
}

std::optional<ScanRecord> ScanStreamReader::Next() {
  if (status_ != Status::kOk) return std::nullopt;
  if (!magic_seen_) {
    const std::span<const uint8_t> pending = Pending();
    const size_t n = std::min(pending.size(), kScanMagic.size());
    // Judge the magic on the bytes we have, so a wrong file fails at once.
    for (size_t i = 0; i < n; ++i) {
      if (pending[i] == kScanMagic[i]) continue;
      if (i == 6) {
        Fail(Status::kBadMagic, "unsupported .mscan format version " + std::to_string(pending[i]) +
                                    " (this reader reads version " +
                                    std::to_string(kScanFormatVersion) + ")");
      } else {
        Fail(Status::kBadMagic, "not an .mscan archive (bad magic)");
      }
      return std::nullopt;
    }
    if (n < kScanMagic.size()) return std::nullopt;
    magic_seen_ = true;
    start_ += kScanMagic.size();
    consumed_ = kScanMagic.size();
  }
  const std::span<const uint8_t> pending = Pending();
  if (pending.size() < 8) return std::nullopt;
  const uint32_t type = LoadU32(pending.data());
  const uint32_t length = LoadU32(pending.data() + 4);
  if (length > kMaxRecordPayload) {
    Fail(Status::kCorrupt, TypeName(type) + " declares a payload of " + std::to_string(length) +
                               " bytes, over the 64 MiB limit (the archive is damaged)");
    return std::nullopt;
  }
  const size_t total = kRecordOverhead + length;
  if (pending.size() < total) return std::nullopt;
  const std::span<const uint8_t> payload = pending.subspan(8, length);
  const uint32_t stored_crc = LoadU32(pending.data() + 8 + length);
  if (stored_crc != internal::RecordCrc(type, length, payload)) {
    Fail(Status::kCorrupt,
         TypeName(type) + " CRC mismatch (the archive is damaged or was cut off)");
    return std::nullopt;
  }
  ScanRecord record;
  record.type = type;
  record.offset = consumed_;
  record.payload.assign(payload.begin(), payload.end());
  start_ += total;
  consumed_ += total;
  return record;
}

std::string ScanStreamReader::PendingDescription() const {
  if (status_ != Status::kOk) return "";
  const std::span<const uint8_t> pending = Pending();
  if (pending.empty()) return "";
  if (!magic_seen_) {
    return "the archive ends inside the 8-byte magic (" + std::to_string(pending.size()) +
           " of 8 bytes)";
  }
  if (pending.size() < 8) {
    return "record header cut off after " + std::to_string(pending.size()) + " of 8 bytes";
  }
  const uint32_t type = LoadU32(pending.data());
  const uint64_t total = kRecordOverhead + uint64_t{LoadU32(pending.data() + 4)};
  return TypeName(type) + " cut off after " + std::to_string(pending.size()) + " of " +
         std::to_string(total) + " bytes";
}

namespace {

// Footer strings are untrusted and may be megabytes long; the message stays one line's worth
// and valid UTF-8 (the parser already rejected invalid UTF-8, so cut at a code point).
std::string Abbreviate(std::string text) {
  constexpr size_t kMax = 200;
  if (text.size() <= kMax) return text;
  size_t cut = kMax;
  while (cut > 0 && (static_cast<uint8_t>(text[cut]) & 0xC0) == 0x80) --cut;
  text.resize(cut);
  return text + "...";
}

std::optional<nlohmann::json> ParseObject(const std::vector<uint8_t>& payload) {
  // No exceptions, so malformed JSON is just "not an object". nlohmann 3.11 parses and
  // destroys iteratively, so deep nesting cannot overflow the stack.
  nlohmann::json value = nlohmann::json::parse(payload.begin(), payload.end(), nullptr,
                                               /*allow_exceptions=*/false);
  if (!value.is_object()) return std::nullopt;
  return value;
}

}  // namespace

ScanArchive ReadScan(std::span<const uint8_t> bytes) {
  ScanStreamReader reader;
  reader.Feed(bytes);

  ScanArchive archive;
  ScanReadReport& report = archive.report;
  bool have_header = false;
  size_t unknown_records = 0;
  std::string stop_reason;  // set when a record is valid framing but breaks the rules
  uint64_t stop_at = 0;
  auto stop = [&](const ScanRecord& record, std::string why) {
    stop_at = record.offset;
    stop_reason = std::move(why);
  };

  while (std::optional<ScanRecord> record = reader.Next()) {
    if (archive.footer) {
      stop(*record, TypeName(record->type) + " after the footer");
      break;
    }
    if (!have_header && record->type != static_cast<uint32_t>(RecordType::kHeader)) {
      stop(*record, "the first record is a " + TypeName(record->type) +
                        ", not the header; no frames are trusted without one");
      break;
    }
    switch (record->type) {
      case static_cast<uint32_t>(RecordType::kHeader): {
        if (have_header) {
          stop(*record, "a second header record");
          break;
        }
        std::optional<nlohmann::json> header = ParseObject(record->payload);
        if (!header) {
          stop(*record, "the header record is not a JSON object; no frames are trusted");
          break;
        }
        archive.header = std::move(*header);
        have_header = true;
        break;
      }
      case static_cast<uint32_t>(RecordType::kFrame): {
        std::string error;
        std::optional<FrameRecord> frame = DecodeFramePayload(record->payload, &error);
        if (!frame) {
          stop(*record, "bad frame record: " + error);
          break;
        }
        report.peaks += frame->peaks.size();
        archive.frames.push_back(std::move(*frame));
        break;
      }
      case static_cast<uint32_t>(RecordType::kFooter): {
        std::optional<nlohmann::json> footer = ParseObject(record->payload);
        if (!footer) {
          stop(*record, "the footer record is not a JSON object");
          break;
        }
        archive.footer = std::move(*footer);
        break;
      }
      default:
        // CRC-valid but unknown: a newer writer's addition, safe to skip.
        ++unknown_records;
        break;
    }
    if (!stop_reason.empty()) break;
  }

  if (reader.status() == ScanStreamReader::Status::kBadMagic) {
    throw ScanFormatError(reader.error());
  }

  report.bytes_total = bytes.size();
  report.frames = archive.frames.size();
  std::string why;
  if (!stop_reason.empty()) {
    report.bytes_valid = stop_at;
    why = stop_reason;
  } else {
    report.bytes_valid = reader.bytes_consumed();
    if (reader.status() != ScanStreamReader::Status::kOk) {
      why = reader.error();
    } else if (std::string pending = reader.PendingDescription(); !pending.empty()) {
      why = pending + " (the archive was cut off, or the record length is damaged)";
    } else if (!reader.magic_seen()) {
      why = "the archive is empty";
    } else if (!have_header) {
      why = "no header record (the archive was cut off)";
    } else if (!archive.footer) {
      why = "no footer record (the scan was cut off or is still being written)";
    }
  }
  // A header is what makes frames meaningful (cameras, lasers, calibration).
  if (!have_header) {
    archive.frames.clear();
    report.frames = 0;
    report.peaks = 0;
  }

  const std::string counts =
      std::to_string(report.frames) + " frames, " + std::to_string(report.peaks) + " peaks";
  if (why.empty()) {
    report.complete = true;
    report.message = "complete: " + counts;
    const nlohmann::json& footer = *archive.footer;
    if (auto status = footer.find("status");
        status != footer.end() && status->is_string() && *status != "complete") {
      report.message += "; footer status \"" + Abbreviate(status->get<std::string>()) + "\"";
      if (auto reason = footer.find("reason"); reason != footer.end() && reason->is_string()) {
        report.message += ": " + Abbreviate(reason->get<std::string>());
      }
    }
  } else {
    report.message = "recovered " + std::to_string(report.frames) + " frames (" +
                     std::to_string(report.peaks) + " peaks) of " +
                     std::to_string(report.bytes_total) + " bytes; stopped at byte " +
                     std::to_string(report.bytes_valid) + ": " + why;
  }
  if (unknown_records > 0) {
    report.message += "; skipped " + std::to_string(unknown_records) + " records of unknown type";
  }
  return archive;
}

}  // namespace mirrorscan
