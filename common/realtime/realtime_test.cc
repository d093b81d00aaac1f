#include "common/realtime/realtime.h"

#include <pthread.h>
#include <sched.h>

#include <condition_variable>
#include <mutex>
#include <thread>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

// A thread that waits until told to go, and records its own scheduling as the kernel
// reports it from inside.
class Worker {
 public:
  Worker() : thread_([this] { Run(); }) {}
  ~Worker() {
    {
      std::lock_guard lock(mutex_);
      go_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  std::thread& thread() { return thread_; }
  // Lets it finish and returns its policy and priority seen from inside.
  std::pair<int, int> Finish() {
    {
      std::lock_guard lock(mutex_);
      go_ = true;
    }
    wake_.notify_all();
    thread_.join();
    return {policy_, priority_};
  }

 private:
  void Run() {
    std::unique_lock lock(mutex_);
    wake_.wait(lock, [&] { return go_; });
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy_, &param);
    priority_ = param.sched_priority;
  }
  std::mutex mutex_;
  std::condition_variable wake_;
  bool go_ = false;
  int policy_ = -1, priority_ = -1;
  std::thread thread_;
};

// The kernel's own answer from inside the thread: FIFO at the priority asked for, or,
// where the machine does not allow it, a reason and the thread's scheduling unchanged.
TEST(RunThreadFirst, TheThreadRunsFifoAtThePriorityOrTheReasonIsGiven) {
  Worker worker;
  const std::string reason = RunThreadFirst(worker.thread(), 7);
  const auto [policy, priority] = worker.Finish();
  if (reason.empty()) {
    EXPECT_EQ(policy, SCHED_FIFO);
    EXPECT_EQ(priority, 7);
  } else {
    EXPECT_NE(reason.find("cannot run at real-time priority"), std::string::npos) << reason;
    EXPECT_EQ(policy, SCHED_OTHER);
  }
  // The caller's own thread is not touched.
  int own_policy = -1;
  sched_param param{};
  pthread_getschedparam(pthread_self(), &own_policy, &param);
  EXPECT_EQ(own_policy, SCHED_OTHER);
}

TEST(RunThreadFirst, APriorityOutsideTheRangeIsRefused) {
  Worker worker;
  EXPECT_EQ(RunThreadFirst(worker.thread(), 0), "real-time priority 0 is outside 1-99");
  EXPECT_EQ(RunThreadFirst(worker.thread(), 100), "real-time priority 100 is outside 1-99");
  EXPECT_EQ(worker.Finish().first, SCHED_OTHER);
}

}  // namespace
}  // namespace mirrorscan
