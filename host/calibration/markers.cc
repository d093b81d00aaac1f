#include "host/calibration/markers.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <Eigen/Eigenvalues>
#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace mirrorscan::calibration {

const char* ViewName(ViewId view) {
  switch (view) {
    case ViewId::kCenter:
      return "center";
    case ViewId::kLeft:
      return "left";
    case ViewId::kRight:
      return "right";
  }
  return "?";
}

namespace {

double Bilinear(const cv::Mat& gray, double u, double v) {
  const int u0 = static_cast<int>(std::floor(u)), v0 = static_cast<int>(std::floor(v));
  const double fu = u - u0, fv = v - v0;
  const auto at = [&](int x, int y) { return static_cast<double>(gray.at<uint8_t>(y, x)); };
  return (1 - fv) * ((1 - fu) * at(u0, v0) + fu * at(u0 + 1, v0)) +
         fv * ((1 - fu) * at(u0, v0 + 1) + fu * at(u0 + 1, v0 + 1));
}

struct Line {
  Eigen::Vector2d point, direction;
};

std::optional<Eigen::Vector2d> Intersect(const Line& a, const Line& b) {
  Eigen::Matrix2d m;
  m << a.direction, -b.direction;
  if (std::abs(m.determinant()) < 1e-6) return std::nullopt;
  const Eigen::Vector2d st = m.inverse() * (b.point - a.point);
  return a.point + st.x() * a.direction;
}

struct EdgeFit {
  Line line;
  std::vector<Eigen::Vector2d> points;
  double contrast = 0.0, sigma = 0.0;
};

// Edge from corner a to corner b of a dark square whose centre is `inside`.
std::optional<EdgeFit> FitEdge(const cv::Mat& gray, const Eigen::Vector2d& a,
                               const Eigen::Vector2d& b, const Eigen::Vector2d& inside) {
  const double length = (b - a).norm();
  if (length < 12.0) return std::nullopt;
  const Eigen::Vector2d along = (b - a) / length;
  Eigen::Vector2d outward(-along.y(), along.x());
  if (outward.dot(0.5 * (a + b) - inside) < 0) outward = -outward;
  // The border is one of six modules wide; the search window stays inside it and inside
  // the white quiet zone beyond.
  // Narrow, since flat samples only add noise: a blurred edge spans about ±2.5 σ.
  const int half = std::clamp(static_cast<int>(0.45 * length / 6.0), 2, 3);
  // Away from the corners by the window and some, where the other edge would bend the
  // profile.
  const double margin = std::max(0.1 * length, half + 3.0);
  std::vector<Eigen::Vector2d> points;
  double contrast_sum = 0.0, sigma2_sum = 0.0;
  for (double t = margin; t <= length - margin; t += 1.0) {
    const Eigen::Vector2d base = a + t * along;
    const Eigen::Vector2d lo = base - (half + 1) * outward, hi = base + (half + 1) * outward;
    if (std::min(lo.x(), hi.x()) < 0 || std::min(lo.y(), hi.y()) < 0 ||
        std::max(lo.x(), hi.x()) > gray.cols - 2 || std::max(lo.y(), hi.y()) > gray.rows - 2) {
      return std::nullopt;
    }
    double weight = 0.0, moment = 0.0, moment2 = 0.0;
    double previous = Bilinear(gray, base.x() - half * outward.x(), base.y() - half * outward.y());
    for (int s = -half; s < half; ++s) {
      const Eigen::Vector2d q = base + (s + 1) * outward;
      const double value = Bilinear(gray, q.x(), q.y());
      const double step = value - previous;  // black inside to white outside: positive
      weight += step;
      moment += step * (s + 0.5);
      moment2 += step * (s + 0.5) * (s + 0.5);
      previous = value;
    }
    if (weight < 8.0) continue;
    const double offset = moment / weight;
    points.push_back(base + offset * outward);
    contrast_sum += weight;
    sigma2_sum += moment2 / weight - offset * offset;
  }
  if (points.size() < 8) return std::nullopt;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
  EdgeFit fit;
  fit.line = {mean, eigen.eigenvectors().col(1)};
  fit.contrast = contrast_sum / points.size();
  // Differences of pixel samples widen a Gaussian edge by about one pixel's box (1/12)
  // on each side; what is left is the blur.
  fit.sigma = std::sqrt(std::max(0.0, sigma2_sum / points.size() - 1.0 / 6.0));
  fit.points = std::move(points);
  return fit;
}

}  // namespace

