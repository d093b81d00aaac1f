// calibration.json: the cabinet's calibration (cameras, mirror planes, panel offsets,
// view regions, laser geometry, residuals). Parsed and validated here so the host (which
// writes it) and the device (which stores uploaded ones) agree on what a valid file is.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "common/config/json_reader.h"
#include "common/geometry/camera.h"
#include "common/geometry/plane.h"

namespace mirrorscan {

inline constexpr const char* kCalibrationSchema = "mirrorscan.calibration";
inline constexpr int kCalibrationVersion = 1;
// The adopted cabinet has two cameras; a third, looking up under the bust and the chin, is
// the measured variation (docs/cabinet-design.md).
inline constexpr size_t kMaxCameras = 3;

// One view of a camera: the centre (no mirror) or the image of one mirror. A mirror
// view's region is the polygon `outline_px`; the centre view is everything else.
struct CalibrationView {
  std::string name;
  std::optional<std::string> mirror;        // the mirror's name; nullopt for the centre
  std::vector<Eigen::Vector2d> outline_px;  // mirror views only, at least 3 points

  bool Contains(const Eigen::Vector2d& pixel) const;  // inside the outline polygon
};

struct CalibrationCamera {
  std::string name;
  Camera camera;
  double fps = 30.0;
  std::vector<CalibrationView> views;

  // Name of the view a pixel belongs to: the first mirror view containing it, else the
  // centre view.
  const CalibrationView* ViewAt(const Eigen::Vector2d& pixel) const;
};

struct CalibrationMirror {
  std::string name;                         // "left" or "right"
  Plane plane;                              // normal towards the subject
  std::vector<Eigen::Vector3d> corners_mm;  // the reflecting rectangle; empty if unknown
  double panel_offset_mm = 0.0;             // diffuse panel behind the mirror surface
};

// Laser k at time t: normal · x = height_at_t0 + speed·t + k·spacing.
struct CalibrationLasers {
  int count = 1;
  double spacing_mm = 200.0;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double height_at_t0_mm = 0.0;
  double speed_mm_s = 0.0;
  // Each laser's height above laser 0 as measured (offsets_mm[0] = 0, ascending); empty:
  // k · spacing_mm.
  std::vector<double> offsets_mm;
  // The slide's position readback minus laser 0's height, as measured; absent: unknown.
  std::optional<double> readback_offset_mm;

  double OffsetOf(int laser) const {
    return offsets_mm.empty() ? laser * spacing_mm : offsets_mm.at(laser);
  }
  Plane PlaneAt(int laser, double t) const {
    return Plane{normal, -(height_at_t0_mm + speed_mm_s * t + OffsetOf(laser))};
  }
};

struct ViewResidual {
  std::string camera, view;
  double rms_px = 0.0;
  double max_px = 0.0;
  int points = 0;
};

struct CalibrationResiduals {
  double reprojection_rms_px = 0.0;  // over every corner of every view
  std::vector<ViewResidual> views;
};

struct Calibration {
  std::string source;                      // what produced it (free text)
  std::string target_id;                   // the calibration target used; empty if none
  std::vector<CalibrationCamera> cameras;  // one or two
  std::vector<CalibrationMirror> mirrors;  // exactly two: left, right
  std::optional<CalibrationLasers> lasers;
  CalibrationResiduals residuals;

  // Errors are ConfigError naming the file and key; every check a device needs before
  // trusting an upload is made here (schema, version, unit normals, proper rotations,
  // finite numbers, views referring to known mirrors, unique names).
  static Calibration Parse(const nlohmann::json& json, const std::string& file_name);
  static Calibration Load(const std::filesystem::path& file);
  static Calibration ParseText(const std::string& text, const std::string& file_name);

  nlohmann::json ToJson() const;
  // FNV-1a 64 of the canonical JSON of everything but the residuals and the source, as
  // 16 hex digits: equal geometry gives an equal hash, whoever wrote the file.
  std::string ContentHash() const;

  const CalibrationCamera* FindCamera(const std::string& name) const;
  const CalibrationMirror* FindMirror(const std::string& name) const;
};

}  // namespace mirrorscan
