#include "host/reconstruction/reconstruct.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <new>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <tuple>
#include <type_traits>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "common/config/json_reader.h"
#include "common/parallel/parallel_for.h"
#include "host/calibration/laser_height.h"
#include "host/reconstruction/icp.h"

namespace mirrorscan::reconstruction {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr int kMaxLasers = 3;
constexpr int kViews = 5;
// A (view, laser) pair as one small integer, for votes.
constexpr int kKeys = kViews * kMaxLasers;
// Neighbours of one hypothesis closer than this in 3D belong to one surface.
constexpr double kLinkColumnMm = 6.0;
constexpr double kLinkFrameMm = 25.0;
constexpr double kSmoothMaxMm = 10.0;

std::string Format(const char* format, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), format, args...);
  return buffer;
}

int Key(PointView view, int laser) { return static_cast<int>(view) * kMaxLasers + laser; }

// One way a peak could have come about: seen along `view`, lit by `laser`.
struct Hypothesis {
  Eigen::Vector3d point;
  Eigen::Vector3d last_direction;  // the ray's last segment (towards the point)
  float sin_angle = 0;             // ray against the laser plane
  float path_mm = 0;               // camera to point along the (unfolded) ray
  uint8_t key = 0;
  bool confirmed = false;  // another camera saw this laser there too
  bool floor = false;      // on the floor below the cylinder: never a point of the subject
  // On a panel beside a mirror, where that laser's line runs: laser-height data that the
  // fit did not take (another camera's line, a stretch it left out), never the subject.
  bool panel = false;
  // A surface that is not the subject: it decides a peak, and the point is dropped.
  bool Background() const { return floor || panel; }
};

// Every peak's hypotheses in one allocation. Each chunk of frames writes its own stretch,
// sized for the most its peaks can have: no chunk waits for another, nothing is copied
// after, and the stretches' unused tails are never written, so that memory is never
// touched (its first touch, not the writing, is what costs on this machine). Only a peak's
// own [first_hypothesis, first_hypothesis + hypotheses) is ever read.
class Hypotheses {
 public:
  explicit Hypotheses(size_t capacity)
      : data_(std::allocator<Hypothesis>().allocate(capacity)), capacity_(capacity) {}
  ~Hypotheses() { std::allocator<Hypothesis>().deallocate(data_, capacity_); }
  Hypotheses(const Hypotheses&) = delete;
  Hypotheses& operator=(const Hypotheses&) = delete;
  Hypothesis& operator[](size_t i) { return data_[i]; }
  const Hypothesis& operator[](size_t i) const { return data_[i]; }

  // Appends into [next, end) of the store.
  struct Writer {
    Hypotheses* store;
    uint32_t next, end;
    uint32_t size() const { return next; }
    void push_back(const Hypothesis& h) {
      if (next >= end) throw std::logic_error("more hypotheses than a peak can have");
      new (store->data_ + next) Hypothesis(h);
      ++next;
    }
  };

 private:
  static_assert(std::is_trivially_destructible_v<Hypothesis>);
  Hypothesis* data_;
  size_t capacity_;
};

enum class Rule : uint8_t { kNone, kCylinder, kVolume, kColumnCount, kLabelVote, kStereo };

