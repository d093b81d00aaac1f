#pragma once

#include <string>
#include <thread>

namespace mirrorscan {

// The threads that keep the outputs safe (the safety supervisor, the drive monitor) and
// the simulated drive that stands in for hardware must answer within milliseconds however
// busy the machine is: peak extraction on the board, a renderer and a browser on a host.
// Under the normal scheduler a loaded machine can hold a thread off for longer than the
// supervisor's 150 ms drive limit. These threads sleep nearly all the time, so running
// them first costs the others nothing.
//
// Moves `thread` to SCHED_FIFO at `priority` (1-99). Returns "" on success, or why not
// (e.g. no CAP_SYS_NICE and no RLIMIT_RTPRIO): the thread then keeps its scheduling and
// the caller says so in its log.
std::string RunThreadFirst(std::thread& thread, int priority);

}  // namespace mirrorscan
