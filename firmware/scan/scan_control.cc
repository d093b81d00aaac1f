#include "firmware/scan/scan_control.h"

namespace mirrorscan::scan {

std::string_view SequencerStateName(SequencerState state) {
  switch (state) {
    case SequencerState::kIdle:
      return "idle";
    case SequencerState::kHoming:
      return "homing";
    case SequencerState::kArming:
      return "arming";
    case SequencerState::kSweeping:
      return "sweeping";
    case SequencerState::kFinishing:
      return "finishing";
    case SequencerState::kDone:
      return "done";
    case SequencerState::kFault:
      return "fault";
    case SequencerState::kAborted:
      return "aborted";
  }
  return "unknown";
}

}  // namespace mirrorscan::scan