std::optional<DetectedMarker> RefineMarkerCorners(const cv::Mat& gray,
                                                  const DetectedMarker& marker) {
  DetectedMarker refined = marker;
  // Twice: the first pass starts from the detector's corners, which may be off by a
  // pixel; the second samples the edges where they really are.
  for (int pass = 0; pass < 2; ++pass) {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const auto& c : refined.corners) centre += 0.25 * c;
    std::array<EdgeFit, 4> edges;
    for (int e = 0; e < 4; ++e) {
      const auto fit = FitEdge(gray, refined.corners[e], refined.corners[(e + 1) % 4], centre);
      if (!fit) return std::nullopt;
      edges[e] = *fit;
    }
    DetectedMarker next = refined;
    double contrast = 0.0, sigma = 0.0;
    for (int c = 0; c < 4; ++c) {
      const auto corner = Intersect(edges[(c + 3) % 4].line, edges[c].line);
      if (!corner || (*corner - refined.corners[c]).norm() > 3.0) return std::nullopt;
      next.corners[c] = *corner;
      next.edge_points[c] = edges[c].points;
      contrast += 0.25 * edges[c].contrast;
      sigma += 0.25 * edges[c].sigma;
    }
    next.contrast_dn = contrast;
    next.edge_sigma_px = sigma;
    refined = next;
  }
  return refined;
}

std::array<ViewDetections, kViews> DetectTargetMarkers(const cv::Mat& gray,
                                                       const MarkerDetectorOptions& options) {
  const auto dictionary = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  const auto parameters = cv::aruco::DetectorParameters::create();
  parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_NONE;  // ours is better
  std::array<std::vector<DetectedMarker>, kViews> candidates;
  std::array<ViewDetections, kViews> result;
  cv::Mat flipped;
  cv::flip(gray, flipped, 1);
  for (const bool flip : {false, true}) {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(flip ? flipped : gray, dictionary, corners, ids, parameters);
    for (size_t i = 0; i < ids.size(); ++i) {
      const int panel = ids[i] / options.markers_per_panel;
      if (panel >= kViews || ids[i] >= static_cast<int>(options.layout_mm.size())) continue;
      // Only mirror views are mirror-imaged; anything else read there is a misreading.
      if (flip != (panel != 0)) continue;
      DetectedMarker m;
      m.id = ids[i];
      for (int c = 0; c < 4; ++c) {
        const double u = corners[i][c].x;
        m.corners[c] = {flip ? gray.cols - 1 - u : u, corners[i][c].y};
      }
      if (const auto refined = RefineMarkerCorners(gray, m)) {
        candidates[panel].push_back(*refined);
      } else {
        ++result[panel].rejected;
      }
    }
  }
  for (int view = 0; view < kViews; ++view) {
    std::vector<DetectedMarker>& found = candidates[view];
    std::vector<bool> keep(found.size(), true);
    // With four or more markers, one homography of the panel must carry them all to the
    // image; a misread id (a mirror-imaged or doubly reflected marker) lands elsewhere.
    if (found.size() >= 4) {
      std::vector<cv::Point2f> layout, image;
      for (const auto& m : found) {
        for (int c = 0; c < 4; ++c) {
          layout.emplace_back(options.layout_mm[m.id][c].x(), options.layout_mm[m.id][c].y());
          image.emplace_back(m.corners[c].x(), m.corners[c].y());
        }
      }
      std::vector<uchar> inliers;
      const cv::Mat h = cv::findHomography(layout, image, cv::RANSAC, options.layout_tolerance_px,
                                           inliers, 2000, 0.999);
      for (size_t i = 0; i < found.size(); ++i) {
        for (int c = 0; c < 4; ++c) keep[i] = keep[i] && !h.empty() && inliers[4 * i + c];
      }
    }
    // One detection per id: a second one of the same id is a reflection of a reflection.
    std::map<int, DetectedMarker> by_id;
    for (size_t i = 0; i < found.size(); ++i) {
      if (!keep[i] || by_id.count(found[i].id)) {
        ++result[view].rejected;
        continue;
      }
      by_id[found[i].id] = found[i];
    }
    for (auto& [id, m] : by_id) result[view].markers.push_back(m);
  }
  return result;
}

}  // namespace mirrorscan::calibration
