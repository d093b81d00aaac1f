#include "host/measurement/measure.h"

#include <stdexcept>

#include "host/measurement/body_analysis.h"

namespace mirrorscan::measurement {
namespace internal {

void BodyAnalysis::Run(const MeasureOptions& options) {
  if (!FindLegsAndCrotch() || !FindTorsoAxis()) {
    WithholdAll("not a human body: " + not_human_);
  } else {
    out_.human = true;
    out_.lateral = lateral_;
    FindArms();
    MeasureStature();
    Add(crotch_);
    MeasureTorso();
    MeasureThighs();
    MeasureNeck();
    MeasureArms();
  }
  for (double z : options.girth_at_mm) GirthAt(z);
}

void BodyAnalysis::Add(Measurement m) {
  if (m.withheld) {
    m.value_mm.reset();
    m.contour_mm.reset();
    m.confidence = 0.0;
  }
  out_.measurements.push_back(std::move(m));
}

void BodyAnalysis::WithholdAll(const std::string& reason) {
  out_.stature_withheld = reason;
  for (const char* name :
       {"stature", "crotch_height", "chest_girth", "waist_girth", "hip_girth", "thigh_girth_left",
        "thigh_girth_right", "neck_girth", "upper_arm_girth_left", "upper_arm_girth_right",
        "shoulder_breadth", "arm_length_left", "arm_length_right"}) {
    Measurement m;
    m.name = name;
    m.withheld = reason;
    Add(m);
  }
}

}  // namespace internal

const Measurement* BodyMeasurements::Find(const std::string& name) const {
  for (const Measurement& m : measurements) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

BodyMeasurements MeasureBody(const TriangleMesh& mesh, const MeasureOptions& options) {
  if (mesh.triangles.empty()) throw std::invalid_argument("the mesh has no triangles");
  const Slicer slicer(WeldVertices(mesh));
  BodyMeasurements out;
  internal::BodyAnalysis(slicer, out).Run(options);
  return out;
}

}  // namespace mirrorscan::measurement
