#pragma once
// What the device API (firmware/service) may ask of the scan sequencer (firmware/scan),
// and what it hears back. The sequencer implements it; the service only uses it, so the
// two are built and tested apart.

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace mirrorscan::scan {

// The sequencer's states (docs/firmware.md). kDone, kFault and kAborted are where a scan
// ends; the next start leaves them.
enum class SequencerState { kIdle, kHoming, kArming, kSweeping, kFinishing, kDone, kFault, kAborted };
std::string_view SequencerStateName(SequencerState state);  // "idle", "homing", ...

struct ScanStatus {
  SequencerState state = SequencerState::kIdle;
  std::string scan_id;        // the running or last scan; empty before the first
  double progress = 0.0;      // 0..1 along the sweep
  double position_mm = 0.0;   // last slide position readback
  uint64_t frames = 0;        // frames stored in this scan
  uint64_t peaks = 0;
  uint64_t dropped = 0;       // frames lost (camera drops + queue overflows)
  std::string reason;         // why it faulted or aborted; empty otherwise
  int64_t updated_ns = 0;     // steady clock
};

// A state change or a progress step (at most a few per second).
struct ScanEvent {
  enum class Type { kState, kProgress };
  Type type = Type::kState;
  ScanStatus status;
};

// One raw frame for calibration (GET/POST /api/v1/captures).
struct CapturedFrame {
  std::string camera;  // the board's camera name
  int width = 0;
  int height = 0;
  bool lasers_on = false;
  int64_t timestamp_ns = 0;
  std::vector<uint8_t> pixels;  // 8-bit gray, row-major, stride = width
};

// Refusals the API turns into 4xx: kBusy → 409, kInvalidArgument → 400, kUnavailable
// (a fault that needs clearing, hardware missing) → 503.
class ScanControlError : public std::runtime_error {
 public:
  enum class Kind { kBusy, kInvalidArgument, kUnavailable };
  ScanControlError(Kind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

class ScanControl {
 public:
  using Listener = std::function<void(const ScanEvent&)>;
  virtual ~ScanControl() = default;

  // Starts a scan as the button does and returns its id once the store has created it
  // (the sweep continues on the sequencer's thread). `origin` ("api", "button", "test")
  // goes into the archive header. Throws ScanControlError kBusy while a scan runs.
  virtual std::string StartScan(std::string_view origin) = 0;
  // Aborts the running scan (lasers off, drive stopped, archive finished as "aborted").
  // No-op when idle.
  virtual void Abort(std::string_view reason) = 0;
  virtual ScanStatus Status() const = 0;
  // The listener runs on the sequencer's thread and must only enqueue. Returns a handle
  // for Unsubscribe; no call runs after Unsubscribe returns.
  virtual int Subscribe(Listener listener) = 0;
  virtual void Unsubscribe(int handle) = 0;
  // One frame from `camera` with the lasers on or off; only while idle (kBusy otherwise),
  // kInvalidArgument for an unknown camera.
  virtual CapturedFrame Capture(const std::string& camera, bool lasers_on) = 0;
};

}  // namespace mirrorscan::scan
