#include "host/cli/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace mirrorscan::cli {

Progress::Progress(std::string command, std::FILE* out)
    : command_(std::move(command)), out_(out), terminal_(isatty(fileno(out)) == 1) {}

Progress::~Progress() { Done(); }

void Progress::Stage(const std::string& name) {
  Done();
  stage_ = name;
  drawn_percent_ = -1;
  stage_start_ = std::chrono::steady_clock::now();
  if (terminal_) {
    Update(0.0);
  } else {
    std::fprintf(out_, "%s: %s ...\n", command_.c_str(), stage_.c_str());
    std::fflush(out_);
  }
}

void Progress::Update(double fraction) {
  if (!terminal_ || stage_.empty()) return;
  const int percent = static_cast<int>(std::lround(100 * std::clamp(fraction, 0.0, 1.0)));
  if (percent == drawn_percent_) return;
  drawn_percent_ = percent;
  constexpr int kWidth = 30;
  const int filled = percent * kWidth / 100;
  std::fprintf(out_, "\r%s: [%s%s] %3d %% %-24s", command_.c_str(),
               std::string(filled, '#').c_str(), std::string(kWidth - filled, ' ').c_str(), percent,
               stage_.c_str());
  std::fflush(out_);
}

void Progress::Done() {
  if (stage_.empty()) return;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - stage_start_).count();
  if (terminal_) {
    Update(1.0);
    std::fprintf(out_, " %.1f s\n", seconds);
  } else {
    std::fprintf(out_, "%s: %s done in %.1f s\n", command_.c_str(), stage_.c_str(), seconds);
  }
  std::fflush(out_);
  stage_.clear();
}

}  // namespace mirrorscan::cli
