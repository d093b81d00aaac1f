// Peak extraction throughput on synthetic 1024x768 frames (3-9 stripes, ambient, noise).

#include <benchmark/benchmark.h>

#include <cstdint>
#include <random>
#include <vector>

#include "common/peaks/peaks.h"
#include "common/peaks/peaks_synth.h"

namespace mirrorscan {
namespace {

const std::vector<synth::Frame>& Frames() {
  static const std::vector<synth::Frame> frames = [] {
    std::vector<synth::Frame> out;
    std::mt19937 rng(42);
    for (int i = 0; i < 8; ++i) {
      synth::Scene scene;
      scene.noise_sigma = 2 + (i % 3);
      scene.speckle = 0.15;
      scene.stripes = synth::RandomStripes(3 + (i % 7), scene.height, 40, 250, &rng);
      out.push_back(synth::Render(scene, 100 + i));
    }
    return out;
  }();
  return frames;
}

void BM_ExtractSimd(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  const PeakParams params;
  size_t i = 0, total = 0;
  for (auto _ : state) {
    extractor.Extract(Frames()[i++ % Frames().size()].view(), params, &peaks);
    total += peaks.size();
    benchmark::DoNotOptimize(peaks.data());
  }
  state.SetLabel(PeakExtractor::SimdTarget());
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
  state.counters["peaks/frame"] = static_cast<double>(total) / state.iterations();
}
BENCHMARK(BM_ExtractSimd);

// The fair speed reference: a plain row-major thresholded centre of mass, one pass over
// the rows (PlainCentreOfMass), at 100 DN (these frames' ambient reaches 88 DN).
void BM_PlainCentreOfMass(benchmark::State& state) {
  PlainCentreOfMass plain;
  std::vector<Peak> peaks;
  size_t i = 0;
  for (auto _ : state) {
    plain.Extract(Frames()[i++ % Frames().size()].view(), 100, &peaks);
    benchmark::DoNotOptimize(peaks.data());
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_PlainCentreOfMass);

// The paper's estimator on the project's own scalar column walk (ExtractScalar's
// candidates and refinement): not a plain implementation, see BM_PlainCentreOfMass.
void BM_ExtractScalarCoM(benchmark::State& state) {
  PeakExtractor extractor;
  std::vector<Peak> peaks;
  PeakParams params;
  params.estimator = PeakEstimator::kThresholdedCom;
  size_t i = 0;
  for (auto _ : state) {
    extractor.ExtractScalar(Frames()[i++ % Frames().size()].view(), params, &peaks);
    benchmark::DoNotOptimize(peaks.data());
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ExtractScalarCoM);

// Memory-bound ceiling: read every byte of the frame once.
void BM_ReadPass(benchmark::State& state) {
  size_t i = 0;
  for (auto _ : state) {
    const synth::Frame& f = Frames()[i++ % Frames().size()];
    const auto* p = reinterpret_cast<const uint64_t*>(f.pixels.data());
    const size_t n = f.pixels.size() / 8;
    uint64_t acc0 = 0, acc1 = 0, acc2 = 0, acc3 = 0;
    for (size_t k = 0; k + 4 <= n; k += 4) {
      acc0 ^= p[k];
      acc1 ^= p[k + 1];
      acc2 ^= p[k + 2];
      acc3 ^= p[k + 3];
    }
    benchmark::DoNotOptimize(acc0 ^ acc1 ^ acc2 ^ acc3);
  }
  state.counters["frames/s"] = benchmark::Counter(state.iterations(), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ReadPass);

}  // namespace
}  // namespace mirrorscan