struct PeakState {
  uint32_t frame = 0;  // archive frame index
  uint16_t u = 0;
  float v = 0;
  float score = 0;
  uint32_t first_hypothesis = 0;
  uint8_t hypotheses = 0;
  uint8_t region = 0;  // the calibration view region: 0 centre, 1 left, 2 right
  bool panel = false;
  bool no_ray = false;
  int16_t chosen = -1;  // index among its hypotheses
  Rule rule = Rule::kNone;
};

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t Find(uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void Join(uint32_t a, uint32_t b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

class Stopwatch {
 public:
  explicit Stopwatch(ReconstructSummary* summary) : summary_(summary) {}
  void Lap(const std::string& stage) {
    const auto now = std::chrono::steady_clock::now();
    summary_->timings_s.emplace_back(stage, std::chrono::duration<double>(now - last_).count());
    last_ = now;
  }

 private:
  ReconstructSummary* summary_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

const nlohmann::json* HeaderValue(const nlohmann::json& header, const char* key) {
  if (!header.is_object()) return nullptr;
  const auto it = header.find(key);
  return it == header.end() ? nullptr : &*it;
}

// The archive names its calibration by the file's SHA-256 (the device), by content hash,
// or by carrying it whole (the simulator); every one given must match.
void CheckCalibration(const ScanArchive& archive, const Calibration& calibration,
                      const ReconstructOptions& options, ReconstructSummary* summary) {
  std::vector<std::string> mismatches;
  bool named = false;
  if (const auto* sha = HeaderValue(archive.header, "calibration_sha256");
      sha && sha->is_string()) {
    named = true;
    if (!options.calibration_file_sha256.empty() &&
        sha->get<std::string>() != options.calibration_file_sha256) {
      mismatches.push_back("the archive's calibration_sha256 " + sha->get<std::string>() +
                           " is not this file's " + options.calibration_file_sha256);
    }
  }
  if (const auto* hash = HeaderValue(archive.header, "calibration_hash");
      hash && hash->is_string()) {
    named = true;
    if (hash->get<std::string>() != calibration.ContentHash()) {
      mismatches.push_back("the archive's calibration_hash " + hash->get<std::string>() +
                           " is not this calibration's " + calibration.ContentHash());
    }
  }
  if (const auto* embedded = HeaderValue(archive.header, "calibration");
      embedded && embedded->is_object()) {
    named = true;
    std::string hash;
    try {
      hash = Calibration::Parse(*embedded, "the archive's header").ContentHash();
    } catch (const std::exception& e) {
      hash = std::string("unreadable (") + e.what() + ")";
    }
    if (hash != calibration.ContentHash()) {
      mismatches.push_back("the archive was made with calibration " + hash + ", this one is " +
                           calibration.ContentHash());
    }
  }
  if (!named)
    summary->warnings.push_back("the archive does not say which calibration it was made with");
  if (mismatches.empty()) return;
  std::string text = mismatches.front();
  for (size_t i = 1; i < mismatches.size(); ++i) text += "; " + mismatches[i];
  if (!options.allow_calibration_mismatch) {
    throw CalibrationMismatchError("calibration mismatch: " + text +
                                   " (another cabinet or an older calibration; "
                                   "--calibration-mismatch-ok to use it anyway)");
  }
  summary->warnings.push_back("calibration mismatch accepted: " + text);
}

// The archive's cameras by FrameRecord::camera, matched to the calibration's by name.
std::vector<const CalibrationCamera*> CamerasOf(const ScanArchive& archive,
                                                const Calibration& calibration) {
  std::vector<const CalibrationCamera*> cameras;
  const auto* listed = HeaderValue(archive.header, "cameras");
  if (!listed || !listed->is_array()) {
    for (const CalibrationCamera& c : calibration.cameras) cameras.push_back(&c);
    return cameras;
  }
  for (const nlohmann::json& entry : *listed) {
    const std::string name =
        entry.is_object() && entry.contains("name") && entry["name"].is_string()
            ? entry["name"].get<std::string>()
            : "";
    cameras.push_back(calibration.FindCamera(name));
  }
  // A camera the archive lists but never used does not need calibrating.
  std::vector<bool> used(cameras.size(), false);
  for (const FrameRecord& frame : archive.frames) {
    if (frame.camera >= cameras.size()) {
      throw ReconstructError(Format("frame %u names camera %d; the archive lists %zu camera(s)",
                                    frame.sequence, frame.camera, cameras.size()));
    }
    used[frame.camera] = true;
  }
  for (size_t i = 0; i < cameras.size(); ++i) {
    if (used[i] && !cameras[i]) {
      throw ReconstructError("the archive's camera \"" +
                             (*listed)[i].value("name", std::string("?")) +
                             "\" is not in the calibration");
    }
  }
  return cameras;
}

// Per camera: the region of each mirror. A camera without a region for a mirror would
// take that mirror's image for the subject itself.
std::vector<std::array<const CalibrationView*, 2>> MirrorViewsOf(
    const std::vector<const CalibrationCamera*>& cameras, const Calibration& calibration) {
  std::vector<std::array<const CalibrationView*, 2>> views(cameras.size(), {nullptr, nullptr});
  for (size_t c = 0; c < cameras.size(); ++c) {
    if (!cameras[c]) continue;
    for (int m = 0; m < 2; ++m) {
      for (const CalibrationView& view : cameras[c]->views) {
        if (view.mirror && *view.mirror == calibration.mirrors[m].name) views[c][m] = &view;
      }
      if (!views[c][m]) {
        throw ReconstructError("calibration: camera \"" + cameras[c]->name +
                               "\" has no view for the " + calibration.mirrors[m].name +
                               " mirror, so its image there cannot be told from the subject");
      }
    }
  }
  return views;
}

struct LaserPlanes {
  std::vector<std::array<Plane, kMaxLasers>> per_frame;  // by archive frame index
  std::vector<bool> valid;
  int count = 1;
};

int LaserCountOf(const ScanArchive& archive, const Calibration& calibration) {
  int count = calibration.lasers ? calibration.lasers->count : 1;
  if (const auto* lasers = HeaderValue(archive.header, "lasers");
      lasers && lasers->is_object() && lasers->contains("count") &&
      (*lasers)["count"].is_number_integer()) {
    count = (*lasers)["count"].get<int>();
  }
  if (count < 1 || count > kMaxLasers)
    throw ReconstructError(
        Format("the archive says %d lasers; 1 to %d are supported", count, kMaxLasers));
  return count;
}

// Laser planes of every frame: the panel lines' fit, or the slide readback where that is
// impossible.
LaserPlanes FitLaserPlanes(const ScanArchive& archive, const Calibration& calibration,
                           const std::vector<const CalibrationCamera*>& cameras,
                           const ReconstructOptions& options, std::vector<PeakState>* peaks,
                           const std::vector<uint32_t>& frame_first,
                           const std::vector<std::optional<Ray3d>>& rays, int threads,
                           ReconstructSummary* summary) {
  LaserPlanes planes;
  planes.count = LaserCountOf(archive, calibration);
  planes.per_frame.resize(archive.frames.size());
  planes.valid.assign(archive.frames.size(), false);
  LaserHeightSummary& s = summary->laser_height;
  const double readback_offset =
      calibration.lasers ? calibration.lasers->readback_offset_mm.value_or(0.0) : 0.0;

  std::string reason;
  if (options.laser_height_from_panels) {
    try {
      LaserCabinet cabinet =
          LaserCabinetFromCalibration(calibration, "calibration", options.panel_margin_mm);
      // By FrameRecord::camera; a listed camera that took no frame stands in as any other.
      cabinet.cameras.clear();
      const auto any = std::find_if(cameras.begin(), cameras.end(),
                                    [](const CalibrationCamera* c) { return c != nullptr; });
      if (any == cameras.end()) throw ReconstructError("the archive uses no calibrated camera");
      for (const CalibrationCamera* c : cameras)
        cabinet.cameras.push_back(c ? c->camera : (*any)->camera);
      cabinet.laser_count = planes.count;
      if (const auto* lasers = HeaderValue(archive.header, "lasers");
          lasers && lasers->is_object() && lasers->contains("spacing_mm") &&
          (*lasers)["spacing_mm"].is_number())
        cabinet.nominal_spacing_mm = (*lasers)["spacing_mm"].get<double>();
      if (const auto* slide = HeaderValue(archive.header, "slide");
          slide && slide->is_object() && slide->contains("speed_mm_s") &&
          (*slide)["speed_mm_s"].is_number())
        cabinet.nominal_speed_mm_s = (*slide)["speed_mm_s"].get<double>();
      LaserHeightOptions lo;
      if (const auto* start = HeaderValue(archive.header, "start_steady_ns");
          start && start->is_number_integer())
        lo.time_origin_ns = start->get<int64_t>();
      lo.readback_offset_mm = readback_offset;
      lo.readback_tolerance_mm = options.readback_tolerance_mm;
      // The calibration measured the panels; one scan's sweep is no better at it.
      lo.fit_panel_offsets = false;
      lo.threads = threads;
      if (calibration.lasers) lo.normal = calibration.lasers->normal;
      // Each peak's ray is known here: the fit gets the points where one meets a panel before
      // any mirror, found as it would find them, without undistorting every peak again.
      std::vector<std::vector<PanelPoint>> chunks(ChunkCount(archive.frames.size(), threads));
      ForEachChunk(archive.frames.size(), threads, [&](size_t chunk, size_t begin, size_t end) {
        for (size_t f = begin; f < end; ++f) {
          for (uint32_t i = frame_first[f]; i < frame_first[f + 1]; ++i) {
            if (!rays[i]) continue;
            const PeakState& p = (*peaks)[i];
            if (auto point = PanelPointOnRay(cabinet, f, p.u, p.v, *rays[i]))
              chunks[chunk].push_back(*point);
          }
        }
      });
      std::vector<PanelPoint> panel_points;
      for (const auto& chunk : chunks)
        panel_points.insert(panel_points.end(), chunk.begin(), chunk.end());
      const LaserHeightResult result =
          EstimateLaserHeightsFromPoints(archive.frames, cabinet, std::move(panel_points), lo);
      const LaserFit& fit = result.fit;
      for (size_t f = 0; f < archive.frames.size(); ++f) {
        const double t = fit.TimeS(archive.frames[f].timestamp_ns);
        for (int k = 0; k < planes.count; ++k) planes.per_frame[f][k] = fit.PlaneAt(k, t);
        planes.valid[f] = true;
      }
      s.source = "panels";
      s.speed_mm_s = fit.speed_mm_s;
      s.height_at_t0_mm = fit.height_at_t0_mm;
      s.offsets_mm = fit.offset_mm;
      s.normal = fit.normal;
      s.panel_residual_rms_mm = result.residual_rms_mm;
      s.panel_points = result.inliers;
      if (result.readback) {
        s.readback_frames = result.readback->frames;
        s.readback_offset_mm = result.readback->offset_mm;
        s.readback_max_error_mm = result.readback->max_error_mm;
        s.readback_frames_off = result.readback->frames_off;
      }
      for (const std::string& w : result.warnings)
        summary->warnings.push_back("laser height: " + w);
      // The panels' own peaks are laser-height data, not the subject.
      for (const PanelPoint& p : result.points) {
        if (p.laser < 0) continue;
        const auto begin = peaks->begin() + frame_first[p.frame];
        const auto end = peaks->begin() + frame_first[p.frame + 1];
        auto it = std::lower_bound(begin, end, p.u,
                                   [](const PeakState& a, uint16_t u) { return a.u < u; });
        for (; it != end && it->u == p.u; ++it) {
          if (it->v == p.v) it->panel = true;
        }
      }
      return planes;
    } catch (const LaserHeightError& e) {
      reason = e.what();
    } catch (const ConfigError& e) {
      reason = e.what();
    }
  } else {
    reason = "panels not used (option)";
  }

  // Readback: laser 0 at readback − offset, the others at the calibration's offsets.
  if (!calibration.lasers) {
    throw ReconstructError("no laser heights: the panels gave none (" + reason +
                           ") and the calibration has no lasers for the readback");
  }
  const CalibrationLasers& lasers = *calibration.lasers;
  if (planes.count > 1 && lasers.offsets_mm.size() < static_cast<size_t>(planes.count) &&
      lasers.count < planes.count) {
    summary->warnings.push_back("laser offsets above laser 0 assumed at the nominal spacing");
  }
  size_t with_readback = 0;
  for (size_t f = 0; f < archive.frames.size(); ++f) {
    const double readback = archive.frames[f].slide_position_mm;
    if (!std::isfinite(readback)) continue;
    const double h0 = readback - readback_offset;
    for (int k = 0; k < planes.count; ++k) {
      const double offset = k < static_cast<int>(lasers.offsets_mm.size()) ? lasers.offsets_mm[k]
                                                                           : k * lasers.spacing_mm;
      planes.per_frame[f][k] = Plane{lasers.normal, -(h0 + offset)};
    }
    planes.valid[f] = true;
    ++with_readback;
  }
  if (with_readback == 0) {
    throw ReconstructError("no laser heights: the panels gave none (" + reason +
                           ") and no frame has a slide readback");
  }
  s.source = "readback";
  s.reason = reason;
  s.normal = lasers.normal;
  s.readback_frames = with_readback;
  if (!calibration.lasers->readback_offset_mm) {
    summary->warnings.push_back(
        "laser heights from the slide readback with no measured readback offset (0 assumed)");
  }
  summary->warnings.push_back("laser heights from the slide readback: " + reason);
  return planes;
}

// A view region's outline cut by every image column: where the vertical line through the
// column crosses the outline, rows ascending. A pixel is inside when an odd number of them
// lie above it (the even–odd rule of CalibrationView::Contains, along the column).
class RegionColumns {
 public:
  RegionColumns() = default;
  RegionColumns(const CalibrationView& view, int width) : crossings_(width) {
    const std::vector<Eigen::Vector2d>& outline = view.outline_px;
    for (int u = 0; u < width; ++u) {
      for (size_t i = 0, j = outline.size() - 1; i < outline.size(); j = i++) {
        const Eigen::Vector2d& a = outline[i];
        const Eigen::Vector2d& b = outline[j];
        if ((a.x() > u) == (b.x() > u)) continue;
        crossings_[u].push_back(a.y() + (u - a.x()) * (b.y() - a.y()) / (b.x() - a.x()));
      }
      std::sort(crossings_[u].begin(), crossings_[u].end());
    }
  }
  bool Contains(int u, double v) const {
    if (u < 0 || u >= static_cast<int>(crossings_.size())) return false;
    const std::vector<double>& c = crossings_[u];
    return (std::upper_bound(c.begin(), c.end(), v) - c.begin()) % 2 == 1;
  }

 private:
  std::vector<std::vector<double>> crossings_;
};

struct Geometry {
  std::vector<const CalibrationCamera*> cameras;
  std::vector<std::array<const CalibrationView*, 2>> mirror_views;
  std::vector<std::array<RegionColumns, 2>> mirror_regions;  // the same, by column
  std::array<Plane, 2> mirrors;
  std::vector<PlanarRectangle> mirror_rectangles;  // empty without corners
  std::vector<PlanarRectangle> panels;             // empty without corners
};

// How close to a laser plane a ray's panel hit must be to be that laser's line there: the
// panel's place is the calibration's estimate, the lasers are 200 mm apart.
constexpr double kPanelLineMm = 10.0;

// Every (view, laser) this peak could be, inside the bounding cylinder (or on the floor).
void Hypothesize(const Geometry& g, const FrameRecord& frame,
                 const std::array<Plane, kMaxLasers>& planes, int laser_count,
                 const BoundingCylinder& cylinder, double mirror_clearance_mm,
                 const std::optional<Ray3d>& ray, PeakState* peak, Hypotheses::Writer* out) {
  peak->first_hypothesis = static_cast<uint32_t>(out->size());
  if (!ray) {
    peak->no_ray = true;
    return;
  }
  peak->region = 0;
  for (int m = 0; m < 2; ++m) {
    if (g.mirror_regions[frame.camera][m].Contains(peak->u, peak->v)) {
      peak->region = static_cast<uint8_t>(m + 1);
      break;
    }
  }
  // Try each laser on one ray segment [0, t_max), `path_before` along the ray from the camera.
  auto add = [&](const Ray3d& segment, double t_max, double path_before, PointView view) {
    for (int k = 0; k < laser_count; ++k) {
      const auto t = IntersectRayPlane(segment, planes[k], 1.0);
      if (!t || *t >= t_max) continue;
      const Eigen::Vector3d point = segment.At(*t);
      // Inside the bounding cylinder and clear of both mirrors: nothing is lit behind them
      // (a ray reflected past the other mirror's edge would otherwise go on outside), and
      // near a mirror's glass every camera's reflected rays run close together, so phantom
      // points there would confirm each other. A laser at the floor's height lights the
      // floor, which runs on under the mirrors' feet: that must be a way the peak can have
      // come about, or another laser would take the floor's stripe into the volume.
      const bool floor = cylinder.OnFloor(point);  // below the bottom: never Contains()
      if (!floor &&
          (!cylinder.Contains(point) || g.mirrors[0].SignedDistance(point) < mirror_clearance_mm ||
           g.mirrors[1].SignedDistance(point) < mirror_clearance_mm))
        continue;
      Hypothesis h;
      h.floor = floor;
      h.point = point;
      h.last_direction = segment.direction;
      h.sin_angle = static_cast<float>(std::abs(planes[k].normal.dot(segment.direction)));
      h.path_mm = static_cast<float>(path_before + *t);
      h.key = static_cast<uint8_t>(Key(view, k));
      out->push_back(h);
    }
    // The panels beside the mirrors carry every laser's line too: where the segment meets
    // one before any mirror's glass, on a laser's plane, that laser's line is a way the
    // peak can have come about (else another laser's point in front of the panel takes it).
    double nearest = t_max;
    const PlanarRectangle* panel = nullptr;
    for (const PlanarRectangle& p : g.panels)
      if (const auto t = p.Intersect(segment); t && *t < nearest) {
        nearest = *t;
        panel = &p;
      }
    if (!panel) return;
    for (const PlanarRectangle& m : g.mirror_rectangles)
      if (const auto t = m.Intersect(segment); t && *t < nearest) return;
    const Eigen::Vector3d on_panel = segment.At(nearest);
    for (int k = 0; k < laser_count; ++k) {
      if (std::abs(planes[k].SignedDistance(on_panel)) > kPanelLineMm) continue;
      Hypothesis h;
      h.panel = true;
      h.point = on_panel;
      h.last_direction = segment.direction;
      h.sin_angle = static_cast<float>(std::abs(planes[k].normal.dot(segment.direction)));
      h.path_mm = static_cast<float>(path_before + nearest);
      h.key = static_cast<uint8_t>(Key(view, k));
      out->push_back(h);
    }
  };
  constexpr double kFar = 1e7;
  if (peak->region == 0) {
    add(*ray, kFar, 0.0, PointView::kCenter);
  } else {
    const int a = peak->region - 1;
    const int b = 1 - a;
    const auto t_a = IntersectRayPlane(*ray, g.mirrors[a], 0.0);
    if (t_a) {
      // Something in front of the mirror (an arm reaching into its region), or, where the
      // ray passes below or beside the glass (the region's outline is not the glass), a
      // panel behind it. The mirror's view stays a hypothesis either way: the outline and
      // the corners are both measured.
      const bool meets_glass =
          g.mirror_rectangles.empty() || g.mirror_rectangles[a].Intersect(*ray).has_value();
      add(*ray, meets_glass ? *t_a : kFar, 0.0, PointView::kCenter);
      const Ray3d once{ray->At(*t_a), g.mirrors[a].ReflectDirection(ray->direction)};
      std::optional<double> t_b;
      if (!g.mirror_rectangles.empty()) t_b = g.mirror_rectangles[b].Intersect(once);
      add(once, t_b.value_or(kFar), *t_a, a == 0 ? PointView::kLeft : PointView::kRight);
      if (t_b) {
        const Ray3d twice{once.At(*t_b), g.mirrors[b].ReflectDirection(once.direction)};
        add(twice, kFar, *t_a + *t_b, a == 0 ? PointView::kLeftRight : PointView::kRightLeft);
      }
    }
  }
  peak->hypotheses = static_cast<uint8_t>(out->size() - peak->first_hypothesis);
}

// The bounding cylinder's box cut into cubes `voxel_mm` on a side: the index of a point's
// voxel, and of its own and its 26 neighbours' (the grids below share it). With a margin,
// the grid has that many more voxels on every side, which only IndexInMargin reaches.
class VoxelBox {
 public:
  VoxelBox(const BoundingCylinder& c, double voxel_mm, int margin = 0)
      : voxel_mm_(voxel_mm), margin_(margin) {
    origin_ =
        Eigen::Vector3d(c.center_mm.x() - c.radius_mm, c.center_mm.y() - c.radius_mm, c.bottom_mm);
    size_ = (Eigen::Vector3d(2 * c.radius_mm, 2 * c.radius_mm, c.top_mm - c.bottom_mm) / voxel_mm)
                .array()
                .ceil()
                .cast<int>() +
            1 + 2 * margin;
  }
  size_t Voxels() const { return static_cast<size_t>(size_.x()) * size_.y() * size_.z(); }
  const Eigen::Vector3i& Size() const { return size_; }
  std::optional<size_t> Index(const Eigen::Vector3d& point) const {
    const Eigen::Vector3i c = Cell(point);
    if (!Inside(c)) return std::nullopt;
    return Flat(c);
  }
  std::optional<size_t> IndexInMargin(const Eigen::Vector3d& point) const {
    const Eigen::Vector3i c = Cell(point);
    if (!(c.array() >= 0).all() || !(c.array() < size_.array()).all()) return std::nullopt;
    return Flat(c);
  }
  template <typename F>
  void ForNeighbourhood(const Eigen::Vector3d& point, F&& visit) const {
    const Eigen::Vector3i at = Cell(point);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i c = at + Eigen::Vector3i(dx, dy, dz);
          if (Inside(c)) visit(Flat(c));
        }
  }

 private:
  // The margin added as an integer: the same voxel boundaries as without it.
  Eigen::Vector3i Cell(const Eigen::Vector3d& point) const {
    return ((point - origin_) / voxel_mm_).array().floor().cast<int>() + margin_;
  }
  bool Inside(const Eigen::Vector3i& c) const {
    return (c.array() >= margin_).all() && (c.array() < size_.array() - margin_).all();
  }
  size_t Flat(const Eigen::Vector3i& c) const {
    return (static_cast<size_t>(c.z()) * size_.y() + c.y()) * size_.x() + c.x();
  }
  double voxel_mm_;
  int margin_;
  Eigen::Vector3d origin_;
  Eigen::Vector3i size_;
};

// Per voxel, the OR of the bits added at points in it or in any of its 26 neighbours. Each
// point marks its own voxel only (a point up to one voxel outside the box marks the margin,
// from where it still reaches in); Spread() then ORs every voxel with its two neighbours
// along x, y and z in turn, which is the 3×3×3 neighbourhood. Marking all 27 voxels per
// point instead cost ten times the writes, scattered.
template <typename Bits>
class NeighbourhoodBits {
 public:
  NeighbourhoodBits(const BoundingCylinder& c, double voxel_mm)
      : box_(c, voxel_mm, 1), cells_(box_.Voxels(), 0) {}
  void Add(const Eigen::Vector3d& point, Bits bits) {
    if (const auto i = box_.IndexInMargin(point)) cells_[*i] |= bits;
  }
  void Spread(int threads) {
    const Eigen::Vector3i& size = box_.Size();
    const size_t sx = size.x(), sy = size.y(), sz = size.z();
    // Axis by axis: lines of n voxels `stride` apart, in blocks of `stride` lines side by
    // side; every voxel ORed with the voxels before and after it on its line (as they were
    // before this pass). Lines are independent, so they go to the threads.
    auto pass = [&](size_t blocks, size_t n, size_t stride) {
      ParallelFor(blocks * stride, threads, [&](size_t first, size_t last) {
        for (size_t line = first; line < last; ++line) {
          Bits* at = cells_.data() + (line / stride) * n * stride + line % stride;
          Bits before = 0;
          for (size_t k = 0; k < n; ++k, at += stride) {
            const Bits own = *at;
            const Bits after = k + 1 < n ? at[stride] : Bits{0};
            *at = static_cast<Bits>(before | own | after);
            before = own;
          }
        }
      });
    };
    pass(sy * sz, sx, 1);
    pass(sz, sy, sx);
    pass(1, sz, sx * sy);
  }
  // After Spread(); 0 outside the box.
  Bits At(const Eigen::Vector3d& point) const {
    const auto i = box_.Index(point);
    return i ? cells_[*i] : Bits{0};
  }

 private:
  VoxelBox box_;
  std::vector<Bits> cells_;
};

// The voxels (10 mm) near a point that was decided alone: the subject's volume as the scan
// itself carves it. A wrong laser's hypothesis lies on the ray behind the surface the ray
// really met, where nothing was seen.
constexpr double kOccupancyVoxelMm = 10.0;

// Per voxel (20 mm), the (view, laser) keys of the peaks decided without the vote near it.
// A mirror stripe that no rule decided can be joined to a real surface in front of the
// mirror by a chain of its phantom hypotheses (its direct ray meeting another laser's plane
// in the air beside an arm); the vote would carry that surface's key along the whole chain,
// so in a mirror's region it gives the direct view only to points near peaks decided so.
constexpr double kKeyOccupancyVoxelMm = 20.0;
static_assert(kKeys <= 16, "one bit per key in a uint16_t");

// Per camera and voxel (10 mm): the best ray–plane angle (its sine) of that camera's
// points there.
class AngleGrid {
 public:
  AngleGrid(const BoundingCylinder& c, size_t cameras)
      : box_(c, 10.0), cells_(cameras, std::vector<float>(box_.Voxels(), 0.0f)) {}
  void Add(size_t camera, const Eigen::Vector3d& point, float sin_angle) {
    if (const auto i = box_.Index(point)) {
      cells_[camera][*i] = std::max(cells_[camera][*i], sin_angle);
    }
  }
  // The best sine another camera has at the point.
  float BestOther(size_t camera, const Eigen::Vector3d& point) const {
    const auto i = box_.Index(point);
    float best = 0;
    if (!i) return best;
    for (size_t c = 0; c < cells_.size(); ++c)
      if (c != camera) best = std::max(best, cells_[c][*i]);
    return best;
  }

 private:
  VoxelBox box_;
  std::vector<std::vector<float>> cells_;
};

// A peak decided on its own: its one hypothesis; else the one another camera confirms; else
// the one inside the cylinder's core among those confirmed (or among all, none confirmed).
void DecideAlone(std::vector<PeakState>* peaks, const Hypotheses& hyp,
                 const BoundingCylinder& cylinder, int threads) {
  const auto is_direct = [](const Hypothesis& x) {
    return x.key / kMaxLasers == static_cast<int>(PointView::kCenter);
  };
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.hypotheses == 0) continue;
      const Hypothesis* first = &hyp[p.first_hypothesis];
      if (p.hypotheses == 1) {
        p.chosen = 0;
        p.rule = Rule::kCylinder;
        continue;
      }
      int confirmed = 0, last_confirmed = -1;
      for (int h = 0; h < p.hypotheses; ++h) {
        if (first[h].confirmed) {
          ++confirmed;
          last_confirmed = h;
        }
      }
      if (confirmed == 1) {
        p.chosen = static_cast<int16_t>(last_confirmed);
        p.rule = Rule::kStereo;
        continue;
      }
      // The floor and the panels are surfaces too: such a hypothesis leaves the core no single
      // answer.
      int in_core = 0, last_in_core = -1;
      for (int h = 0; h < p.hypotheses; ++h) {
        if ((confirmed == 0 || first[h].confirmed) &&
            (first[h].Background() || cylinder.CoreContains(first[h].point))) {
          ++in_core;
          last_in_core = h;
        }
      }
      if (in_core != 1) continue;
      // The direct ray in a mirror's region meets the other lasers' planes in the air beside
      // whatever stands in front of the mirror, often inside the core: no proof while the
      // mirror's view has a hypothesis further out (a hand seen in the mirror).
      // And the other way round: the mirror's view meets a laser's plane inside the core, in
      // the air in front of the legs, while the truth is a hand in front of the mirror, outside
      // the core.
      if (p.region != 0 && std::any_of(first, first + p.hypotheses, [&](const Hypothesis& x) {
            return !x.Background() && is_direct(x) != is_direct(first[last_in_core]);
          }))
        continue;
      p.chosen = static_cast<int16_t>(last_in_core);
      p.rule = Rule::kCylinder;
    }
  });
}

