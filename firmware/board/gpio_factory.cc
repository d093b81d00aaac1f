#include "firmware/board/gpio_factory.h"

#include <string>
#include <utility>

#include "firmware/hal/gpio_line.h"
#include "firmware/hal/gpiod/gpiod_line.h"
#include "firmware/hal/virtual/virtual_gpio_line.h"
#include "firmware/hal/virtual/virtual_monostable.h"

namespace mirrorscan::board {
namespace {

using hal::ActiveLevelLine;
using hal::GpioBackend;
using hal::GpioButton;
using hal::GpioConfig;
using hal::GpiodLine;
using hal::GpioLine;
using hal::GpioLaserBank;
using hal::GpioLaserInterlock;
using hal::GpioLed;
using hal::GpioLineConfig;
using hal::VirtualGpioLine;
using hal::VirtualLineStates;
using hal::VirtualMonostable;

std::unique_ptr<GpioLine> MakeLine(const GpioConfig& config, GpioBackend backend,
                                   const GpioLineConfig& line, bool output,
                                   const std::string& role) {
  // Outputs start inactive; an input's idle (released) level is inactive too.
  const bool idle_high = ActiveLevelLine::ToPhysical(false, line.active_low);
  if (backend == GpioBackend::kGpiod) {
    return std::make_unique<GpiodLine>(
        config.chip, static_cast<unsigned int>(line.line),
        output ? GpiodLine::Direction::kOutput : GpiodLine::Direction::kInputWithEdges, role,
        idle_high);
  }
  return std::make_unique<VirtualGpioLine>(
      role, output ? VirtualGpioLine::Direction::kOutput : VirtualGpioLine::Direction::kInput,
      idle_high);
}

}  // namespace

GpioLines MakeGpioLines(const GpioConfig& config, GpioBackend backend,
                        const std::optional<std::filesystem::path>& interlock_state_file,
                        const std::optional<std::filesystem::path>& line_state_file) {
  GpioLines lines;
  for (size_t i = 0; i < config.lasers.size(); ++i) {
    lines.lasers.push_back(
        {MakeLine(config, backend, config.lasers[i], true, "laser[" + std::to_string(i) + "]"),
         config.lasers[i].active_low});
  }
  lines.led = {MakeLine(config, backend, config.led, true, "led"), config.led.active_low};
  lines.button = {MakeLine(config, backend, config.button, false, "button"),
                  config.button.active_low};
  if (backend == GpioBackend::kVirtual && line_state_file) {
    auto states = std::make_shared<VirtualLineStates>(*line_state_file);
    for (auto& laser : lines.lasers) {
      static_cast<VirtualGpioLine&>(*laser.line).MirrorTo(states);
    }
    static_cast<VirtualGpioLine&>(*lines.led.line).MirrorTo(states);
  }
  if (backend == GpioBackend::kVirtual) {
    lines.interlock = {
        std::make_unique<VirtualMonostable>(std::chrono::milliseconds(config.interlock_pulse_ms),
                                            interlock_state_file),
        false};
  } else if (config.interlock) {
    lines.interlock = {MakeLine(config, backend, *config.interlock, true, "interlock"),
                       config.interlock->active_low};
  }
  return lines;
}

GpioDevices MakeGpioDevices(const GpioConfig& config, GpioLines lines) {
  GpioDevices d;
  d.lasers = std::make_unique<GpioLaserBank>(std::move(lines.lasers));
  d.led = std::make_unique<GpioLed>(std::move(lines.led));
  d.button = std::make_unique<GpioButton>(std::move(lines.button),
                                          std::chrono::milliseconds(config.debounce_ms));
  if (lines.interlock.line) {
    d.interlock = std::make_unique<GpioLaserInterlock>(
        std::move(lines.interlock), std::chrono::milliseconds(config.interlock_pulse_ms));
  }
  return d;
}

}  // namespace mirrorscan::board
