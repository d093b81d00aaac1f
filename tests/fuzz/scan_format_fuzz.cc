// libFuzzer target for the .mscan reader: ReadScan and the stream reader must never
// crash, hang or over-allocate, and must agree with each other on every input.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <span>
#include <vector>

#include "common/scan_format/scan_format.h"
#include "common/scan_format/scan_format_internal.h"

namespace {

void Check(bool ok) {
  if (!ok) std::abort();  // a disagreement is a bug the fuzzer should report
}

// Mutations almost never keep a CRC valid, so on raw input the fuzzer would only ever
// reach the CRC check. Rewriting each record's CRC lets it explore the payload decoders.
std::vector<uint8_t> WithValidCrcs(std::span<const uint8_t> bytes) {
  using mirrorscan::internal::LoadU32;
  std::vector<uint8_t> out(bytes.begin(), bytes.end());
  size_t pos = mirrorscan::kScanMagic.size();
  while (pos + 8 <= out.size()) {
    const uint32_t type = LoadU32(out.data() + pos);
    const uint32_t length = LoadU32(out.data() + pos + 4);
    if (length > mirrorscan::kMaxRecordPayload || out.size() - pos - 8 < uint64_t{length} + 4) {
      break;
    }
    const std::span<const uint8_t> payload(out.data() + pos + 8, length);
    mirrorscan::internal::StoreU32(out.data() + pos + 8 + length,
                                   mirrorscan::internal::RecordCrc(type, length, payload));
    pos += mirrorscan::kRecordOverhead + length;
  }
  return out;
}

void CheckInput(std::span<const uint8_t> bytes);

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> bytes(data, size);
  CheckInput(bytes);
  CheckInput(WithValidCrcs(bytes));
  return 0;
}

namespace {

void CheckInput(std::span<const uint8_t> bytes) {
  using mirrorscan::ScanStreamReader;
  const uint8_t* data = bytes.data();
  const size_t size = bytes.size();
  bool threw = false;
  mirrorscan::ScanArchive archive;
  try {
    archive = mirrorscan::ReadScan(bytes);
  } catch (const mirrorscan::ScanFormatError&) {
    threw = true;
  }

  // Feed in chunks whose sizes come from the input itself, so splits vary with it.
  ScanStreamReader reader;
  size_t records = 0;
  size_t frames = 0;
  size_t pos = 0;
  size_t step = size > 0 ? data[0] % 17 + 1 : 1;
  while (pos < size) {
    const size_t n = std::min(step, size - pos);
    reader.Feed(bytes.subspan(pos, n));
    pos += n;
    step = step * 7 % 23 + 1;
    while (std::optional<mirrorscan::ScanRecord> record = reader.Next()) {
      ++records;
      if (record->type == static_cast<uint32_t>(mirrorscan::RecordType::kFrame) &&
          mirrorscan::DecodeFramePayload(record->payload)) {
        ++frames;
      }
    }
  }
  Check(reader.bytes_fed() == size);
  Check(threw == (reader.status() == ScanStreamReader::Status::kBadMagic));
  if (threw) return;
  const mirrorscan::ScanReadReport& report = archive.report;
  Check(report.bytes_total == size);
  Check(report.bytes_valid <= reader.bytes_consumed());
  Check(report.frames == archive.frames.size());
  Check(frames >= archive.frames.size());
  Check(!report.complete || (archive.footer && report.bytes_valid == size));
  Check(!report.message.empty());
  Check(records >= archive.frames.size());
}

}  // namespace
