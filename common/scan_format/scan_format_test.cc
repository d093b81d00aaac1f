#include "common/scan_format/scan_format.h"

#include <unistd.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "common/scan_format/scan_format_internal.h"

namespace mirrorscan {
namespace {

using Bytes = std::vector<uint8_t>;

FrameRecord RandomFrame(std::mt19937& rng, uint32_t sequence, size_t max_peaks) {
  std::uniform_real_distribution<float> f(-1e4f, 1e4f);
  std::uniform_int_distribution<int> byte(0, 255);
  FrameRecord frame;
  frame.camera = static_cast<uint8_t>(byte(rng));
  frame.lasers_on = byte(rng) & 1;
  frame.sequence = sequence;
  frame.timestamp_ns = std::uniform_int_distribution<int64_t>()(rng);
  frame.slide_position_mm = std::uniform_real_distribution<double>(-2000, 2000)(rng);
  const size_t n = std::uniform_int_distribution<size_t>(0, max_peaks)(rng);
  for (size_t i = 0; i < n; ++i) {
    frame.peaks.push_back({static_cast<uint16_t>(std::uniform_int_distribution<int>(0, 65535)(rng)),
                           f(rng), f(rng), f(rng), f(rng)});
  }
  return frame;
}

// Bitwise, so NaN slide positions compare equal to themselves.
void ExpectSameFrame(const FrameRecord& a, const FrameRecord& b) {
  EXPECT_EQ(a.camera, b.camera);
  EXPECT_EQ(a.lasers_on, b.lasers_on);
  EXPECT_EQ(a.sequence, b.sequence);
  EXPECT_EQ(a.timestamp_ns, b.timestamp_ns);
  EXPECT_EQ(std::bit_cast<uint64_t>(a.slide_position_mm),
            std::bit_cast<uint64_t>(b.slide_position_mm));
  EXPECT_EQ(a.peaks, b.peaks);
}

const nlohmann::json kHeader = {{"device", "mirrorscan-virtual"},
                                {"board", "virtual"},
                                {"firmware_version", "0.1.0"},
                                {"calibration_hash", "sha256:abc"},
                                {"cameras", {{{"id", 0}, {"width", 1024}, {"height", 768}}}},
                                {"lasers", 3},
                                {"slide_speed_mm_s", 400.0},
                                {"start_time", "2026-11-24T01:00:00Z"}};

nlohmann::json Footer(size_t frames, size_t peaks, const std::string& status = "complete") {
  return {{"frames", frames},    {"peaks", peaks},
          {"dropped_frames", 0}, {"end_time", "2026-11-24T01:00:05Z"},
          {"status", status},    {"reason", ""}};
}

// A small archive plus the byte offset where each record ends (boundaries[0] = header end).
struct Small {
  Bytes bytes;
  std::vector<FrameRecord> frames;
  std::vector<size_t> record_ends;  // header, frames..., footer
};

Small MakeSmall(size_t frames = 4, size_t max_peaks = 3) {
  std::mt19937 rng(7);
  VectorSink sink;
  ScanWriter writer(sink);
  Small s;
  writer.Begin(kHeader);
  s.record_ends.push_back(writer.bytes_written());
  size_t peaks = 0;
  for (size_t i = 0; i < frames; ++i) {
    s.frames.push_back(RandomFrame(rng, static_cast<uint32_t>(i), max_peaks));
    peaks += s.frames.back().peaks.size();
    writer.AppendFrame(s.frames.back());
    s.record_ends.push_back(writer.bytes_written());
  }
  writer.Finish(Footer(frames, peaks));
  s.record_ends.push_back(writer.bytes_written());
  s.bytes = sink.bytes();
  return s;
}

TEST(ScanFormatTest, RoundTripsHeaderFramesAndFooter) {
  std::mt19937 rng(1);
  VectorSink sink;
  ScanWriter writer(sink);
  writer.Begin(kHeader);
  std::vector<FrameRecord> frames;
  size_t peaks = 0;
  for (uint32_t i = 0; i < 300; ++i) {
    frames.push_back(RandomFrame(rng, i, 200));
    peaks += frames.back().peaks.size();
  }
  frames[3].peaks.clear();
  frames[5].slide_position_mm = std::numeric_limits<double>::quiet_NaN();
  peaks = 0;
  for (const FrameRecord& f : frames) {
    writer.AppendFrame(f);
    peaks += f.peaks.size();
  }
  writer.Finish(Footer(frames.size(), peaks));
  EXPECT_EQ(writer.bytes_written(), sink.bytes().size());
  EXPECT_EQ(writer.frames_written(), frames.size());
  EXPECT_EQ(writer.peaks_written(), peaks);

  const ScanArchive archive = ReadScan(sink.bytes());
  EXPECT_TRUE(archive.report.complete) << archive.report.message;
  EXPECT_EQ(archive.header, kHeader);
  ASSERT_TRUE(archive.footer);
  EXPECT_EQ(*archive.footer, Footer(frames.size(), peaks));
  ASSERT_EQ(archive.frames.size(), frames.size());
  for (size_t i = 0; i < frames.size(); ++i) ExpectSameFrame(archive.frames[i], frames[i]);
  EXPECT_TRUE(std::isnan(archive.frames[5].slide_position_mm));
  EXPECT_EQ(archive.report.frames, frames.size());
  EXPECT_EQ(archive.report.peaks, peaks);
  EXPECT_EQ(archive.report.bytes_total, sink.bytes().size());
  EXPECT_EQ(archive.report.bytes_valid, sink.bytes().size());
  EXPECT_EQ(archive.report.message, "complete: 300 frames, " + std::to_string(peaks) + " peaks");
}

TEST(ScanFormatTest, LayoutMatchesTheDocumentedFormat) {
  FrameRecord frame;
  frame.camera = 1;
  frame.lasers_on = true;
  frame.sequence = 0x01020304;
  frame.timestamp_ns = -2;
  frame.slide_position_mm = 1.5;
  frame.peaks = {{0x0102, 1.0f, 2.0f, 3.0f, 4.0f}};
  const Bytes record = EncodeFrame(frame);
  ASSERT_EQ(record.size(), 12 + 28 + 18);
  EXPECT_EQ(internal::LoadU32(record.data()), 2u);
  EXPECT_EQ(internal::LoadU32(record.data() + 4), 46u);
  const uint8_t* p = record.data() + 8;
  EXPECT_EQ(p[0], 1);
  EXPECT_EQ(p[1], 1);
  EXPECT_EQ(internal::LoadU32(p + 4), 0x01020304u);
  EXPECT_EQ(internal::LoadU64(p + 8), ~uint64_t{1});
  EXPECT_EQ(internal::LoadU64(p + 16), std::bit_cast<uint64_t>(1.5));
  EXPECT_EQ(internal::LoadU32(p + 24), 1u);
  EXPECT_EQ(p[28], 0x02);
  EXPECT_EQ(p[29], 0x01);
  EXPECT_EQ(internal::LoadU32(p + 30), std::bit_cast<uint32_t>(1.0f));
  EXPECT_EQ(internal::LoadU32(p + 42), std::bit_cast<uint32_t>(4.0f));
  VectorSink sink;
  ScanWriter writer(sink);
  writer.Begin(kHeader);
  EXPECT_TRUE(std::equal(kScanMagic.begin(), kScanMagic.end(), sink.bytes().begin()));
  EXPECT_EQ(std::string(sink.bytes().begin(), sink.bytes().begin() + 8),
            std::string("MSCAN\0\x01\n", 8));
}

TEST(ScanFormatTest, TruncationAtEveryByteRecoversTheWrittenPrefix) {
  const Small s = MakeSmall();
  const size_t size = s.bytes.size();
  for (size_t cut = 0; cut <= size; ++cut) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    ScanArchive archive;
    ASSERT_NO_THROW(archive = ReadScan(std::span(s.bytes).first(cut)));
    size_t valid = cut < 8 ? 0 : 8;
    for (size_t end : s.record_ends) {
      if (end <= cut) valid = end;
    }
    size_t frames = 0;
    if (cut >= s.record_ends[0]) {
      for (size_t i = 1; i + 1 < s.record_ends.size(); ++i) frames += s.record_ends[i] <= cut;
    }
    EXPECT_EQ(archive.report.complete, cut == size);
    EXPECT_EQ(archive.report.bytes_total, cut);
    EXPECT_EQ(archive.report.bytes_valid, valid);
    ASSERT_EQ(archive.frames.size(), frames);
    EXPECT_EQ(archive.report.frames, frames);
    for (size_t i = 0; i < frames; ++i) ExpectSameFrame(archive.frames[i], s.frames[i]);
    EXPECT_EQ(archive.footer.has_value(), cut == size);
    if (cut < size) {
      EXPECT_NE(
          archive.report.message.find("of " + std::to_string(cut) + " bytes; stopped at byte " +
                                      std::to_string(valid) + ": "),
          std::string::npos)
          << archive.report.message;
    }
  }
}

TEST(ScanFormatTest, EverySingleBitFlipStopsAtTheDamagedRecord) {
  const Small s = MakeSmall();
  for (size_t bit = 0; bit < s.bytes.size() * 8; ++bit) {
    const size_t byte = bit / 8;
    SCOPED_TRACE("bit " + std::to_string(bit) + " (byte " + std::to_string(byte) + ")");
    Bytes damaged = s.bytes;
    damaged[byte] ^= static_cast<uint8_t>(1u << (bit % 8));
    if (byte < 8) {
      EXPECT_THROW(ReadScan(damaged), ScanFormatError);
      continue;
    }
    size_t record = 0;  // 0 = header, 1..n = frames, n+1 = footer
    while (s.record_ends[record] <= byte) ++record;
    const size_t record_start = record == 0 ? 8 : s.record_ends[record - 1];
    const size_t frames = record == 0 ? 0 : record - 1;
    ScanArchive archive;
    ASSERT_NO_THROW(archive = ReadScan(damaged));
    EXPECT_FALSE(archive.report.complete);
    EXPECT_EQ(archive.report.bytes_valid, record_start) << archive.report.message;
    ASSERT_EQ(archive.frames.size(), frames) << archive.report.message;
    for (size_t i = 0; i < frames; ++i) ExpectSameFrame(archive.frames[i], s.frames[i]);
    EXPECT_FALSE(archive.footer.has_value());
  }
}

Bytes MagicThen(std::initializer_list<Bytes> records) {
  Bytes out(kScanMagic.begin(), kScanMagic.end());
  for (const Bytes& r : records) out.insert(out.end(), r.begin(), r.end());
  return out;
}

Bytes HeaderRecord() {
  const std::string text = kHeader.dump();
  return EncodeRecord(RecordType::kHeader, Bytes(text.begin(), text.end()));
}

Bytes RawRecord(uint32_t type, uint32_t length, size_t payload_bytes) {
  Bytes r(8 + payload_bytes, 0xAB);
  internal::StoreU32(r.data(), type);
  internal::StoreU32(r.data() + 4, length);
  return r;
}

TEST(ScanFormatTest, HostileLengthsAreCorruptionNotAllocations) {
  for (uint32_t type : {1u, 2u, 3u, 77u}) {
    for (uint32_t length : {0xFFFFFFFFu, kMaxRecordPayload + 1}) {
      const ScanArchive a = ReadScan(MagicThen({HeaderRecord(), RawRecord(type, length, 16)}));
      EXPECT_FALSE(a.report.complete);
      EXPECT_EQ(a.report.bytes_valid, 8 + HeaderRecord().size());
      EXPECT_NE(a.report.message.find("over the 64 MiB limit"), std::string::npos)
          << a.report.message;
    }
  }
  // A plausible length with few bytes behind it is a cut-off record; nothing is allocated
  // for the declared size (the stream reader keeps only what it was fed).
  ScanStreamReader reader;
  const Bytes bytes = MagicThen({HeaderRecord(), RawRecord(2, kMaxRecordPayload, 100)});
  reader.Feed(bytes);
  EXPECT_TRUE(reader.Next());
  EXPECT_FALSE(reader.Next());
  EXPECT_EQ(reader.status(), ScanStreamReader::Status::kOk);
  EXPECT_NE(reader.PendingDescription().find("cut off after 108 of 67108876 bytes"),
            std::string::npos)
      << reader.PendingDescription();

  // peak_count 0xFFFFFFFF inside a CRC-valid frame record.
  Bytes payload(kFrameFixedSize, 0);
  internal::StoreU32(payload.data() + 24, 0xFFFFFFFFu);
  const ScanArchive a =
      ReadScan(MagicThen({HeaderRecord(), EncodeRecord(RecordType::kFrame, payload)}));
  EXPECT_EQ(a.frames.size(), 0u);
  EXPECT_NE(a.report.message.find("bad frame record: frame peak_count 4294967295"),
            std::string::npos)
      << a.report.message;
  // One peak's worth of bytes too few and too many.
  FrameRecord frame;
  frame.peaks.resize(2);
  Bytes good = EncodeFramePayload(frame);
  EXPECT_TRUE(DecodeFramePayload(good));
  EXPECT_FALSE(DecodeFramePayload(std::span(good).first(good.size() - 1)));
  good.push_back(0);
  EXPECT_FALSE(DecodeFramePayload(good));
  EXPECT_FALSE(DecodeFramePayload(Bytes(27, 0)));
}

TEST(ScanFormatTest, StreamReaderFedOneByteAtATimeEqualsReadScan) {
  const Small s = MakeSmall(6, 5);
  Bytes flipped = s.bytes;
  flipped[s.record_ends[3] + 20] ^= 0x10;
  const Bytes cut(s.bytes.begin(), s.bytes.begin() + static_cast<long>(s.record_ends[4] + 5));
  for (const Bytes* input : std::vector<const Bytes*>{&s.bytes, &flipped, &cut}) {
    const ScanArchive whole = ReadScan(*input);
    ScanStreamReader reader;
    std::vector<ScanRecord> records;
    for (uint8_t b : *input) {
      reader.Feed(std::span(&b, 1));
      while (std::optional<ScanRecord> r = reader.Next()) records.push_back(std::move(*r));
    }
    EXPECT_EQ(reader.bytes_fed(), input->size());
    EXPECT_EQ(reader.bytes_consumed(), whole.report.bytes_valid);
    ASSERT_EQ(records.size(), whole.frames.size() + 1 + (whole.footer ? 1 : 0));
    EXPECT_EQ(records[0].type, 1u);
    EXPECT_EQ(nlohmann::json::parse(records[0].payload), whole.header);
    for (size_t i = 0; i < whole.frames.size(); ++i) {
      EXPECT_EQ(records[i + 1].type, 2u);
      EXPECT_EQ(records[i + 1].offset, s.record_ends[i]);
      ExpectSameFrame(*DecodeFramePayload(records[i + 1].payload), whole.frames[i]);
    }
    if (whole.footer) {
      EXPECT_EQ(nlohmann::json::parse(records.back().payload), *whole.footer);
    }
  }
}

TEST(ScanFormatTest, BadMagicAndVersionThrow) {
  Bytes bytes = MakeSmall().bytes;
  bytes[0] = 'X';
  EXPECT_THROW(ReadScan(bytes), ScanFormatError);
  bytes = MakeSmall().bytes;
  bytes[6] = 2;
  try {
    ReadScan(bytes);
    FAIL();
  } catch (const ScanFormatError& e) {
    EXPECT_STREQ(e.what(), "unsupported .mscan format version 2 (this reader reads version 1)");
  }
  // A wrong first byte fails at once, without waiting for the rest of the magic.
  EXPECT_THROW(ReadScan(Bytes{'{'}), ScanFormatError);
  // A prefix of the magic is a cut-off archive, not a foreign file.
  const ScanArchive a = ReadScan(Bytes{'M', 'S', 'C'});
  EXPECT_FALSE(a.report.complete);
  EXPECT_EQ(a.report.message,
            "recovered 0 frames (0 peaks) of 3 bytes; stopped at byte 0: the archive ends inside "
            "the 8-byte magic (3 of 8 bytes) (the archive was cut off, or the record length is "
            "damaged)");
  EXPECT_EQ(ReadScan(Bytes{}).report.message,
            "recovered 0 frames (0 peaks) of 0 bytes; stopped at byte 0: the archive is empty");
}

TEST(ScanFormatTest, FramesWithoutAHeaderAreNotTrusted) {
  FrameRecord frame;
  frame.peaks.resize(3);
  const ScanArchive a = ReadScan(MagicThen({EncodeFrame(frame), EncodeFrame(frame)}));
  EXPECT_EQ(a.frames.size(), 0u);
  EXPECT_EQ(a.report.frames, 0u);
  EXPECT_EQ(a.report.bytes_valid, 8u);
  EXPECT_NE(a.report.message.find("the first record is a frame record, not the header"),
            std::string::npos)
      << a.report.message;

  const std::string not_object = "[1,2]";
  const ScanArchive b = ReadScan(
      MagicThen({EncodeRecord(RecordType::kHeader, Bytes(not_object.begin(), not_object.end())),
                 EncodeFrame(frame)}));
  EXPECT_EQ(b.frames.size(), 0u);
  EXPECT_NE(b.report.message.find("header record is not a JSON object"), std::string::npos);

  // Deep nesting must neither crash the parser nor the destructor.
  const std::string deep(1 << 20, '[');
  const ScanArchive c =
      ReadScan(MagicThen({EncodeRecord(RecordType::kHeader, Bytes(deep.begin(), deep.end()))}));
  EXPECT_TRUE(c.header.is_null());
  const std::string deep_ok = "{\"a\":" + std::string(100000, '[') + std::string(100000, ']') + "}";
  const ScanArchive d = ReadScan(
      MagicThen({EncodeRecord(RecordType::kHeader, Bytes(deep_ok.begin(), deep_ok.end()))}));
  EXPECT_TRUE(d.header.is_object());
}

TEST(ScanFormatTest, ReportsFooterStatusTrailingDataAndUnknownRecords) {
  VectorSink sink;
  ScanWriter writer(sink);
  writer.Begin(kHeader);
  writer.AppendFrame(FrameRecord{});
  nlohmann::json footer = Footer(1, 0, "aborted");
  footer["reason"] = "button pressed";
  writer.Finish(footer);
  EXPECT_EQ(ReadScan(sink.bytes()).report.message,
            "complete: 1 frames, 0 peaks; footer status \"aborted\": button pressed");

  // Untrusted footer strings are shortened at a UTF-8 code point boundary.
  VectorSink long_sink;
  ScanWriter long_writer(long_sink);
  long_writer.Begin(kHeader);
  footer["reason"] = std::string(5, 'x') + [] {
    std::string s;
    for (int i = 0; i < 1000; ++i) s += "\u00e9";
    return s;
  }();
  long_writer.Finish(footer);
  const std::string long_message = ReadScan(long_sink.bytes()).report.message;
  EXPECT_LT(long_message.size(), 300u);
  EXPECT_EQ(long_message.substr(long_message.size() - 3), "...");
  EXPECT_NO_THROW(nlohmann::json(long_message).dump());

  Bytes trailing = sink.bytes();
  const Bytes extra = EncodeFrame(FrameRecord{});
  trailing.insert(trailing.end(), extra.begin(), extra.end());
  const ScanArchive t = ReadScan(trailing);
  EXPECT_FALSE(t.report.complete);
  EXPECT_TRUE(t.footer);
  EXPECT_EQ(t.report.bytes_valid, sink.bytes().size());
  EXPECT_NE(t.report.message.find("frame record after the footer"), std::string::npos);

  const Bytes unknown = EncodeRecord(static_cast<RecordType>(9), Bytes{1, 2, 3});
  const ScanArchive u = ReadScan(MagicThen({HeaderRecord(), unknown, EncodeFrame(FrameRecord{}),
                                            EncodeRecord(RecordType::kFooter, Bytes{'{', '}'})}));
  EXPECT_TRUE(u.report.complete);
  EXPECT_EQ(u.frames.size(), 1u);
  EXPECT_EQ(u.report.message, "complete: 1 frames, 0 peaks; skipped 1 records of unknown type");
}

TEST(ScanFormatTest, WriterRejectsMisuseWithoutWriting) {
  VectorSink sink;
  ScanWriter writer(sink);
  EXPECT_THROW(writer.AppendFrame(FrameRecord{}), std::logic_error);
  EXPECT_THROW(writer.Finish(nlohmann::json::object()), std::logic_error);
  EXPECT_THROW(writer.Begin(nlohmann::json::array()), std::invalid_argument);
  EXPECT_TRUE(sink.bytes().empty());
  writer.Begin(kHeader);
  EXPECT_THROW(writer.Begin(kHeader), std::logic_error);
  writer.Finish(nlohmann::json::object());
  EXPECT_THROW(writer.AppendFrame(FrameRecord{}), std::logic_error);
  EXPECT_TRUE(writer.finished());
}

struct ThrowingSink : ByteSink {
  int calls = 0;
  void Write(std::span<const uint8_t>) override {
    if (++calls == 2) throw std::runtime_error("disk full");
  }
};

TEST(ScanFormatTest, WriterRefusesToAppendAfterASinkError) {
  ThrowingSink sink;
  ScanWriter writer(sink);
  writer.Begin(kHeader);
  EXPECT_THROW(writer.AppendFrame(FrameRecord{}), std::runtime_error);
  EXPECT_THROW(writer.AppendFrame(FrameRecord{}), std::logic_error);
  EXPECT_EQ(sink.calls, 2);
}

class ScanFormatFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        std::filesystem::temp_directory_path() / ("scan_format_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(ScanFormatFileTest, WritesAndReadsFiles) {
  const auto path = dir_ / "a.mscan";
  std::mt19937 rng(3);
  {
    ScanFileWriter writer(path, {.fsync_every_frames = 2});
    writer.Begin(kHeader);
    for (uint32_t i = 0; i < 5; ++i) writer.AppendFrame(RandomFrame(rng, i, 10));
    writer.Finish(Footer(5, 0));
    EXPECT_EQ(writer.bytes_written(), std::filesystem::file_size(path));
  }
  const ScanArchive a = ReadScanFile(path);
  EXPECT_TRUE(a.report.complete) << a.report.message;
  EXPECT_EQ(a.frames.size(), 5u);
  // Never replaces an existing file unless told to.
  EXPECT_THROW(ScanFileWriter{path}, ScanFormatError);
  ScanFileWriter again(path, {.overwrite = true});
  again.Begin(kHeader);
  EXPECT_EQ(ReadScanFile(path).report.frames, 0u);
}

TEST_F(ScanFormatFileTest, AbandonedWriterLeavesAReadablePrefix) {
  const auto path = dir_ / "crash.mscan";
  {
    ScanFileWriter writer(path);
    writer.Begin(kHeader);
    writer.AppendFrame(FrameRecord{});
  }
  const ScanArchive a = ReadScanFile(path);
  EXPECT_FALSE(a.report.complete);
  EXPECT_EQ(a.frames.size(), 1u);
  EXPECT_NE(a.report.message.find("no footer record"), std::string::npos);
}

TEST_F(ScanFormatFileTest, ErrorsNameTheFile) {
  const auto missing = dir_ / "missing.mscan";
  try {
    ReadScanFile(missing);
    FAIL();
  } catch (const ScanFormatError& e) {
    EXPECT_NE(std::string(e.what()).find(missing.string() + ": cannot open"), std::string::npos)
        << e.what();
  }
  const auto text = dir_ / "notes.txt";
  std::ofstream(text) << "hello";
  try {
    ReadScanFile(text);
    FAIL();
  } catch (const ScanFormatError& e) {
    EXPECT_EQ(std::string(e.what()), text.string() + ": not an .mscan archive (bad magic)");
  }
  EXPECT_THROW(ReadScanFile(dir_), ScanFormatError);
}

TEST(ScanFormatTest, FuzzSeedIsACompleteArchive) {
  const ScanArchive a =
      ReadScanFile(std::filesystem::path(MIRRORSCAN_SOURCE_DIR) / "tests/fuzz/corpus/seed.mscan");
  EXPECT_TRUE(a.report.complete) << a.report.message;
  EXPECT_GT(a.frames.size(), 0u);
}

}  // namespace
}  // namespace mirrorscan
