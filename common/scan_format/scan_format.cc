#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include <zlib.h>

#include "common/scan_format/scan_format.h"
#include "common/scan_format/scan_format_internal.h"

namespace mirrorscan {
namespace internal {

uint32_t RecordCrc(uint32_t type, uint32_t length, std::span<const uint8_t> payload) {
  uint8_t head[8];
  StoreU32(head, type);
  StoreU32(head + 4, length);
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, head, sizeof(head));
  // Payloads are at most kMaxRecordPayload, so the length fits zlib's uInt.
  if (!payload.empty()) crc = crc32(crc, payload.data(), static_cast<uInt>(payload.size()));
  return static_cast<uint32_t>(crc);
}

}  // namespace internal

using internal::LoadU16;
using internal::LoadU32;
using internal::LoadU64;
using internal::StoreU16;
using internal::StoreU32;
using internal::StoreU64;

std::vector<uint8_t> EncodeRecord(RecordType type, std::span<const uint8_t> payload) {
  if (payload.size() > kMaxRecordPayload) {
    throw std::invalid_argument("mscan record payload of " + std::to_string(payload.size()) +
                                " bytes exceeds the 64 MiB limit");
  }
  const auto type_value = static_cast<uint32_t>(type);
  const auto length = static_cast<uint32_t>(payload.size());
  std::vector<uint8_t> record(kRecordOverhead + payload.size());
  StoreU32(record.data(), type_value);
  StoreU32(record.data() + 4, length);
  std::copy(payload.begin(), payload.end(), record.begin() + 8);
  StoreU32(record.data() + 8 + payload.size(), internal::RecordCrc(type_value, length, payload));
  return record;
}

std::vector<uint8_t> EncodeFramePayload(const FrameRecord& frame) {
  if (frame.peaks.size() > (kMaxRecordPayload - kFrameFixedSize) / kPeakSize) {
    throw std::invalid_argument("mscan frame with " + std::to_string(frame.peaks.size()) +
                                " peaks exceeds the 64 MiB record limit");
  }
  std::vector<uint8_t> out(kFrameFixedSize + frame.peaks.size() * kPeakSize);
  uint8_t* p = out.data();
  p[0] = frame.camera;
  p[1] = frame.lasers_on ? 1 : 0;
  StoreU16(p + 2, 0);  // reserved
  StoreU32(p + 4, frame.sequence);
  StoreU64(p + 8, std::bit_cast<uint64_t>(frame.timestamp_ns));
  StoreU64(p + 16, std::bit_cast<uint64_t>(frame.slide_position_mm));
  StoreU32(p + 24, static_cast<uint32_t>(frame.peaks.size()));
  p += kFrameFixedSize;
  for (const Peak& peak : frame.peaks) {
    StoreU16(p, peak.u);
    StoreU32(p + 2, std::bit_cast<uint32_t>(peak.v));
    StoreU32(p + 6, std::bit_cast<uint32_t>(peak.intensity));
    StoreU32(p + 10, std::bit_cast<uint32_t>(peak.width));
    StoreU32(p + 14, std::bit_cast<uint32_t>(peak.score));
    p += kPeakSize;
  }
  return out;
}

std::vector<uint8_t> EncodeFrame(const FrameRecord& frame) {
  return EncodeRecord(RecordType::kFrame, EncodeFramePayload(frame));
}

std::optional<FrameRecord> DecodeFramePayload(std::span<const uint8_t> payload,
                                              std::string* error) {
  auto fail = [&](std::string why) -> std::optional<FrameRecord> {
    if (error) *error = std::move(why);
    return std::nullopt;
  };
  if (payload.size() < kFrameFixedSize) {
    return fail("frame payload of " + std::to_string(payload.size()) + " bytes is shorter than " +
                std::to_string(kFrameFixedSize));
  }
  const uint8_t* p = payload.data();
  const uint32_t peak_count = LoadU32(p + 24);
  // 64-bit arithmetic: a hostile count must not wrap around to a matching size.
  const uint64_t expected = kFrameFixedSize + uint64_t{peak_count} * kPeakSize;
  if (expected != payload.size()) {
    return fail("frame peak_count " + std::to_string(peak_count) + " needs " +
                std::to_string(expected) + " payload bytes, the record has " +
                std::to_string(payload.size()));
  }
  FrameRecord frame;
  frame.camera = p[0];
  frame.lasers_on = (p[1] & 1) != 0;
  frame.sequence = LoadU32(p + 4);
  frame.timestamp_ns = std::bit_cast<int64_t>(LoadU64(p + 8));
  frame.slide_position_mm = std::bit_cast<double>(LoadU64(p + 16));
  frame.peaks.resize(peak_count);
  p += kFrameFixedSize;
  for (Peak& peak : frame.peaks) {
    peak.u = LoadU16(p);
    peak.v = std::bit_cast<float>(LoadU32(p + 2));
    peak.intensity = std::bit_cast<float>(LoadU32(p + 6));
    peak.width = std::bit_cast<float>(LoadU32(p + 10));
    peak.score = std::bit_cast<float>(LoadU32(p + 14));
    p += kPeakSize;
  }
  return frame;
}

void VectorSink::Write(std::span<const uint8_t> bytes) {
  bytes_.insert(bytes_.end(), bytes.begin(), bytes.end());
}

ScanWriter::ScanWriter(ByteSink& sink) : sink_(sink) {}

void ScanWriter::Write(std::span<const uint8_t> bytes) {
  // Marked broken until the sink returns: if it throws, a partial record may be out there
  // and appending after it would hide every later record from the reader.
  const State previous = state_;
  state_ = State::kBroken;
  sink_.Write(bytes);
  state_ = previous;
  bytes_written_ += bytes.size();
}

namespace {

std::vector<uint8_t> JsonPayload(const nlohmann::json& value, const char* what) {
  if (!value.is_object()) {
    throw std::invalid_argument(std::string("mscan ") + what + " must be a JSON object");
  }
  const std::string text = value.dump();
  return std::vector<uint8_t>(text.begin(), text.end());
}

void RequireState(bool ok, const char* message) {
  if (!ok) throw std::logic_error(message);
}

}  // namespace

void ScanWriter::Begin(const nlohmann::json& header) {
  RequireState(state_ == State::kNew, "ScanWriter::Begin called twice or after a sink error");
  // Encode before writing anything, so a bad header leaves the sink untouched.
  std::vector<uint8_t> bytes(kScanMagic.begin(), kScanMagic.end());
  const std::vector<uint8_t> record =
      EncodeRecord(RecordType::kHeader, JsonPayload(header, "header"));
  bytes.insert(bytes.end(), record.begin(), record.end());
  Write(bytes);
  state_ = State::kOpen;
}

void ScanWriter::AppendFrame(const FrameRecord& frame) {
  RequireState(state_ == State::kOpen,
               "ScanWriter::AppendFrame needs Begin first, and no Finish or sink error");
  Write(EncodeFrame(frame));
  ++frames_written_;
  peaks_written_ += frame.peaks.size();
}

void ScanWriter::Finish(const nlohmann::json& footer) {
  RequireState(state_ == State::kOpen,
               "ScanWriter::Finish needs Begin first, and no Finish or sink error");
  Write(EncodeRecord(RecordType::kFooter, JsonPayload(footer, "footer")));
  state_ = State::kFinished;
}

}  // namespace mirrorscan