// The surface the scan has seen so far, voxel by voxel (not spread): whether a mirror view's
// ray passed through it on the way to the point. The mannequin's upper camera sees the
// torso's back in a mirror where nothing was decided alone yet, and the same ray, on
// through the torso, meets another laser's plane beside the forearm, in the carved volume:
// without this the volume took laser k - 1 there for ~800 peaks, and the vote then dropped
// them as conflicts. The direct view is not walked: what the camera sees directly is
// mostly decided alone already, and walking it too, the lower camera's rays past the
// turned cuboid tripod's thin front leg to the leg behind it counted as hidden
// (cuboid3-yaw30: 438 -> 549 wrong points), with nothing gained on the mannequin.
class SeenSurface {
 public:
  SeenSurface(const BoundingCylinder& c, const Geometry& g)
      : voxels_(c, kOccupancyVoxelMm), mirrors_(g.mirrors) {}
  void Add(const Hypothesis& h) {
    if (!h.Background()) voxels_.Add(h.point, 1);
  }
  // Walks back from the point along its last ray segment, from clear of the point's own
  // surface to the mirror the segment came from. The surfaces at the peak's other
  // hypotheses (`others`, `count` of them, h among them) do not count: the ray runs through
  // those whatever it really met.
  bool Hides(const Hypothesis& h, const Hypothesis* others, int count) const {
    const int view = h.key / kMaxLasers;
    if (view == static_cast<int>(PointView::kCenter)) return false;
    // The last bounce: left and right-left end on mirror 0, right and left-right on 1.
    const bool left = view == static_cast<int>(PointView::kLeft) ||
                      view == static_cast<int>(PointView::kRightLeft);
    const Plane& mirror = mirrors_[left ? 0 : 1];
    const double approach = mirror.normal.dot(h.last_direction);
    if (approach <= 1e-9) return false;
    const double length = mirror.SignedDistance(h.point) / approach;
    constexpr double kClear2 = kOwnSurfaceMm * kOwnSurfaceMm;
    for (double s = kOwnSurfaceMm; s < length; s += kStepMm) {
      const Eigen::Vector3d at = h.point - s * h.last_direction;
      if (!voxels_.At(at)) continue;
      if (std::none_of(others, others + count, [&](const Hypothesis& o) {
            return &o != &h && (o.point - at).squaredNorm() < kClear2;
          }))
        return true;
    }
    return false;
  }

 private:
  // Clear of the point's own surface: at 40 mm a ray grazing it at 15 degrees has left its
  // voxels.
  static constexpr double kOwnSurfaceMm = 40.0;
  static constexpr double kStepMm = 5.0;
  NeighbourhoodBits<uint8_t> voxels_;
  std::array<Plane, 2> mirrors_;
};

// Peaks the cylinder left ambiguous with exactly one hypothesis in the carved volume that
// the ray reaches without passing through a seen surface first.
void DecideByVolume(std::vector<PeakState>* peaks, const Hypotheses& hyp,
                    const BoundingCylinder& cylinder, const Geometry& g, int threads) {
  NeighbourhoodBits<uint8_t> occupied(cylinder, kOccupancyVoxelMm);
  SeenSurface seen(cylinder, g);
  for (const PeakState& p : *peaks)
    if (p.rule == Rule::kCylinder || p.rule == Rule::kStereo) {
      occupied.Add(hyp[p.first_hypothesis + p.chosen].point, 1);
      seen.Add(hyp[p.first_hypothesis + p.chosen]);
    }
  occupied.Spread(threads);
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = (*peaks)[i];
      if (p.rule != Rule::kNone || p.hypotheses < 2) continue;
      int found = -1, count = 0;
      for (int h = 0; h < p.hypotheses; ++h) {
        const Hypothesis& x = hyp[p.first_hypothesis + h];
        if (occupied.At(x.point) && !seen.Hides(x, &hyp[p.first_hypothesis], p.hypotheses)) {
          found = h;
          ++count;
        }
      }
      if (count == 1) {
        p.chosen = static_cast<int16_t>(found);
        p.rule = Rule::kVolume;
      }
    }
  });
}

