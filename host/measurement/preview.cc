#include "host/measurement/preview.h"

#include <algorithm>
#include <array>
#include <numeric>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

namespace mirrorscan::measurement {

cv::Mat RenderPreview(const TriangleMesh& mesh, const BodyMeasurements& body, int height_px) {
  const Eigen::Vector3d lateral(body.lateral.x(), body.lateral.y(), 0.0);
  const Eigen::Vector3d front(body.lateral.y(), -body.lateral.x(), 0.0);
  double u_lo = 1e18, u_hi = -1e18, z_lo = 1e18, z_hi = -1e18;
  for (const Eigen::Vector3d& v : mesh.vertices) {
    u_lo = std::min(u_lo, v.dot(lateral));
    u_hi = std::max(u_hi, v.dot(lateral));
    z_lo = std::min(z_lo, v.z());
    z_hi = std::max(z_hi, v.z());
  }
  const double margin = 40.0;  // px
  const double scale = (height_px - 2 * margin) / std::max(1.0, z_hi - z_lo);
  const int width = static_cast<int>((u_hi - u_lo) * scale + 2 * margin + 260);  // room for names
  cv::Mat image(height_px, width, CV_8UC3, cv::Scalar(255, 255, 255));
  auto pixel = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(margin + (p.dot(lateral) - u_lo) * scale),
                     static_cast<int>(height_px - margin - (p.z() - z_lo) * scale));
  };
  // The body, shaded by how squarely each triangle faces the viewer, far ones first.
  std::vector<int> order(mesh.triangles.size());
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> depth(mesh.triangles.size());
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    depth[i] = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]).dot(front);
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return depth[a] < depth[b]; });
  for (int i : order) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    const Eigen::Vector3d& a = mesh.vertices[t[0]];
    const Eigen::Vector3d n = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a);
    if (n.norm() == 0.0) continue;
    const double facing = std::abs(n.normalized().dot(front));
    const int shade = static_cast<int>(90 + 140 * facing);
    const std::array<cv::Point, 3> corners = {pixel(a), pixel(mesh.vertices[t[1]]),
                                              pixel(mesh.vertices[t[2]])};
    cv::fillConvexPoly(image, corners.data(), 3, cv::Scalar(shade, shade, shade), cv::LINE_8);
  }
  const std::array<cv::Scalar, 6> colours = {cv::Scalar(0, 0, 220),   cv::Scalar(0, 150, 0),
                                             cv::Scalar(220, 0, 0),   cv::Scalar(0, 140, 220),
                                             cv::Scalar(160, 0, 160), cv::Scalar(140, 140, 0)};
  const int label_x = width - 250;
  int label_y = 30;
  for (size_t k = 0; k < body.contours.size(); ++k) {
    const MeasuredContour& c = body.contours[k];
    const cv::Scalar colour = colours[k % colours.size()];
    std::vector<cv::Point> line;
    for (const Eigen::Vector3d& p : c.points_mm) line.push_back(pixel(p));
    cv::polylines(image, line, /*isClosed=*/true, colour, 2, cv::LINE_AA);
    const Measurement* m = body.Find(c.name);
    std::string label = c.name;
    if (m && m->value_mm)
      label += " " + std::to_string(static_cast<int>(std::lround(*m->value_mm)));
    cv::putText(image, label, cv::Point(label_x, label_y), cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1,
                cv::LINE_AA);
    if (!line.empty()) {
      const cv::Point anchor =
          *std::max_element(line.begin(), line.end(),
                            [](const cv::Point& a, const cv::Point& b) { return a.x < b.x; });
      cv::line(image, anchor, cv::Point(label_x - 4, label_y - 4), colour, 1, cv::LINE_AA);
    }
    label_y += 22;
  }
  for (const Landmark& l : body.landmarks) {
    cv::circle(image, pixel(l.point_mm), 5, cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA);
    cv::circle(image, pixel(l.point_mm), 3, cv::Scalar(0, 230, 255), cv::FILLED, cv::LINE_AA);
    cv::putText(image, l.name, pixel(l.point_mm) + cv::Point(7, -5), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return image;
}

}  // namespace mirrorscan::measurement
