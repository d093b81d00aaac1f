#pragma once

#include <stdexcept>
#include <string>

namespace mirrorscan::hal {

// Every hardware backend reports failures by throwing HardwareError (never by crashing,
// never by returning a silent default). The kind lets callers react without parsing text.
class HardwareError : public std::runtime_error {
 public:
  enum class Kind {
    kTimeout,          // the device did not answer within the configured time
    kIo,               // the link failed (cannot open, connection lost, bad frame)
    kRejected,         // the device answered with an error (e.g. a Modbus exception)
    kFault,            // the device reports a fault (its code is in the message)
    kInvalidArgument,  // a request outside the configured limits; nothing was sent
    kAborted,          // a blocking call was interrupted (e.g. Stop() during Home())
  };

  HardwareError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}

  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

}  // namespace mirrorscan::hal