// A common hypothesis of two peaks whose points are within max_mm.
bool Consistent(const Hypotheses& hyp, const PeakState& a, const PeakState& b, double max_mm) {
  const double max2 = max_mm * max_mm;
  for (int i = 0; i < a.hypotheses; ++i) {
    const Hypothesis& ha = hyp[a.first_hypothesis + i];
    for (int j = 0; j < b.hypotheses; ++j) {
      const Hypothesis& hb = hyp[b.first_hypothesis + j];
      if (ha.key == hb.key && (ha.point - hb.point).squaredNorm() < max2) return true;
    }
  }
  return false;
}

int FindHypothesis(const Hypotheses& hyp, const PeakState& p, int key) {
  for (int i = 0; i < p.hypotheses; ++i) {
    if (hyp[p.first_hypothesis + i].key == key) return i;
  }
  return -1;
}

// The archive's peaks in frame order, each frame's sorted by column then row.
struct PeakTable {
  std::vector<PeakState> peaks;
  std::vector<uint32_t> frame_first;  // per archive frame, and one past the end
  // Per archive frame: the next frame of the same camera (or -1).
  std::vector<int32_t> next_frame;

  // Per archive frame and column u in [0, columns], the first peak at u or right of it.
  int columns = 1;
  std::vector<uint32_t> column_first;

  // The frame's peaks in column u: [first, last).
  std::pair<uint32_t, uint32_t> Column(uint32_t frame, int u) const {
    if (u < 0 || u >= columns) return {0, 0};
    const size_t at = static_cast<size_t>(frame) * (columns + 1) + u;
    return {column_first[at], column_first[at + 1]};
  }
};

PeakTable BuildTable(const ScanArchive& archive, const std::vector<bool>& use_frame, int threads) {
  PeakTable table;
  const size_t n = archive.frames.size();
  table.frame_first.assign(n + 1, 0);
  size_t total = 0;
  for (size_t f = 0; f < n; ++f) {
    table.frame_first[f] = static_cast<uint32_t>(total);
    if (use_frame[f]) total += archive.frames[f].peaks.size();
  }
  table.frame_first[n] = static_cast<uint32_t>(total);
  table.peaks.resize(total);
  for (size_t f = 0; f < n; ++f) {
    if (!use_frame[f]) continue;
    for (const Peak& p : archive.frames[f].peaks) table.columns = std::max(table.columns, p.u + 1);
  }
  const size_t stride = table.columns + 1;
  table.column_first.resize(n * stride);
  ParallelFor(n, threads, [&](size_t begin, size_t end) {
    for (size_t f = begin; f < end; ++f) {
      const auto first = table.peaks.begin() + table.frame_first[f];
      const auto last = table.peaks.begin() + table.frame_first[f + 1];
      if (use_frame[f]) {
        auto out = first;
        for (const Peak& p : archive.frames[f].peaks) {
          out->frame = static_cast<uint32_t>(f);
          out->u = p.u;
          out->v = p.v;
          out->score = p.score;
          ++out;
        }
        std::sort(first, last, [](const PeakState& a, const PeakState& b) {
          return a.u != b.u ? a.u < b.u : a.v < b.v;
        });
      }
      uint32_t i = table.frame_first[f];
      for (int u = 0; u <= table.columns; ++u) {
        while (i < table.frame_first[f + 1] && table.peaks[i].u < u) ++i;
        table.column_first[f * stride + u] = i;
      }
    }
  });
  // Frames of one camera in time order.
  table.next_frame.assign(n, -1);
  std::vector<uint32_t> order;
  for (size_t f = 0; f < n; ++f)
    if (use_frame[f]) order.push_back(static_cast<uint32_t>(f));
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    const FrameRecord& fa = archive.frames[a];
    const FrameRecord& fb = archive.frames[b];
    return fa.camera != fb.camera ? fa.camera < fb.camera : fa.timestamp_ns < fb.timestamp_ns;
  });
  for (size_t i = 0; i + 1 < order.size(); ++i) {
    if (archive.frames[order[i]].camera == archive.frames[order[i + 1]].camera)
      table.next_frame[order[i]] = static_cast<int32_t>(order[i + 1]);
  }
  return table;
}

// Each frame's hypotheses of one laser by the 2D cell of their point (the laser plane gives
// the height), so another camera's hypotheses near a point are a few binary searches away.
class HypothesisIndex {
 public:
  HypothesisIndex(const PeakTable& table, const Hypotheses& hyp) {
    const size_t frames = table.frame_first.size() - 1;
    first_.assign(frames * kMaxLasers + 1, 0);
    for (size_t f = 0; f < frames; ++f)
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        for (int h = 0; h < p.hypotheses; ++h)
          ++first_[f * kMaxLasers + hyp[p.first_hypothesis + h].key % kMaxLasers + 1];
      }
    for (size_t s = 1; s < first_.size(); ++s) first_[s] += first_[s - 1];
    entries_.resize(first_.back());
    std::vector<uint32_t> fill(first_.begin(), first_.end() - 1);
    for (size_t f = 0; f < frames; ++f)
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        for (int h = 0; h < p.hypotheses; ++h) {
          const uint32_t at = p.first_hypothesis + h;
          const Eigen::Vector3d& x = hyp[at].point;
          entries_[fill[f * kMaxLasers + hyp[at].key % kMaxLasers]++] = {Cell(x.x(), x.y()), at};
        }
      }
    for (size_t s = 0; s + 1 < first_.size(); ++s)
      std::sort(entries_.begin() + first_[s], entries_.begin() + first_[s + 1],
                [](const Entry& a, const Entry& b) { return a.cell < b.cell; });
  }

  // Whether the frame has a hypothesis of this laser within radius of the point.
  bool AnyNear(const Hypotheses& hyp, size_t frame, int laser, const Eigen::Vector3d& point,
               double radius) const {
    const auto begin = entries_.begin() + first_[frame * kMaxLasers + laser];
    const auto end = entries_.begin() + first_[frame * kMaxLasers + laser + 1];
    if (begin == end) return false;
    const double r2 = radius * radius;
    const int x0 = CellIndex(point.x() - radius), x1 = CellIndex(point.x() + radius);
    const int y0 = CellIndex(point.y() - radius), y1 = CellIndex(point.y() + radius);
    for (int x = x0; x <= x1; ++x) {
      // Cells of one x are consecutive in y.
      const uint32_t lo = Pack(x, y0), hi = Pack(x, y1);
      for (auto it = std::lower_bound(begin, end, lo,
                                      [](const Entry&e, uint32_t c) { return e.cell < c; });
           it != end && it->cell <= hi; ++it) {
        if ((hyp[it->hyp].point - point).squaredNorm() <= r2) return true;
      }
    }
    return false;
  }

 private:
  static constexpr double kCellMm = 8.0;
  struct Entry {
    uint32_t cell;
    uint32_t hyp;
  };
  static int CellIndex(double mm) { return static_cast<int>(std::floor(mm / kCellMm)) + 32768; }
  static uint32_t Pack(int x, int y) {
    return static_cast<uint32_t>(std::clamp(x, 0, 65535)) << 16 |
           static_cast<uint32_t>(std::clamp(y, 0, 65535));
  }
  static uint32_t Cell(double x, double y) { return Pack(CellIndex(x), CellIndex(y)); }
  std::vector<uint32_t> first_;  // per (frame, laser), and one past the end
  std::vector<Entry> entries_;
};

// Marks the hypotheses another camera confirms: at its frame nearest in time it has a
// hypothesis of the same laser at the same place, moved by the plane's travel between the
// two frames. A right hypothesis is the one surface point both cameras see lit; two wrong
// ones coincide only where their curves in a laser plane happen to cross.
void ConfirmByStereo(const ScanArchive& archive, const PeakTable& table,
                     const std::vector<std::array<Plane, kMaxLasers>>& planes, double max_mm,
                     int threads, Hypotheses* hyp) {
  const size_t frames = table.frame_first.size() - 1;
  // Per camera, its frames in time order and its frame period.
  size_t cameras = 0;
  for (size_t f = 0; f < frames; ++f)
    if (table.frame_first[f + 1] > table.frame_first[f])
      cameras = std::max<size_t>(cameras, archive.frames[f].camera + 1);
  if (cameras < 2) return;
  std::vector<std::vector<std::pair<int64_t, uint32_t>>> by_time(cameras);
  for (size_t f = 0; f < frames; ++f)
    if (table.frame_first[f + 1] > table.frame_first[f])
      by_time[archive.frames[f].camera].emplace_back(archive.frames[f].timestamp_ns, f);
  std::vector<int64_t> period(cameras, 0);
  for (size_t c = 0; c < cameras; ++c) {
    auto& list = by_time[c];
    std::sort(list.begin(), list.end());
    std::vector<int64_t> steps;
    for (size_t i = 1; i < list.size(); ++i) steps.push_back(list[i].first - list[i - 1].first);
    if (!steps.empty()) {
      std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
      period[c] = steps[steps.size() / 2];
    }
  }
  const HypothesisIndex index(table, *hyp);
  // Each frame marks only its own hypotheses and reads the others' points, which stay.
  ParallelFor(frames, threads, [&](size_t frames_begin, size_t frames_end) {
    std::vector<uint32_t> partners;
    for (size_t f = frames_begin; f < frames_end; ++f) {
      if (table.frame_first[f + 1] == table.frame_first[f]) continue;
      const FrameRecord& frame = archive.frames[f];
      partners.clear();
      for (size_t c = 0; c < cameras; ++c) {
        if (c == frame.camera || by_time[c].empty()) continue;
        const auto& list = by_time[c];
        const auto it = std::lower_bound(list.begin(), list.end(),
                                         std::make_pair(frame.timestamp_ns, uint32_t{0}));
        // The frames either side within three quarters of a period.
        for (auto near : {it, it == list.begin() ? list.end() : it - 1}) {
          if (near == list.end()) continue;
          if (4 * std::abs(near->first - frame.timestamp_ns) <= 3 * period[c])
            partners.push_back(near->second);
        }
      }
      if (partners.empty()) continue;
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        const PeakState& p = table.peaks[i];
        if (p.hypotheses < 2) continue;
        for (int h = 0; h < p.hypotheses; ++h) {
          Hypothesis& x = (*hyp)[p.first_hypothesis + h];
          const int laser = x.key % kMaxLasers;
          for (uint32_t g : partners) {
            const Plane& plane = planes[g][laser];
            if (std::abs(plane.normal.z()) < 0.5) continue;
            // Where the other frame's plane is above this point: the stripe has moved by that.
            const double z =
                -(plane.normal.x() * x.point.x() + plane.normal.y() * x.point.y() + plane.offset) /
                plane.normal.z();
            const Eigen::Vector3d moved(x.point.x(), x.point.y(), z);
            if (index.AnyNear(*hyp, g, laser, moved, max_mm + std::abs(z - x.point.z()))) {
              x.confirmed = true;
              break;
            }
          }
        }
      }
    }
  });
}

// Joins peaks that are neighbours in (column, frame) and agree on some hypothesis.
void LinkNeighbours(const PeakTable& table, const Hypotheses& hyp,
                    const ReconstructOptions& options, UnionFind* labels) {
  const size_t frames = table.frame_first.size() - 1;
  // Two neighbours decided with different keys are two surfaces that touch in the image (a
  // mirror's stripe beside the subject's stripe of another laser in front of the mirror):
  // joined, the larger one's vote would take the other's peaks.
  auto join = [&](uint32_t a, uint32_t b) {
    const PeakState& pa = table.peaks[a];
    const PeakState& pb = table.peaks[b];
    if (pa.chosen >= 0 && pb.chosen >= 0 &&
        hyp[pa.first_hypothesis + pa.chosen].key != hyp[pb.first_hypothesis + pb.chosen].key)
      return;
    labels->Join(a, b);
  };
  for (size_t f = 0; f < frames; ++f) {
    const uint32_t begin = table.frame_first[f], end = table.frame_first[f + 1];
    // Column neighbours: the run at u + 1 starts after the run at u.
    uint32_t next_col = begin;
    for (uint32_t i = begin; i < end; ++i) {
      const PeakState& p = table.peaks[i];
      if (p.hypotheses == 0) continue;
      while (next_col < end && table.peaks[next_col].u <= p.u) ++next_col;
      for (uint32_t j = next_col; j < end && table.peaks[j].u == p.u + 1; ++j) {
        const PeakState& q = table.peaks[j];
        if (q.hypotheses == 0 || std::abs(q.v - p.v) > options.label_max_row_step_px) continue;
        if (Consistent(hyp, p, q, kLinkColumnMm)) join(i, j);
      }
    }
    const int32_t g = table.next_frame[f];
    if (g < 0) continue;
    for (uint32_t i = begin; i < end;) {
      const uint16_t u = table.peaks[i].u;
      uint32_t run_end = i;
      while (run_end < end && table.peaks[run_end].u == u) ++run_end;
      const auto [lo, hi] = table.Column(static_cast<uint32_t>(g), u);
      for (uint32_t a = i; a < run_end; ++a) {
        const PeakState& p = table.peaks[a];
        if (p.hypotheses == 0) continue;
        for (uint32_t b = lo; b < hi; ++b) {
          const PeakState& q = table.peaks[b];
          if (q.hypotheses == 0 || std::abs(q.v - p.v) > options.label_max_frame_step_px) continue;
          if (Consistent(hyp, p, q, kLinkFrameMm)) join(a, b);
        }
      }
      i = run_end;
    }
  }
}

