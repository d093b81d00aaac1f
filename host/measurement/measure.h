#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "host/measurement/section.h"

namespace mirrorscan::measurement {

// Body measurements from a mesh, after ISO 8559-1's definitions as docs/measurement.md
// states them for a scan: landmarks found in horizontal sections (legs, crotch, arms
// told apart from the torso), girths taken as a tape takes them (the convex hull of the
// part's section) with the followed contour beside them, heights from the floor (z = 0).
// Where the surface does not support a value (a hole across a section, an arm merged
// with the torso, a subject that is not a human body) the value is withheld with the
// reason, never guessed. One value is extrapolated, where a scan leaves a hole at the top
// of the head: the stature, from the seen cap below the hole (head_cap.h), a short way
// only and with a lower confidence (docs/measurement.md).

struct Measurement {
  std::string name;                  // e.g. "chest_girth", "arm_length_left"
  std::optional<double> value_mm;    // nullopt when withheld
  std::optional<double> z_mm;        // height of a horizontal girth
  std::optional<double> contour_mm;  // a girth's followed contour
  double confidence = 0.0;           // 0..1; 0 when withheld
  std::optional<std::string> withheld;
};

// The horizontal girth at a requested height, of each body part there: the torso (arms
// told apart), each leg below the crotch, the "upper_body" above the arms' junction, or
// the "section" of a subject that is not a body.
struct SliceGirth {
  double z_mm = 0.0;
  std::string part;
  std::optional<double> girth_mm, contour_mm;
  std::optional<std::string> withheld;
};

struct Landmark {
  std::string name;
  Eigen::Vector3d point_mm;
};

// A measured contour (the tape's path: a girth's hull, closed), for previews.
struct MeasuredContour {
  std::string name;
  std::vector<Eigen::Vector3d> points_mm;
};

struct BodyMeasurements {
  std::optional<double> stature_mm;
  std::optional<std::string> stature_withheld;
  bool human = false;
  std::vector<Measurement> measurements;
  std::vector<SliceGirth> slices;
  std::vector<Landmark> landmarks;
  std::vector<MeasuredContour> contours;
  Eigen::Vector2d lateral = Eigen::Vector2d::UnitX();  // the body's left, in x-y

  const Measurement* Find(const std::string& name) const;
};

struct MeasureOptions {
  std::vector<double> girth_at_mm;  // extra horizontal girths
};

// Throws std::invalid_argument on an empty mesh.
BodyMeasurements MeasureBody(const TriangleMesh& mesh, const MeasureOptions& options = {});

// {"stature_mm", "measurements": [{"name", "value_mm", "z_mm", "contour_mm",
//  "confidence", "withheld"}], "slices": [{"z_mm", "part", "girth_mm", "contour_mm",
//  "withheld"}], "landmarks": [{"name", "point_mm"}]}; null where withheld or not a girth.
nlohmann::json ToJson(const BodyMeasurements& body);
// One row per measurement, then per slice: name,value_mm,z_mm,contour_mm,confidence,withheld
std::string ToCsv(const BodyMeasurements& body);

}  // namespace mirrorscan::measurement
