#include "common/realtime/realtime.h"

#include <pthread.h>
#include <sched.h>

#include <cstring>

namespace mirrorscan {

std::string RunThreadFirst(std::thread& thread, int priority) {
  const int lowest = sched_get_priority_min(SCHED_FIFO);
  const int highest = sched_get_priority_max(SCHED_FIFO);
  if (priority < lowest || priority > highest) {
    return "real-time priority " + std::to_string(priority) + " is outside " +
           std::to_string(lowest) + "-" + std::to_string(highest);
  }
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(thread.native_handle(), SCHED_FIFO, &param);
  if (error != 0) {
    return std::string("cannot run at real-time priority: ") + std::strerror(error);
  }
  return "";
}

}  // namespace mirrorscan