// Column counting: in one column of one view region, as many peaks as lasers are the
// lasers top (highest) to bottom. In a mirror's region an arm in front of the glass can add
// its stripe to the mirror's, and the count then takes the arm's peak for the lowest laser
// in the mirror (the mannequin's two wrong column-count points, 17 mm off); counting in the
// centre region only fixed them but left the cuboid's stripes that run on into a mirror's
// region without the support the vote needs there (CuboidThroughTheTrueCalibration...: 5,700
// fewer points), so it counts in every region.
void DecideByColumnCount(PeakTable* table, const Hypotheses& hyp, int laser_count, int threads) {
  if (laser_count < 2) return;
  const size_t frames = table->frame_first.size() - 1;
  // A frame decides only its own peaks.
  ParallelFor(frames, threads, [&](size_t frames_begin, size_t frames_end) {
    for (size_t f = frames_begin; f < frames_end; ++f) {
      const uint32_t begin = table->frame_first[f], end = table->frame_first[f + 1];
      for (uint32_t i = begin; i < end;) {
        uint32_t run_end = i;
        while (run_end < end && table->peaks[run_end].u == table->peaks[i].u) ++run_end;
        for (uint8_t region = 0; region < 3; ++region) {
          std::array<uint32_t, kMaxLasers> members{};
          int n = 0;
          for (uint32_t j = i; j < run_end; ++j) {
            const PeakState& p = table->peaks[j];
            if (p.region != region || p.hypotheses == 0 || p.panel) continue;
            if (n == laser_count) {
              n = laser_count + 1;
              break;
            }
            members[n++] = j;
          }
          if (n != laser_count) continue;
          // Rows ascend within a column: the first is the highest laser, and every row is
          // the same view (a mirror keeps up and down). A peak of the column decided already
          // with another laser or view, or rows whose lasers only other views have, say the
          // count is not the lasers: an arm in front of a mirror stands in for one of the
          // mirror's stripes.
          std::array<int, kMaxLasers> pick{};
          int view = -1;
          bool agrees = true;
          for (int r = 0; r < n && agrees; ++r) {
            const PeakState& p = table->peaks[members[r]];
            const int laser = laser_count - 1 - r;
            int count = 0;
            pick[r] = -1;
            for (int h = 0; h < p.hypotheses; ++h) {
              if (hyp[p.first_hypothesis + h].key % kMaxLasers == laser) {
                pick[r] = h;
                ++count;
              }
            }
            if (p.chosen >= 0) {
              pick[r] = p.chosen;
              count = 1;
            }
            if (count != 1) {
              pick[r] = -1;  // no single hypothesis of this laser: the row decides nothing
              continue;
            }
            const int key = hyp[p.first_hypothesis + pick[r]].key;
            if (key % kMaxLasers != laser || (view >= 0 && key / kMaxLasers != view))
              agrees = false;
            view = key / kMaxLasers;
          }
          if (!agrees) continue;
          for (int r = 0; r < n; ++r) {
            PeakState& p = table->peaks[members[r]];
            if (p.rule != Rule::kNone || pick[r] < 0) continue;
            p.chosen = static_cast<int16_t>(pick[r]);
            p.rule = Rule::kColumnCount;
          }
        }
        i = run_end;
      }
    }
  });
}

// Majority vote per label over the peaks decided alone; the winner decides the rest.
void DecideByLabelVote(PeakTable* table, const Hypotheses& hyp, UnionFind* labels,
                       const BoundingCylinder& cylinder, int threads, ReconstructSummary* summary) {
  const size_t n = table->peaks.size();
  NeighbourhoodBits<uint16_t> decided(cylinder, kKeyOccupancyVoxelMm);
  for (const PeakState& p : table->peaks) {
    if (p.chosen < 0) continue;
    const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
    decided.Add(h.point, static_cast<uint16_t>(1u << h.key));
  }
  decided.Spread(threads);
  std::vector<int32_t> label_of_root(n, -1);
  std::vector<std::array<uint32_t, kKeys>> votes;
  std::vector<int32_t> label(n, -1);
  for (uint32_t i = 0; i < n; ++i) {
    const PeakState& p = table->peaks[i];
    if (p.hypotheses == 0 || p.panel) continue;
    const uint32_t root = labels->Find(i);
    if (label_of_root[root] < 0) {
      label_of_root[root] = static_cast<int32_t>(votes.size());
      votes.push_back({});
    }
    label[i] = label_of_root[root];
    if (p.chosen >= 0) ++votes[label[i]][hyp[p.first_hypothesis + p.chosen].key];
  }
  std::vector<int> winner(votes.size(), -1);
  for (size_t l = 0; l < votes.size(); ++l) {
    const auto best = std::max_element(votes[l].begin(), votes[l].end());
    if (*best > 0) winner[l] = static_cast<int>(best - votes[l].begin());
  }
  // Each peak decided on its own from its label's winner, chunk by chunk.
  struct Counts {
    size_t ambiguous = 0, conflict = 0, unsupported = 0;
  };
  std::vector<Counts> counts(ChunkCount(n, threads));
  ForEachChunk(n, threads, [&](size_t chunk, size_t begin, size_t end) {
    Counts& count = counts[chunk];
    for (size_t i = begin; i < end; ++i) {
      PeakState& p = table->peaks[i];
      if (label[i] < 0) continue;
      const int key = winner[label[i]];
      if (key < 0) {
        ++count.ambiguous;
        p.chosen = -1;
        continue;
      }
      const int h = FindHypothesis(hyp, p, key);
      if (h < 0 || (p.chosen >= 0 && p.chosen != h)) {
        ++count.conflict;
        p.chosen = -1;
        p.rule = Rule::kNone;
        continue;
      }
      if (p.chosen < 0) {
        // Only the direct view in a mirror's region is at risk: there the direct ray's other
        // lasers' points lie in the air beside whatever stands in front of the mirror.
        if (p.region != 0 && key / kMaxLasers == static_cast<int>(PointView::kCenter) &&
            !(decided.At(hyp[p.first_hypothesis + h].point) >> key & 1u)) {
          ++count.unsupported;
          continue;
        }
        p.chosen = static_cast<int16_t>(h);
        p.rule = Rule::kLabelVote;
      }
    }
  });
  for (const Counts& count : counts) {
    summary->dropped_ambiguous += count.ambiguous;
    summary->dropped_conflict += count.conflict;
    summary->dropped_unsupported += count.unsupported;
  }
}

// Per camera and image column, what the decided peaks saw along their pixel's ray: the
// row and the path length, rows ascending. A pixel's ray meets one surface first, whatever
// laser lights it and whenever.
class SeenAlongRays {
 public:
  struct Seen {
    float v;
    float path_mm;
    uint8_t laser;
  };

  SeenAlongRays(const ScanArchive& archive, const PeakTable& table, const Hypotheses& hyp,
                size_t cameras) {
    width_ = table.columns;
    first_.assign(cameras * width_ + 1, 0);
    auto slot = [&](const PeakState& p) { return archive.frames[p.frame].camera * width_ + p.u; };
    for (const PeakState& p : table.peaks)
      if (p.chosen >= 0) ++first_[slot(p) + 1];
    for (size_t i = 1; i < first_.size(); ++i) first_[i] += first_[i - 1];
    seen_.resize(first_.back());
    std::vector<uint32_t> fill(first_.begin(), first_.end() - 1);
    for (const PeakState& p : table.peaks) {
      if (p.chosen < 0) continue;
      const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
      seen_[fill[slot(p)]++] = {p.v, h.path_mm, static_cast<uint8_t>(h.key % kMaxLasers)};
    }
    for (size_t i = 0; i + 1 < first_.size(); ++i)
      std::sort(seen_.begin() + first_[i], seen_.begin() + first_[i + 1],
                [](const Seen& a, const Seen& b) { return a.v < b.v; });
  }

  // Calls f for every peak seen in the camera's column u within rows of v.
  template <typename F>
  void ForEachNear(size_t camera, int u, double v, double rows, F f) const {
    if (u < 0 || u >= width_) return;
    const auto begin = seen_.begin() + first_[camera * width_ + u];
    const auto end = seen_.begin() + first_[camera * width_ + u + 1];
    const float lo = static_cast<float>(v - rows);
    for (auto it = std::lower_bound(begin, end, lo, [](const Seen&s, float x) { return s.v < x; });
         it != end && it->v <= v + rows; ++it)
      f(*it);
  }

 private:
  int width_ = 1;
  std::vector<uint32_t> first_;  // per (camera, column), and one past the end
  std::vector<Seen> seen_;
};

// Free space: a point is only where the rays through it saw nothing behind it. At its own
// pixel the other lasers light the same first surface, so their path lengths must agree
// with its own; and where another camera, or a mirror's view, looks through the point and
// sees further, it is not there, unless some view sees it. Wrong lasers and views that the
// vote carried along a whole label (an arm in front of a mirror taken for the torso in it, a
// laser taken for the next one consistently over many frames) fail one or the other. Both
// judge every point against the same set, before any is dropped.
void DropPointsSeenThrough(const Geometry& g, const ScanArchive& archive, const PeakTable& table,
                           const Hypotheses& hyp, const ReconstructOptions& options, int threads,
                           std::vector<PeakState>* peaks, size_t* dropped) {
  const SeenAlongRays seen(archive, table, hyp, g.cameras.size());
  const double rows = options.free_space_rows_px;
  const double tolerance_mm = options.free_space_mm;
  struct View {
    const Camera* camera;
    Eigen::Matrix3d cam_from_world_rotation;
    Eigen::Vector3d cam_from_world_translation;
    Eigen::Vector3d center;
  };
  std::vector<View> views;
  for (const CalibrationCamera* c : g.cameras) {
    if (!c) {
      views.push_back(
          {nullptr, Eigen::Matrix3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()});
      continue;
    }
    views.push_back({&c->camera, c->camera.cam_from_world.rotation.toRotationMatrix(),
                     c->camera.cam_from_world.translation, c->camera.CenterInWorld()});
  }
  std::vector<uint8_t> drop(peaks->size(), 0);
  ParallelFor(peaks->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const PeakState& p = (*peaks)[i];
      if (p.chosen < 0) continue;
      const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
      if (h.Background()) continue;
      const int laser = h.key % kMaxLasers;
      const size_t own_camera = archive.frames[p.frame].camera;
      size_t others = 0, agree = 0;
      seen.ForEachNear(own_camera, p.u, p.v, rows, [&](const SeenAlongRays::Seen& s) {
        if (s.laser == laser) return;
        ++others;
        if (std::abs(s.path_mm - h.path_mm) <= tolerance_mm * (1.0 + std::abs(s.v - p.v))) ++agree;
      });
      if (others > 0 && agree == 0) {
        drop[i] = 1;
        continue;
      }
      // Other lasers see it there. (A stereo confirmation is no such proof: two cameras'
      // phantoms in front of a mirror met within 3 mm, 250 mm off the body.)
      if (agree > 0) continue;
      size_t through = 0, seen_there = 0;
      const PointView own_view = static_cast<PointView>(h.key / kMaxLasers);
      for (size_t c = 0; c < views.size() && seen_there == 0; ++c) {
        if (!views[c].camera) continue;
        for (int w = 0; w < 3 && seen_there == 0; ++w) {
          if (c == own_camera && w == static_cast<int>(own_view)) continue;
          if (w > 0 && g.mirror_rectangles.empty()) continue;
          const Eigen::Vector3d point = w == 0 ? h.point : g.mirrors[w - 1].ReflectPoint(h.point);
          const Eigen::Vector3d towards = point - views[c].center;
          const double path = towards.norm();
          // A mirror's view sees the point only through its glass.
          if (w > 0) {
            const auto t =
                g.mirror_rectangles[w - 1].Intersect(Ray3d{views[c].center, towards / path});
            if (!t || *t > path) continue;
          }
          const auto pixel = views[c].camera->intrinsics.Project(
              views[c].cam_from_world_rotation * point + views[c].cam_from_world_translation);
          if (!pixel || !views[c].camera->intrinsics.InImage(*pixel)) continue;
          seen.ForEachNear(c, static_cast<int>(std::lround(pixel->x())), pixel->y(), rows,
                           [&](const SeenAlongRays::Seen& s) {
                             const double tolerance =
                                 tolerance_mm * (1.0 + std::abs(s.v - pixel->y()));
                             if (std::abs(s.path_mm - path) <= tolerance) {
                               ++seen_there;
                             } else if (s.path_mm > path + tolerance) {
                               ++through;
                             }
                           });
        }
      }
      if (seen_there == 0 && through >= 2) drop[i] = 1;
    }
  });
  for (size_t i = 0; i < drop.size(); ++i) {
    if (!drop[i]) continue;
    (*peaks)[i].chosen = -1;
    ++*dropped;
  }
}

