// The calibration's report: its JSON and the image with the corners drawn.
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "host/calibration/calibrate.h"
#include "host/calibration/checks.h"

namespace mirrorscan::calibration {

using internal::Format;

nlohmann::json CalibrationResult::ReportJson() const {
  nlohmann::json cameras_json = nlohmann::json::array();
  for (const CameraReport& c : cameras) {
    nlohmann::json views = nlohmann::json::array();
    for (const ViewReport& v : c.views) {
      views.push_back({{"view", ViewName(v.view)},
                       {"markers_found", v.found},
                       {"markers_missing", v.missing},
                       {"markers_rejected", v.rejected},
                       {"contrast_dn", v.contrast_dn},
                       {"edge_sigma_px", v.edge_sigma_px},
                       {"rms_before_px", v.rms_before_px},
                       {"rms_after_px", v.rms_after_px},
                       {"max_after_px", v.max_after_px}});
    }
    // One string per row of cells: '#' with data, '.' without.
    nlohmann::json cells = nlohmann::json::array();
    for (int row = 0; row < LensCoverage::kRows; ++row) {
      std::string line;
      for (int column = 0; column < LensCoverage::kColumns; ++column)
        line += c.coverage.points[row * LensCoverage::kColumns + column] > 0 ? '#' : '.';
      cells.push_back(line);
    }
    cameras_json.push_back({{"name", c.name},
                            {"white_dn", c.white_dn},
                            {"views", views},
                            {"lens",
                             {{"fixed", c.coverage.lens_fixed},
                              {"coverage", c.coverage.fraction},
                              {"cells", cells}}}});
  }
  nlohmann::json checks_json = nlohmann::json::array();
  for (const Check& c : checks) {
    checks_json.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit}, {"ok", c.ok}});
  }
  nlohmann::json report = {
      {"ok", ok}, {"failures", failures}, {"cameras", cameras_json}, {"checks", checks_json}};
  if (calibration) {
    nlohmann::json mirrors = nlohmann::json::array();
    for (const auto& m : calibration->mirrors) {
      mirrors.push_back({{"name", m.name},
                         {"normal", {m.plane.normal.x(), m.plane.normal.y(), m.plane.normal.z()}},
                         {"offset_mm", m.plane.offset}});
    }
    report["mirrors"] = mirrors;
    report["content_hash"] = calibration->ContentHash();
  }
  return report;
}

cv::Mat DrawReport(const CameraImage& image, const CameraReport& report) {
  cv::Mat out;
  cv::cvtColor(image.gray, out, cv::COLOR_GRAY2BGR);
  const cv::Scalar green(0, 200, 0), red(0, 0, 255);
  // Lens coverage: cells with no data tinted red, a faint grid over the rest.
  cv::Mat tint = out.clone();
  for (int row = 0; row < LensCoverage::kRows; ++row) {
    for (int column = 0; column < LensCoverage::kColumns; ++column) {
      const cv::Rect cell(column * out.cols / LensCoverage::kColumns,
                          row * out.rows / LensCoverage::kRows, out.cols / LensCoverage::kColumns,
                          out.rows / LensCoverage::kRows);
      if (report.coverage.points[row * LensCoverage::kColumns + column] == 0) {
        cv::rectangle(tint, cell, red, cv::FILLED);
      }
      cv::rectangle(out, cell, cv::Scalar(90, 120, 90), 1);
    }
  }
  cv::addWeighted(tint, 0.3, out, 0.7, 0.0, out);
  int line = 0;
  for (const ViewReport& v : report.views) {
    for (size_t i = 0; i < v.observed.size(); ++i) {
      const cv::Point2d seen(v.observed[i].x(), v.observed[i].y());
      cv::circle(out, seen, 3, green, 1, cv::LINE_AA);
      if (i < v.reprojected.size()) {
        const cv::Point2d projected(v.reprojected[i].x(), v.reprojected[i].y());
        cv::drawMarker(out, projected, red, cv::MARKER_CROSS, 6, 1, cv::LINE_AA);
        const Eigen::Vector2d tip = v.observed[i] + 50.0 * (v.reprojected[i] - v.observed[i]);
        cv::line(out, seen, cv::Point2d(tip.x(), tip.y()), red, 1, cv::LINE_AA);
      }
    }
    std::ostringstream text;
    text << ViewName(v.view) << ": " << v.found.size() << " markers, RMS "
         << Format("%.3f", v.rms_after_px) << " px";
    cv::putText(out, text.str(), cv::Point(10, 24 + 22 * line++), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  }
  cv::putText(out,
              "lens data on " + Format("%.0f", 100.0 * report.coverage.fraction) +
                  "% of the image (red: none)" +
                  (report.coverage.lens_fixed ? ", lens fixed" : ", lens from the target"),
              cv::Point(10, 24 + 22 * line++), cv::FONT_HERSHEY_SIMPLEX, 0.6,
              cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  return out;
}

}  // namespace mirrorscan::calibration
