#include "host/reconstruction/summary.h"

#include <string>

#include <gtest/gtest.h>

namespace mirrorscan::reconstruction {
namespace {

// Every count lands under its documented name (docs/reconstruction.md), in JSON and text.
TEST(Summary, NamesEveryCountAsTheDocsDo) {
  ReconstructSummary s;
  s.frames = 3;
  s.peaks = 40;
  s.points = 21;
  s.decided_by_stereo = 5;
  s.decided_by_cylinder = 6;
  s.decided_by_volume = 7;
  s.decided_by_column_count = 8;
  s.decided_by_label_vote = 9;
  s.dropped_outside = 11;
  s.dropped_seen_through = 12;
  s.dropped_off_surface = 13;
  s.dropped_flat_off_surface = 14;
  s.points_per_camera = {20, 1};
  s.points_per_view = {10, 5, 4, 1, 1};
  s.points_per_laser = {21};
  s.laser_height.source = "readback";
  s.laser_height.reason = "panels not used (option)";
  s.warnings = {"something to say"};
  s.timings_s = {{"read", 0.25}, {"rays", 0.5}};
  const nlohmann::json json = SummaryJson(s);
  EXPECT_EQ(json["points"], 21);
  EXPECT_EQ(json["decided"]["stereo"], 5);
  EXPECT_EQ(json["decided"]["column_count"], 8);
  EXPECT_EQ(json["decided"]["label_vote"], 9);
  EXPECT_EQ(json["dropped"]["outside_volume"], 11);
  EXPECT_EQ(json["dropped"]["seen_through"], 12);
  EXPECT_EQ(json["dropped"]["off_surface"], 13);
  EXPECT_EQ(json["dropped"]["flat_off_surface"], 14);
  EXPECT_EQ(json["points_per_view"]["right-left"], 1);
  EXPECT_EQ(json["points_per_camera"][1], 1);
  EXPECT_EQ(json["laser_height"]["source"], "readback");
  EXPECT_DOUBLE_EQ(json["timings_s"]["total"].get<double>(), 0.75);
  EXPECT_EQ(json["warnings"][0], "something to say");
  const std::string text = SummaryText(s);
  EXPECT_NE(text.find("21 points from 40 peaks in 3 frames"), std::string::npos) << text;
  EXPECT_NE(text.find("decided by stereo 5, cylinder 6, volume 7, column count 8, label vote 9"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("off surface 13, flat off surface 14"), std::string::npos) << text;
  EXPECT_NE(text.find("laser heights from readback (panels not used (option))"), std::string::npos)
      << text;
  EXPECT_NE(text.find("warning: something to say"), std::string::npos) << text;
}

TEST(Summary, TheTimerLapsEachStageInOrderAndReportsItsStart) {
  ReconstructSummary s;
  std::string started;
  StageTimer timer(&s, [&](const std::string& stage, double fraction) {
    started += stage + "@" + std::to_string(static_cast<int>(fraction)) + " ";
  });
  timer.Start("rays");
  timer.Lap("rays");
  timer.Lap("laser heights");
  timer.Start("done");
  ASSERT_EQ(s.timings_s.size(), 2u);
  EXPECT_EQ(s.timings_s[0].first, "rays");
  EXPECT_EQ(s.timings_s[1].first, "laser heights");
  EXPECT_GE(s.timings_s[1].second, 0.0);
  EXPECT_EQ(started, "rays@0 done@1 ");
}

}  // namespace
}  // namespace mirrorscan::reconstruction
