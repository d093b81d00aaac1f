// Frames per second of the virtual cabinet: one 1024×768 laser frame of the mannequin.
#include <benchmark/benchmark.h>

#include "boards/virtual/renderer.h"

namespace mirrorscan::virtual_cabinet {
namespace {

const Renderer& MannequinRenderer() {
  static const Renderer renderer(
      Scene::Load(std::string(MIRRORSCAN_SOURCE_DIR) + "/boards/virtual/scenes/mannequin.json"));
  return renderer;
}

void BM_RenderLaserFrame(benchmark::State& state) {
  const Renderer& renderer = MannequinRenderer();
  renderer.RenderFrame(0, 0.0, 0);  // per-camera precomputation, once
  uint64_t frame = 0;
  for (auto _ : state) {
    const double t = (frame % 300) / 30.0;
    benchmark::DoNotOptimize(renderer.RenderFrame(0, t, frame++));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_RenderLaserFrame)->Unit(benchmark::kMillisecond);

void BM_GroundTruth(benchmark::State& state) {
  const Renderer& renderer = MannequinRenderer();
  int frame = 0;
  for (auto _ : state) benchmark::DoNotOptimize(renderer.Truth(0, (frame++ % 300) / 30.0));
}
BENCHMARK(BM_GroundTruth)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mirrorscan::virtual_cabinet
