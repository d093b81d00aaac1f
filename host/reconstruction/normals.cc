#include "host/reconstruction/normals.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/parallel/parallel_for.h"
#include "host/reconstruction/hypotheses.h"

namespace mirrorscan::reconstruction {

namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
}  // namespace

PointCloud PointsWithNormals(const ScanArchive& archive, const PeakTable& table, const Grid& grid,
                             const FilteredGrid& filtered, const ReconstructOptions& options,
                             int threads, PointNotes* notes, ReconstructSummary* summary) {
  PointCloud cloud;
  // Each chunk of grid points into its own list, joined in order.
  struct CloudChunk {
    std::vector<CloudPoint> points;
    PointNotes notes;
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
        const Eigen::Vector3d pa = a >= 0 ? filtered.smoothed[a] : filtered.smoothed[i];
        const Eigen::Vector3d pb = b >= 0 ? filtered.smoothed[b] : filtered.smoothed[i];
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
      cp.point_in_world = filtered.smoothed[i].cast<float>();
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
          std::min(1.0, (filtered.end_distance[i] + 1.0) / (options.stripe_end_columns + 2.0));
      cp.confidence = static_cast<float>(std::clamp(p.score * angle_factor * end_factor, 0.0, 1.0));
      if (cp.confidence < options.min_confidence) {
        ++out.low_confidence;
        continue;
      }
      out.points.push_back(cp);
      out.notes.suspect.push_back(gp.suspect);
      out.notes.sin_angle.push_back(static_cast<float>(gp.sin_angle));
    }
  });
  for (CloudChunk& chunk : cloud_chunks) {
    cloud.points.insert(cloud.points.end(), chunk.points.begin(), chunk.points.end());
    notes->suspect.insert(notes->suspect.end(), chunk.notes.suspect.begin(),
                          chunk.notes.suspect.end());
    notes->sin_angle.insert(notes->sin_angle.end(), chunk.notes.sin_angle.begin(),
                            chunk.notes.sin_angle.end());
    summary->dropped_low_confidence += chunk.low_confidence;
  }
  return cloud;
}

}  // namespace mirrorscan::reconstruction
