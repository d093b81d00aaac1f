// Prints how far a calibration.json is from the virtual cabinet's truth over every stripe
// point of a scene's sweep (docs/calibration.md's tables):
//   calibration_truth --scene SCENE.json --calibration C.json [--frame-step N]
#include <cstdio>
#include <exception>
#include <string>

#include "tests/support/calibration_truth.h"

int main(int argc, char** argv) {
  std::string scene_path, calibration_path;
  int frame_step = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--scene")
      scene_path = argv[i + 1];
    else if (flag == "--calibration")
      calibration_path = argv[i + 1];
    else if (flag == "--frame-step")
      frame_step = std::stoi(argv[i + 1]);
    else {
      std::fprintf(stderr, "calibration_truth: unknown option %s\n", flag.c_str());
      return 2;
    }
  }
  if (scene_path.empty() || calibration_path.empty()) {
    std::fprintf(stderr,
                 "usage: calibration_truth --scene SCENE.json --calibration C.json "
                 "[--frame-step N]\n");
    return 2;
  }
  try {
    using namespace mirrorscan;
    const auto scene = virtual_cabinet::Scene::Load(scene_path);
    const auto truth = test_support::SweepTruth(scene, frame_step);
    const auto rows =
        test_support::CompareWithTruth(Calibration::Load(calibration_path), scene, truth);
    std::printf("%s", test_support::FormatAgreement(rows).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "calibration_truth: %s\n", e.what());
    return 1;
  }
  return 0;
}
