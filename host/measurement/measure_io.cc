// MeasureBody's results as JSON and CSV (measure.h).
#include <optional>
#include <sstream>
#include <string>

#include "host/measurement/measure.h"

namespace mirrorscan::measurement {
namespace {

nlohmann::json Nullable(const std::optional<double>& x) {
  return x ? nlohmann::json(*x) : nlohmann::json(nullptr);
}
nlohmann::json Nullable(const std::optional<std::string>& x) {
  return x ? nlohmann::json(*x) : nlohmann::json(nullptr);
}

std::string CsvField(const std::optional<double>& x) {
  if (!x) return "";
  std::ostringstream out;
  out.precision(10);
  out << *x;
  return out.str();
}

std::string CsvText(const std::optional<std::string>& x) {
  if (!x) return "";
  std::string quoted = "\"";
  for (char c : *x) quoted += (c == '"') ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace

nlohmann::json ToJson(const BodyMeasurements& body) {
  nlohmann::json json;
  json["stature_mm"] = Nullable(body.stature_mm);
  json["human"] = body.human;
  json["measurements"] = nlohmann::json::array();
  for (const Measurement& m : body.measurements) {
    json["measurements"].push_back({{"name", m.name},
                                    {"value_mm", Nullable(m.value_mm)},
                                    {"z_mm", Nullable(m.z_mm)},
                                    {"contour_mm", Nullable(m.contour_mm)},
                                    {"confidence", m.confidence},
                                    {"withheld", Nullable(m.withheld)}});
  }
  json["slices"] = nlohmann::json::array();
  for (const SliceGirth& s : body.slices) {
    json["slices"].push_back({{"z_mm", s.z_mm},
                              {"part", s.part},
                              {"girth_mm", Nullable(s.girth_mm)},
                              {"contour_mm", Nullable(s.contour_mm)},
                              {"withheld", Nullable(s.withheld)}});
  }
  json["landmarks"] = nlohmann::json::array();
  for (const Landmark& l : body.landmarks) {
    json["landmarks"].push_back(
        {{"name", l.name}, {"point_mm", {l.point_mm.x(), l.point_mm.y(), l.point_mm.z()}}});
  }
  return json;
}

std::string ToCsv(const BodyMeasurements& body) {
  std::ostringstream out;
  out << "name,value_mm,z_mm,contour_mm,confidence,withheld\n";
  for (const Measurement& m : body.measurements) {
    out << m.name << ',' << CsvField(m.value_mm) << ',' << CsvField(m.z_mm) << ','
        << CsvField(m.contour_mm) << ',' << m.confidence << ',' << CsvText(m.withheld) << '\n';
  }
  for (const SliceGirth& s : body.slices) {
    out << "girth_at:" << s.part << ',' << CsvField(s.girth_mm) << ',' << CsvField(s.z_mm) << ','
        << CsvField(s.contour_mm) << ',' << (s.withheld ? 0.0 : 1.0) << ',' << CsvText(s.withheld)
        << '\n';
  }
  return out.str();
}

}  // namespace mirrorscan::measurement