// Output points with their place in the (column, frame) grid.
struct GridPoint {
  uint32_t peak = 0;
  Eigen::Vector3d point;
  Eigen::Vector3d last_direction;
  float sin_angle = 0;
  uint8_t key = 0;
  bool keep = true;
  // Flagged by the outlier test and left for the surface check to judge; never anyone's
  // neighbour.
  bool suspect = false;
};

class Grid {
 public:
  Grid(const PeakTable& table, const Hypotheses& hyp, int threads) : table_(table) {
    point_of_peak_.assign(table.peaks.size(), -1);
    int32_t count = 0;
    for (uint32_t i = 0; i < table.peaks.size(); ++i)
      if (table.peaks[i].chosen >= 0) point_of_peak_[i] = count++;
    points.resize(count);
    ParallelFor(table.peaks.size(), threads, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        if (point_of_peak_[i] < 0) continue;
        const PeakState& p = table.peaks[i];
        const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
        points[point_of_peak_[i]] = {
            static_cast<uint32_t>(i), h.point, h.last_direction, h.sin_angle, h.key, true, false};
      }
    });
    previous_frame_.assign(table.next_frame.size(), -1);
    for (size_t f = 0; f < table.next_frame.size(); ++f)
      if (table.next_frame[f] >= 0) previous_frame_[table.next_frame[f]] = static_cast<int32_t>(f);
  }

  // Finds every point's neighbours once: the point of the same (view, laser) at column
  // u + du in the frame df away whose row is nearest, within row_step (same frame) or
  // frame_step (another frame).
  void Link(double row_step, double frame_step, int threads) {
    neighbours_.assign(points.size(), {});
    ParallelFor(points.size(), threads, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        for (int df = -1; df <= 1; ++df)
          for (int du = -1; du <= 1; ++du)
            neighbours_[i][Direction(du, df)] =
                du == 0 && df == 0 ? -1
                                   : Search(points[i], du, df, df == 0 ? row_step : frame_step);
      }
    });
  }

  // That neighbour while it is kept and not suspect; -1 otherwise.
  int32_t Neighbour(const GridPoint& gp, int du, int df) const {
    const int32_t q = neighbours_[&gp - points.data()][Direction(du, df)];
    return q >= 0 && points[q].keep && !points[q].suspect ? q : -1;
  }

  std::vector<GridPoint> points;

 private:
  static int Direction(int du, int df) { return (df + 1) * 3 + du + 1; }

  int32_t Search(const GridPoint& gp, int du, int df, double max_dv) const {
    const PeakState& p = table_.peaks[gp.peak];
    int32_t frame = static_cast<int32_t>(p.frame);
    if (df > 0) frame = table_.next_frame[frame];
    if (df < 0) frame = previous_frame_[frame];
    if (frame < 0) return -1;
    const auto [lo, hi] = table_.Column(static_cast<uint32_t>(frame), p.u + du);
    int32_t best = -1;
    double best_dv = max_dv;
    for (uint32_t j = lo; j < hi; ++j) {
      const int32_t q = point_of_peak_[j];
      if (q < 0 || points[q].key != gp.key) continue;
      const double dv = std::abs(table_.peaks[j].v - p.v);
      if (dv <= best_dv) {
        best_dv = dv;
        best = q;
      }
    }
    return best;
  }

  const PeakTable& table_;
  std::vector<int32_t> point_of_peak_;
  std::vector<int32_t> previous_frame_;
  std::vector<std::array<int32_t, 9>> neighbours_;
};

// How many kept columns follow this point in direction du before the stripe ends.
int RunLength(const Grid& grid, const GridPoint& gp, int du, int limit) {
  int n = 0;
  const GridPoint* at = &gp;
  while (n < limit) {
    const int32_t q = grid.Neighbour(*at, du, 0);
    if (q < 0) break;
    at = &grid.points[q];
    ++n;
  }
  return n;
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const auto mid = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// ReconstructOptions::surface_check, for the weak points and the outlier test's suspects
// (`suspect`, one flag per point). The confident points that are not suspect are indexed in
// a grid of cells as large as the radius (counting sort), so a point's neighbours are in its
// 27 cells.
struct SurfaceDrops {
  size_t weak = 0, suspect = 0;
};
SurfaceDrops DropOffSurface(const ReconstructOptions& options, int threads,
                            const std::vector<uint8_t>& suspect, std::vector<CloudPoint>* points) {
  const double radius = options.surface_check_radius_mm;
  const float threshold = static_cast<float>(options.surface_check_confidence);
  const VoxelBox box(options.cylinder, radius);
  // Each confident point's cell; the points' places then by cell, side by side in memory.
  constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> cell_of(points->size(), kNone);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      if (cp.confidence < threshold || suspect[i]) continue;
      if (const auto cell = box.Index(cp.point_in_world.cast<double>()))
        cell_of[i] = static_cast<uint32_t>(*cell);
    }
  });
  std::vector<uint32_t> start(box.Voxels() + 1, 0);
  for (const uint32_t cell : cell_of)
    if (cell != kNone) ++start[cell + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  std::vector<Eigen::Vector3f> by_cell(start[box.Voxels()]);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < points->size(); ++i)
      if (cell_of[i] != kNone) by_cell[fill[cell_of[i]]++] = (*points)[i].point_in_world;
  }
  constexpr int kMinNeighbours = 6;
  const double radius2 = radius * radius;
  std::vector<uint8_t> drop(points->size(), 0);
  ParallelFor(points->size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const CloudPoint& cp = (*points)[i];
      if (cp.confidence >= threshold && !suspect[i]) continue;
      const Eigen::Vector3d at = cp.point_in_world.cast<double>();
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
      int n = 0;
      box.ForNeighbourhood(at, [&](size_t cell) {
        for (uint32_t k = start[cell]; k < start[cell + 1]; ++k) {
          const Eigen::Vector3d q = by_cell[k].cast<double>() - at;
          if (q.squaredNorm() > radius2) continue;
          sum += q;
          outer += q * q.transpose();
          ++n;
        }
      });
      // A suspect needs the surface's word: isolated phantoms have none.
      if (n < kMinNeighbours) {
        drop[i] =
            suspect[i] || cp.rule == DecidedBy::kColumnCount || cp.rule == DecidedBy::kLabelVote;
        continue;
      }
      const Eigen::Vector3d mean = sum / n;
      const Eigen::Matrix3d covariance = outer / n - mean * mean.transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
      const double rms = std::sqrt(std::max(0.0, solver.eigenvalues()(0)));
      const double off = std::abs(solver.eigenvectors().col(0).dot(-mean));
      // A suspect is already off its neighbours: where the plane says nothing (an edge, a
      // fold) it is not given the benefit of the doubt that a weak point gets.
      drop[i] = suspect[i] ? off > options.surface_check_outlier_mm
                           : off > options.surface_check_max_mm && off > 3.0 * rms;
    }
  });
  SurfaceDrops drops;
  size_t kept = 0;
  for (size_t i = 0; i < points->size(); ++i) {
    if (!drop[i])
      (*points)[kept++] = (*points)[i];
    else
      ++(suspect[i] ? drops.suspect : drops.weak);
  }
  points->resize(kept);
  return drops;
}

}  // namespace

const char* PointViewName(PointView view) {
  switch (view) {
    case PointView::kCenter:
      return "center";
    case PointView::kLeft:
      return "left";
    case PointView::kRight:
      return "right";
    case PointView::kLeftRight:
      return "left-right";
    case PointView::kRightLeft:
      return "right-left";
  }
  return "?";
}

const char* DecidedByName(DecidedBy rule) {
  switch (rule) {
    case DecidedBy::kCylinder:
      return "cylinder";
    case DecidedBy::kVolume:
      return "volume";
    case DecidedBy::kColumnCount:
      return "column_count";
    case DecidedBy::kLabelVote:
      return "label_vote";
    case DecidedBy::kStereo:
      return "stereo";
  }
  return "?";
}

bool BoundingCylinder::Contains(const Eigen::Vector3d& point) const {
  if (point.z() < bottom_mm || point.z() > top_mm) return false;
  return (point.head<2>() - center_mm).squaredNorm() <= radius_mm * radius_mm;
}

bool BoundingCylinder::OnFloor(const Eigen::Vector3d& point) const {
  if (point.z() >= bottom_mm || point.z() < -std::max(bottom_mm, 20.0)) return false;
  return (point.head<2>() - center_mm).squaredNorm() <= radius_mm * radius_mm;
}

bool BoundingCylinder::CoreContains(const Eigen::Vector3d& point) const {
  if (point.z() < bottom_mm || point.z() > top_mm) return false;
  const double r = std::min(core_radius_mm, radius_mm);
  return (point.head<2>() - center_mm).squaredNorm() <= r * r;
}

BoundingCylinder BoundingCylinder::FromBoard(const std::filesystem::path& board_json) {
  const nlohmann::json json = JsonReader::ParseFile(board_json);
  const JsonReader root(json, board_json.string());
  BoundingCylinder c;
  if (!root.Has("reconstruction")) return c;
  const JsonReader r = root.Object("reconstruction");
  r.AllowOnly({"bounding_cylinder"});
  if (!r.Has("bounding_cylinder")) return c;
  const JsonReader b = r.Object("bounding_cylinder");
  b.AllowOnly({"radius_mm", "core_radius_mm", "bottom_mm", "top_mm", "center_mm"});
  c.radius_mm = b.Number("radius_mm", c.radius_mm, 1.0, 1e5);
  c.core_radius_mm = b.Number("core_radius_mm", std::min(c.core_radius_mm, c.radius_mm), 1.0, 1e5);
  if (c.core_radius_mm > c.radius_mm) b.Fail("core_radius_mm", "must not exceed radius_mm");
  c.bottom_mm = b.Number("bottom_mm", c.bottom_mm, -1e5, 1e5);
  c.top_mm = b.Number("top_mm", c.top_mm, -1e5, 1e5);
  if (c.top_mm <= c.bottom_mm) b.Fail("top_mm", "must be above bottom_mm");
  const std::vector<double> center = b.Numbers("center_mm", 2, std::vector<double>{0.0, 0.0});
  c.center_mm = {center[0], center[1]};
  return c;
}

