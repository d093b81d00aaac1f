// libFuzzer target for calibration.json: parsing never crashes or throws anything but a
// ConfigError, and whatever parses survives a round trip through ToJson unchanged.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "common/config/calibration.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const mirrorscan::Calibration calibration =
        mirrorscan::Calibration::ParseText(text, "fuzz.json");
    const mirrorscan::Calibration back =
        mirrorscan::Calibration::Parse(calibration.ToJson(), "round-trip.json");
    if (back.ContentHash() != calibration.ContentHash()) std::abort();
  } catch (const mirrorscan::ConfigError&) {
  }
  return 0;
}
