// The per-frame copy the libcamera backend makes (a strided plane into the packed pool
// buffer), at the board's 1024x768 and with the ISP's row padding.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <vector>

#include "firmware/hal/libcamera/libcamera_stream.h"

namespace mirrorscan::hal::libcamera_stream {
namespace {

void BM_PackPlane(benchmark::State& state) {
  const int width = 1024, height = 768;
  const auto stride = static_cast<size_t>(state.range(0));
  const std::vector<uint8_t> plane(stride * height, 77);
  std::vector<uint8_t> packed(static_cast<size_t>(width) * height);
  for (auto _ : state) {
    PackPlane(plane, stride, width, height, packed.data());
    benchmark::DoNotOptimize(packed.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * width * height);
}
// Unpadded (one memcpy) and padded to a 64-byte multiple plus 64 (a row at a time).
BENCHMARK(BM_PackPlane)->Arg(1024)->Arg(1088);

}  // namespace
}  // namespace mirrorscan::hal::libcamera_stream