Reconstruction Reconstruct(const ScanArchive& archive, const Calibration& calibration,
                           const ReconstructOptions& options) {
  Reconstruction result;
  ReconstructSummary& summary = result.summary;
  Stopwatch stopwatch(&summary);
  const int threads = ResolveThreads(options.threads);
  auto progress = [&](const char* stage, double fraction) {
    if (options.progress) options.progress(stage, fraction);
  };
  summary.archive_message = archive.report.message;
  summary.archive_complete = archive.report.complete;
  if (archive.header.is_null())
    throw ReconstructError("no readable header (" + archive.report.message + ")");
  if (!archive.report.complete)
    summary.warnings.push_back("incomplete archive, using what was recovered: " +
                               archive.report.message);
  if (calibration.mirrors.size() != 2)
    throw ReconstructError("the calibration needs exactly two mirrors");
  CheckCalibration(archive, calibration, options, &summary);

  Geometry g;
  g.cameras = CamerasOf(archive, calibration);
  g.mirror_views = MirrorViewsOf(g.cameras, calibration);
  g.mirror_regions.resize(g.cameras.size());
  for (size_t c = 0; c < g.cameras.size(); ++c)
    if (g.cameras[c])
      for (int m = 0; m < 2; ++m)
        g.mirror_regions[c][m] =
            RegionColumns(*g.mirror_views[c][m], g.cameras[c]->camera.intrinsics.width);
  for (int m = 0; m < 2; ++m) g.mirrors[m] = calibration.mirrors[m].plane;
  if (std::all_of(calibration.mirrors.begin(), calibration.mirrors.end(),
                  [](const CalibrationMirror& m) { return m.corners_mm.size() == 4; })) {
    for (const CalibrationMirror& m : calibration.mirrors) {
      g.mirror_rectangles.push_back(MirrorRectangle(
          m.name, m.plane, {m.corners_mm[0], m.corners_mm[1], m.corners_mm[2], m.corners_mm[3]}));
    }
    g.panels =
        LaserCabinetFromCalibration(calibration, "calibration", options.panel_margin_mm).panels;
  } else {
    summary.warnings.push_back(
        "the calibration has no mirror corners: rays through both mirrors are not followed");
  }

  std::vector<bool> use_frame(archive.frames.size());
  for (size_t f = 0; f < archive.frames.size(); ++f) {
    use_frame[f] = archive.frames[f].lasers_on && !archive.frames[f].peaks.empty();
    if (use_frame[f]) {
      ++summary.frames;
      summary.peaks += archive.frames[f].peaks.size();
    }
  }
  if (summary.peaks == 0) {
    throw ReconstructError(archive.frames.empty()
                               ? "the archive holds no frames (" + archive.report.message + ")"
                               : "no frame with the lasers on has any peak");
  }
  PeakTable table = BuildTable(archive, use_frame, threads);
  stopwatch.Lap("read");
  progress("rays", 0.0);
  // Each peak undistorted and back-projected once, for the laser fit and the hypotheses.
  std::vector<std::optional<Ray3d>> rays(table.peaks.size());
  std::vector<std::optional<CameraRays>> camera_rays(g.cameras.size());
  for (size_t c = 0; c < g.cameras.size(); ++c)
    if (g.cameras[c]) camera_rays[c] = g.cameras[c]->camera.RaysThroughPixels();
  ParallelFor(archive.frames.size(), threads, [&](size_t begin, size_t end) {
    for (size_t f = begin; f < end; ++f) {
      if (!use_frame[f]) continue;
      const CameraRays& camera = *camera_rays[archive.frames[f].camera];
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i)
        rays[i] = camera.Through({table.peaks[i].u, table.peaks[i].v});
    }
  });
  stopwatch.Lap("rays");
  progress("laser heights", 0.0);

  const LaserPlanes planes = FitLaserPlanes(archive, calibration, g.cameras, options, &table.peaks,
                                            table.frame_first, rays, threads, &summary);
  stopwatch.Lap("laser heights");

  progress("triangulation", 0.0);
  // Hypotheses per peak; each chunk of frames in its own stretch of the store. A peak has at
  // most a surface and a panel hypothesis per laser on each of its ray's three segments.
  const size_t frame_count = archive.frames.size();
  const size_t most_per_peak = 3 * 2 * static_cast<size_t>(planes.count);
  if (table.peaks.size() * most_per_peak >= std::numeric_limits<uint32_t>::max())
    throw ReconstructError(
        Format("%zu peaks are more than one reconstruction can take", table.peaks.size()));
  Hypotheses hyp(table.peaks.size() * most_per_peak);
  struct Counts {
    size_t panel = 0, no_ray = 0, outside = 0;
  };
  std::vector<Counts> counts(ChunkCount(frame_count, threads));
  ForEachChunk(frame_count, threads, [&](size_t c, size_t begin, size_t end) {
    Hypotheses::Writer out{&hyp, static_cast<uint32_t>(table.frame_first[begin] * most_per_peak),
                           static_cast<uint32_t>(table.frame_first[end] * most_per_peak)};
    Counts& count = counts[c];
    for (size_t f = begin; f < end; ++f) {
      if (!use_frame[f]) continue;
      for (uint32_t i = table.frame_first[f]; i < table.frame_first[f + 1]; ++i) {
        PeakState& p = table.peaks[i];
        p.first_hypothesis = out.size();
        if (p.panel) {
          ++count.panel;
          continue;
        }
        if (!planes.valid[f]) {
          ++count.no_ray;
          continue;
        }
        Hypothesize(g, archive.frames[f], planes.per_frame[f], planes.count, options.cylinder,
                    options.mirror_clearance_mm, rays[i], &p, &out);
        if (p.no_ray) {
          ++count.no_ray;
        } else if (p.hypotheses == 0) {
          ++count.outside;
        }
      }
    }
  });
  for (const Counts& count : counts) {
    summary.dropped_panel += count.panel;
    summary.dropped_no_ray += count.no_ray;
    summary.dropped_outside += count.outside;
  }
  stopwatch.Lap("triangulation");
  progress("correspondence", 0.0);

  if (options.stereo) {
    ConfirmByStereo(archive, table, planes.per_frame, options.stereo_max_mm, threads, &hyp);
    stopwatch.Lap("stereo");
  }
  DecideAlone(&table.peaks, hyp, options.cylinder, threads);
  DecideByVolume(&table.peaks, hyp, options.cylinder, g, threads);
  DecideByColumnCount(&table, hyp, planes.count, threads);
  UnionFind labels(table.peaks.size());
  LinkNeighbours(table, hyp, options, &labels);
  DecideByLabelVote(&table, hyp, &labels, options.cylinder, threads, &summary);
  for (const PeakState& p : table.peaks) {
    if (p.chosen < 0) continue;
    if (p.rule == Rule::kStereo) ++summary.decided_by_stereo;
    if (p.rule == Rule::kCylinder) ++summary.decided_by_cylinder;
    if (p.rule == Rule::kVolume) ++summary.decided_by_volume;
    if (p.rule == Rule::kColumnCount) ++summary.decided_by_column_count;
    if (p.rule == Rule::kLabelVote) ++summary.decided_by_label_vote;
  }
  stopwatch.Lap("correspondence");
  if (options.free_space_check) {
    progress("free space", 0.0);
    DropPointsSeenThrough(g, archive, table, hyp, options, threads, &table.peaks,
                          &summary.dropped_seen_through);
    stopwatch.Lap("free space");
  }
  progress("filtering", 0.0);

  for (PeakState& p : table.peaks) {
    if (p.chosen < 0) continue;
    const Hypothesis& h = hyp[p.first_hypothesis + p.chosen];
    if (h.floor) ++summary.dropped_floor;
    if (h.panel) ++summary.dropped_panel;
    if (h.Background()) p.chosen = -1;
  }
  Grid grid(table, hyp, threads);
  grid.Link(options.label_max_row_step_px, options.label_max_frame_step_px, threads);
  const double min_sin = std::sin(options.min_ray_plane_angle_deg * kDegToRad);
  for (GridPoint& gp : grid.points) {
    if (gp.sin_angle < min_sin) {
      gp.keep = false;
      ++summary.dropped_flat_angle;
    }
  }
  // Where several cameras see the same surface, the one meeting the laser planes more
  // squarely: depth error grows as 1 / tan(angle).
  if (options.prefer_camera_ratio > 0 && g.cameras.size() > 1) {
    AngleGrid angles(options.cylinder, g.cameras.size());
    for (const GridPoint& gp : grid.points)
      if (gp.keep)
        angles.Add(archive.frames[table.peaks[gp.peak].frame].camera, gp.point, gp.sin_angle);
    for (GridPoint& gp : grid.points) {
      if (!gp.keep) continue;
      const size_t camera = archive.frames[table.peaks[gp.peak].frame].camera;
      if (angles.BestOther(camera, gp.point) > options.prefer_camera_ratio * gp.sin_angle) {
        gp.keep = false;
        ++summary.dropped_other_camera;
      }
    }
  }
  // Stripe ends, decided on the whole stripe before any of it is dropped.
  std::vector<int> end_distance(grid.points.size(), 0);
  const int end_limit = std::max(1, options.stripe_end_columns) + 2;
  ParallelFor(grid.points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid.points[i];
      if (!gp.keep) continue;
      end_distance[i] =
          std::min(RunLength(grid, gp, -1, end_limit), RunLength(grid, gp, +1, end_limit));
    }
  });
  if (options.drop_stripe_ends) {
    for (size_t i = 0; i < grid.points.size(); ++i) {
      if (grid.points[i].keep && end_distance[i] < options.stripe_end_columns) {
        grid.points[i].keep = false;
        ++summary.dropped_stripe_end;
      }
    }
  }
  // Outliers: the second difference along the column and frame directions.
  if (options.remove_outliers) {
    std::vector<double> residual(grid.points.size(), -1.0);
    ParallelFor(grid.points.size(), threads, [&](size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const GridPoint& gp = grid.points[i];
        if (!gp.keep) continue;
        double best = std::numeric_limits<double>::infinity();
        bool isolated = true;
        for (const auto& [du, df] : {std::pair{1, 0}, std::pair{0, 1}}) {
          const int32_t a = grid.Neighbour(gp, du, df);
          const int32_t b = grid.Neighbour(gp, -du, -df);
          if (a >= 0 || b >= 0) isolated = false;
          if (a < 0 || b < 0) continue;
          // Less a share of the chord: a curved surface sampled coarsely (successive frames far
          // apart where the plane grazes it) bends away from the chord's midpoint by chord² / 8R.
          const double chord = (grid.points[a].point - grid.points[b].point).norm();
          const double off =
              (gp.point - 0.5 * (grid.points[a].point + grid.points[b].point)).norm();
          best = std::min(best, std::max(0.0, off - options.outlier_chord_share * chord));
        }
        if (isolated) {
          residual[i] = std::numeric_limits<double>::infinity();
        } else if (std::isfinite(best)) {
          residual[i] = best;
        }
      }
    });
    std::vector<double> all;
    for (const double r : residual)
      if (r >= 0 && std::isfinite(r)) all.push_back(r);
    // Gross errors only: the surface's own bends (edges, folds) stay.
    const double limit =
        std::max(options.outlier_min_mm, options.outlier_sigmas * 1.4826 * Median(all));
    // With the surface check, a flagged point stays a suspect until the confident points
    // around it have had their say: 1,711 of the mannequin's 2,139 flagged points, most of
    // them stripe ends, lie within 0.5 mm of its surface (docs/reconstruction.md).
    for (size_t i = 0; i < grid.points.size(); ++i) {
      if (residual[i] <= limit) continue;
      if (options.surface_check) {
        grid.points[i].suspect = true;
      } else {
        grid.points[i].keep = false;
        ++summary.dropped_outlier;
      }
    }
  }
  if (options.clip_to_cylinder) {
    for (GridPoint& gp : grid.points) {
      if (gp.keep && !options.cylinder.Contains(gp.point)) {
        gp.keep = false;
        ++summary.dropped_outside;
      }
    }
  }
  // The paper's 3×3 average in (column, frame), within one surface. Neighbours come in
  // opposite pairs only, so the average stays centred on the point: one-sided at a stripe's
  // end or the first frame of a surface it would pull the point along the surface (up to
  // half a frame's slide travel off its laser plane) and, on a curved one, off it.
  std::vector<Eigen::Vector3d> smoothed(grid.points.size());
  auto usable = [&](const GridPoint& gp, int32_t q) {
    return q >= 0 && (grid.points[q].point - gp.point).norm() <= kSmoothMaxMm;
  };
  ParallelFor(grid.points.size(), threads, [&](size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid.points[i];
      smoothed[i] = gp.point;
      if (!gp.keep || gp.suspect || !options.smooth_3x3) continue;
      Eigen::Vector3d sum = gp.point;
      int n = 1;
      for (const auto& [du, df] :
           {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
        const int32_t a = grid.Neighbour(gp, du, df);
        const int32_t b = grid.Neighbour(gp, -du, -df);
        if (!usable(gp, a) || !usable(gp, b)) continue;
        sum += grid.points[a].point + grid.points[b].point;
        n += 2;
      }
      smoothed[i] = sum / n;
    }
  });
  stopwatch.Lap("filtering");
  progress("normals", 0.0);

  // Normals from the grid: the column and the frame direction span the surface.
  PointCloud& cloud = result.cloud;
  summary.points_per_camera.assign(g.cameras.size(), 0);
  summary.points_per_view.assign(kViews, 0);
  summary.points_per_laser.assign(planes.count, 0);
  // Each chunk of grid points into its own list, joined in order.
  struct CloudChunk {
    std::vector<CloudPoint> points;
    std::vector<uint8_t> suspect;
    size_t low_confidence = 0;
  };
  std::vector<CloudChunk> cloud_chunks(ChunkCount(grid.points.size(), threads));
  ForEachChunk(grid.points.size(), threads, [&](size_t chunk, size_t begin, size_t end) {
    CloudChunk& out = cloud_chunks[chunk];
    for (size_t i = begin; i < end; ++i) {
      const GridPoint& gp = grid.points[i];
      if (!gp.keep) continue;
      auto tangent = [&](int du, int df) -> std::optional<Eigen::Vector3d> {
        const int32_t a = grid.Neighbour(gp, du, df);
        const int32_t b = grid.Neighbour(gp, -du, -df);
        if (a < 0 && b < 0) return std::nullopt;
        const Eigen::Vector3d pa = a >= 0 ? smoothed[a] : smoothed[i];
        const Eigen::Vector3d pb = b >= 0 ? smoothed[b] : smoothed[i];
        return pa - pb;
      };
      const auto along_column = tangent(1, 0);
      const auto along_frame = tangent(0, 1);
      Eigen::Vector3d normal = -gp.last_direction;
      if (along_column && along_frame) {
        const Eigen::Vector3d n = along_column->cross(*along_frame);
        if (n.norm() > 1e-9) normal = n.normalized();
      } else if (along_column) {
        // Only the stripe's direction: the normal closest to the ray that is orthogonal to it.
        const Eigen::Vector3d t = along_column->normalized();
        const Eigen::Vector3d n = -gp.last_direction - t.dot(-gp.last_direction) * t;
        if (n.norm() > 1e-9) normal = n.normalized();
      }
      if (normal.dot(gp.last_direction) > 0) normal = -normal;

      const PeakState& p = table.peaks[gp.peak];
      const FrameRecord& frame = archive.frames[p.frame];
      CloudPoint cp;
      cp.point_in_world = smoothed[i].cast<float>();
      cp.normal = normal.cast<float>();
      cp.camera = frame.camera;
      cp.view = static_cast<PointView>(gp.key / kMaxLasers);
      cp.laser = static_cast<uint8_t>(gp.key % kMaxLasers);
      cp.frame = frame.sequence;
      cp.u = p.u;
      cp.v = p.v;
      cp.rule = p.rule == Rule::kVolume        ? DecidedBy::kVolume
                : p.rule == Rule::kColumnCount ? DecidedBy::kColumnCount
                : p.rule == Rule::kLabelVote   ? DecidedBy::kLabelVote
                : p.rule == Rule::kStereo      ? DecidedBy::kStereo
                                               : DecidedBy::kCylinder;
      // Peak score, how squarely the ray meets the plane, how far from the stripe's end.
      const double angle_factor = std::min(1.0, gp.sin_angle / std::sin(30.0 * kDegToRad));
      const double end_factor =
          std::min(1.0, (end_distance[i] + 1.0) / (options.stripe_end_columns + 2.0));
      cp.confidence = static_cast<float>(std::clamp(p.score * angle_factor * end_factor, 0.0, 1.0));
      if (cp.confidence < options.min_confidence) {
        ++out.low_confidence;
        continue;
      }
      out.points.push_back(cp);
      out.suspect.push_back(gp.suspect);
    }
  });
  std::vector<uint8_t> suspect;
  for (CloudChunk& chunk : cloud_chunks) {
    cloud.points.insert(cloud.points.end(), chunk.points.begin(), chunk.points.end());
    suspect.insert(suspect.end(), chunk.suspect.begin(), chunk.suspect.end());
    summary.dropped_low_confidence += chunk.low_confidence;
  }
  cloud_chunks.clear();
  stopwatch.Lap("normals");
  if (options.surface_check) {
    const SurfaceDrops drops = DropOffSurface(options, threads, suspect, &cloud.points);
    summary.dropped_off_surface = drops.weak;
    summary.dropped_outlier += drops.suspect;
    stopwatch.Lap("surface check");
  }
  for (const CloudPoint& cp : cloud.points) {
    ++summary.points_per_camera[cp.camera];
    ++summary.points_per_view[static_cast<int>(cp.view)];
    ++summary.points_per_laser[cp.laser];
    if (cp.view == PointView::kLeftRight || cp.view == PointView::kRightLeft)
      ++summary.double_bounce;
  }
  if (options.icp) {
    progress("icp", 0.0);
    summary.icp = RefineViews(&cloud);
    stopwatch.Lap("icp");
  }
  summary.points = cloud.points.size();
  progress("done", 1.0);
  return result;
}

