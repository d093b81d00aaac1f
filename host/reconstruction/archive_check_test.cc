#include "host/reconstruction/archive_check.h"

#include <algorithm>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "host/reconstruction/reconstruct.h"
#include "host/reconstruction/test_sweep.h"

namespace mirrorscan::reconstruction::testing_sweeps {
namespace {

TEST(ArchiveCheck, CalibrationOfAnotherCabinetIsRefused) {
  const Sweep& sweep = CuboidSweep();
  Calibration other = sweep.calibration;
  other.mirrors[1].plane.offset += 0.5;
  try {
    Reconstruct(sweep.archive, other);
    FAIL() << "accepted";
  } catch (const CalibrationMismatchError& e) {
    EXPECT_NE(std::string(e.what()).find("--calibration-mismatch-ok"), std::string::npos);
  }
  ReconstructOptions ok;
  ok.allow_calibration_mismatch = true;
  const Reconstruction r = Reconstruct(sweep.archive, other, ok);
  ASSERT_FALSE(r.summary.warnings.empty());
  EXPECT_NE(r.summary.warnings.front().find("mismatch"), std::string::npos);

  // The device's way: the file's SHA-256 in the header.
  ScanArchive device = sweep.archive;
  device.header.erase("calibration");
  device.header["calibration_sha256"] = "aa";
  ReconstructOptions sha;
  sha.calibration_file_sha256 = "bb";
  EXPECT_THROW(Reconstruct(device, sweep.calibration, sha), CalibrationMismatchError);
  sha.calibration_file_sha256 = "aa";
  EXPECT_GT(Reconstruct(device, sweep.calibration, sha).summary.points, 0u);
  device.header["calibration_hash"] = "0123456789abcdef";
  EXPECT_THROW(Reconstruct(device, sweep.calibration, sha), CalibrationMismatchError);
}

TEST(ArchiveCheck, EmptyOrTruncatedArchives) {
  const Sweep& sweep = CuboidSweep();
  ScanArchive empty = sweep.archive;
  empty.frames.clear();
  EXPECT_THROW(Reconstruct(empty, sweep.calibration), ReconstructError);
  ScanArchive no_header;
  EXPECT_THROW(Reconstruct(no_header, sweep.calibration), ReconstructError);

  // An archive cut mid-sweep: what was recovered, said so.
  VectorSink sink;
  ScanWriter writer(sink);
  writer.Begin(sweep.archive.header);
  for (const FrameRecord& f : sweep.archive.frames) writer.AppendFrame(f);
  std::vector<uint8_t> bytes = sink.bytes();
  bytes.resize(bytes.size() * 2 / 3);
  const ScanArchive cut = ReadScan(bytes);
  ASSERT_FALSE(cut.report.complete);
  const Reconstruction r = Reconstruct(cut, sweep.calibration);
  EXPECT_FALSE(r.summary.archive_complete);
  EXPECT_GT(r.summary.points, 1000u);
  ASSERT_FALSE(r.summary.warnings.empty());
  EXPECT_NE(r.summary.warnings.front().find("incomplete archive"), std::string::npos);
  EXPECT_LE(ScoreAgainstTruth(sweep, r.cloud).wrong, r.summary.points * 0.001);
}

TEST(ArchiveCheck, CalibrationMissingACameraOrAViewIsAnError) {
  const Sweep& sweep = CuboidSweep();
  Calibration one_camera = sweep.calibration;
  one_camera.cameras.pop_back();
  ReconstructOptions ok;
  ok.allow_calibration_mismatch = true;
  try {
    Reconstruct(sweep.archive, one_camera, ok);
    FAIL() << "accepted";
  } catch (const ReconstructError& e) {
    EXPECT_NE(std::string(e.what()).find("\"lower\" is not in the calibration"), std::string::npos)
        << e.what();
  }
  Calibration no_right_view = sweep.calibration;
  auto& views = no_right_view.cameras[0].views;
  views.erase(std::remove_if(views.begin(), views.end(),
                             [](const CalibrationView& v) { return v.mirror == "right"; }),
              views.end());
  try {
    Reconstruct(sweep.archive, no_right_view, ok);
    FAIL() << "accepted";
  } catch (const ReconstructError& e) {
    EXPECT_NE(std::string(e.what()).find("no view for the right mirror"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace mirrorscan::reconstruction::testing_sweeps
