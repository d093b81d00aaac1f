#include "host/cli/measure_command.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/mesh/mesh_io.h"
#include "host/measurement/measure.h"
#include "host/measurement/preview.h"

namespace mirrorscan::cli {
namespace {

namespace fs = std::filesystem;

struct MeasureOptions {
  std::string mesh;
  std::string out;
  std::string csv;
  std::string preview;
  std::vector<double> girth_at_mm;
  bool json = false;
};

void WriteText(const std::string& file, const std::string& text) {
  // Beside the target, then renamed: a reader never sees half a file.
  const std::string partial = file + ".partial";
  {
    std::ofstream out(partial, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error(file + ": cannot write");
  }
  std::error_code error;
  fs::rename(partial, file, error);
  if (error) throw std::runtime_error(file + ": cannot write (" + error.message() + ")");
}

void Run(const MeasureOptions& o) {
  const TriangleMesh mesh = ReadTriangleMesh(o.mesh);
  if (!o.json)
    std::fprintf(stderr, "measuring %s (%zu triangles)\n", o.mesh.c_str(), mesh.triangles.size());
  measurement::MeasureOptions options;
  options.girth_at_mm = o.girth_at_mm;
  const measurement::BodyMeasurements body = measurement::MeasureBody(mesh, options);
  const nlohmann::json json = measurement::ToJson(body);
  WriteText(o.out, json.dump(2) + "\n");
  if (!o.csv.empty()) WriteText(o.csv, measurement::ToCsv(body));
  if (!o.preview.empty()) {
    const cv::Mat image = measurement::RenderPreview(mesh, body);
    if (!cv::imwrite(o.preview, image)) throw std::runtime_error(o.preview + ": cannot write PNG");
  }
  if (o.json) {
    std::printf("%s\n", json.dump(2).c_str());
    return;
  }
  for (const measurement::Measurement& m : body.measurements) {
    if (m.value_mm) {
      std::printf("%-24s %8.1f mm  (confidence %.2f)\n", m.name.c_str(), *m.value_mm, m.confidence);
    } else {
      std::printf("%-24s withheld: %s\n", m.name.c_str(), m.withheld.value_or("").c_str());
    }
  }
  for (const measurement::SliceGirth& s : body.slices) {
    if (s.girth_mm) {
      std::printf("girth at %7.1f mm %-10s %8.1f mm (contour %.1f)\n", s.z_mm, s.part.c_str(),
                  *s.girth_mm, s.contour_mm.value_or(0.0));
    } else {
      std::printf("girth at %7.1f mm %-10s withheld: %s\n", s.z_mm, s.part.c_str(),
                  s.withheld.value_or("").c_str());
    }
  }
  std::printf("wrote %s\n", o.out.c_str());
}

}  // namespace

void AddMeasureCommand(CLI::App& app) {
  auto options = std::make_shared<MeasureOptions>();
  auto* cmd = app.add_subcommand(
      "measure", "Body measurements (ISO 8559-1 style) from a mesh; withheld where unsupported");
  cmd->add_option("mesh", options->mesh, "Mesh file (.ply, .obj or .stl), millimetres, z up")
      ->required();
  cmd->add_option("--out", options->out, "Measurements JSON")->required();
  cmd->add_option("--csv", options->csv, "Also write the measurements as CSV");
  cmd->add_option("--girth-at", options->girth_at_mm,
                  "Horizontal girths at these heights (mm), e.g. 900,1100")
      ->delimiter(',');
  cmd->add_option("--preview", options->preview,
                  "Write a PNG of the body with the measured contours and landmarks");
  cmd->add_flag("--json", options->json, "Print the measurements JSON on stdout");
  cmd->callback([options] { Run(*options); });
}

}  // namespace mirrorscan::cli