nlohmann::json SummaryJson(const ReconstructSummary& s) {
  nlohmann::json per_view = nlohmann::json::object();
  for (size_t v = 0; v < s.points_per_view.size(); ++v)
    per_view[PointViewName(static_cast<PointView>(v))] = s.points_per_view[v];
  nlohmann::json timings = nlohmann::json::object();
  double total = 0;
  for (const auto& [stage, seconds] : s.timings_s) {
    timings[stage] = seconds;
    total += seconds;
  }
  timings["total"] = total;
  const LaserHeightSummary& l = s.laser_height;
  nlohmann::json icp = {{"ran", s.icp.ran}, {"steps", nlohmann::json::array()}};
  for (const IcpSummary::Step& step : s.icp.steps) {
    icp["steps"].push_back({{"what", step.what},
                            {"rmse_before_mm", step.rmse_before_mm},
                            {"rmse_after_mm", step.rmse_after_mm},
                            {"rotation_deg", step.rotation_deg},
                            {"translation_mm", step.translation_mm},
                            {"applied", step.applied}});
  }
  return {{"archive", {{"complete", s.archive_complete}, {"message", s.archive_message}}},
          {"frames", s.frames},
          {"peaks", s.peaks},
          {"points", s.points},
          {"points_per_camera", s.points_per_camera},
          {"points_per_view", per_view},
          {"points_per_laser", s.points_per_laser},
          {"decided",
           {{"stereo", s.decided_by_stereo},
            {"cylinder", s.decided_by_cylinder},
            {"volume", s.decided_by_volume},
            {"column_count", s.decided_by_column_count},
            {"label_vote", s.decided_by_label_vote}}},
          {"dropped",
           {{"panel", s.dropped_panel},
            {"no_ray", s.dropped_no_ray},
            {"outside_volume", s.dropped_outside},
            {"floor", s.dropped_floor},
            {"ambiguous", s.dropped_ambiguous},
            {"conflict", s.dropped_conflict},
            {"unsupported", s.dropped_unsupported},
            {"seen_through", s.dropped_seen_through},
            {"flat_angle", s.dropped_flat_angle},
            {"other_camera", s.dropped_other_camera},
            {"stripe_end", s.dropped_stripe_end},
            {"low_confidence", s.dropped_low_confidence},
            {"off_surface", s.dropped_off_surface},
            {"outlier", s.dropped_outlier}}},
          {"double_bounce", s.double_bounce},
          {"laser_height",
           {{"source", l.source},
            {"reason", l.reason},
            {"speed_mm_s", l.speed_mm_s},
            {"height_at_t0_mm", l.height_at_t0_mm},
            {"offsets_mm", l.offsets_mm},
            {"normal", {l.normal.x(), l.normal.y(), l.normal.z()}},
            {"panel_residual_rms_mm", l.panel_residual_rms_mm},
            {"panel_points", l.panel_points},
            {"readback",
             {{"frames", l.readback_frames},
              {"offset_mm", l.readback_offset_mm},
              {"max_error_mm", l.readback_max_error_mm},
              {"frames_off", l.readback_frames_off}}}}},
          {"icp", icp},
          {"warnings", s.warnings},
          {"timings_s", timings}};
}

std::string SummaryText(const ReconstructSummary& s) {
  std::string text =
      Format("%zu points from %zu peaks in %zu frames\n", s.points, s.peaks, s.frames);
  text += "  per camera:";
  for (size_t c = 0; c < s.points_per_camera.size(); ++c)
    text += Format(" %zu: %zu", c, s.points_per_camera[c]);
  text += "\n  per view:";
  for (size_t v = 0; v < s.points_per_view.size(); ++v)
    text += Format(" %s %zu", PointViewName(static_cast<PointView>(v)), s.points_per_view[v]);
  text += "\n  per laser:";
  for (size_t k = 0; k < s.points_per_laser.size(); ++k)
    text += Format(" %zu: %zu", k, s.points_per_laser[k]);
  text += Format(
      "\n  decided by stereo %zu, cylinder %zu, volume %zu, column count %zu, label vote %zu\n",
      s.decided_by_stereo, s.decided_by_cylinder, s.decided_by_volume, s.decided_by_column_count,
      s.decided_by_label_vote);
  text += Format(
      "  dropped: panel %zu, no ray %zu, outside volume %zu, floor %zu, ambiguous %zu, conflict "
      "%zu, unsupported %zu, seen through %zu, flat angle %zu, other camera better %zu, stripe "
      "end %zu, outlier %zu, low confidence %zu, off surface %zu\n",
      s.dropped_panel, s.dropped_no_ray, s.dropped_outside, s.dropped_floor, s.dropped_ambiguous,
      s.dropped_conflict, s.dropped_unsupported, s.dropped_seen_through, s.dropped_flat_angle,
      s.dropped_other_camera, s.dropped_stripe_end, s.dropped_outlier, s.dropped_low_confidence,
      s.dropped_off_surface);
  const LaserHeightSummary& l = s.laser_height;
  text += Format("  laser heights from %s", l.source.c_str());
  if (l.source == "panels") {
    text += Format(" (%zu points, rms %.3f mm, speed %.3f mm/s)", l.panel_points,
                   l.panel_residual_rms_mm, l.speed_mm_s);
    if (l.readback_frames)
      text += Format("; readback max error %.3f mm over %zu frames (%zu off)",
                     l.readback_max_error_mm, l.readback_frames, l.readback_frames_off);
  } else {
    text += " (" + l.reason + ")";
  }
  text += "\n";
  if (s.icp.ran) {
    for (const IcpSummary::Step& step : s.icp.steps)
      text += Format("  icp %s: rmse %.3f -> %.3f mm, %.4f deg, %.3f mm%s\n", step.what.c_str(),
                     step.rmse_before_mm, step.rmse_after_mm, step.rotation_deg,
                     step.translation_mm, step.applied ? "" : " (not applied)");
  }
  double total = 0;
  text += "  timings:";
  for (const auto& [stage, seconds] : s.timings_s) {
    text += Format(" %s %.3f s,", stage.c_str(), seconds);
    total += seconds;
  }
  text += Format(" total %.3f s\n", total);
  for (const std::string& w : s.warnings) text += "  warning: " + w + "\n";
  return text;
}

}  // namespace mirrorscan::reconstruction
