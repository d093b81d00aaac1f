#include "firmware/service/connection_guard.h"

#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

namespace mirrorscan::service {
namespace {

using std::chrono::milliseconds;

// A connected socket pair: shutting one end down is what the table does to evict.
struct SocketPair {
  SocketPair() { EXPECT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, fds), 0); }
  ~SocketPair() {
    ::close(fds[0]);
    ::close(fds[1]);
  }
  // True when the server end was shut down: the peer reads end-of-file at once.
  bool ShutDown() const {
    char byte;
    return ::recv(fds[1], &byte, 1, MSG_DONTWAIT) == 0;
  }
  int fds[2];
};

TEST(ConnectionTable, RefusesPastThePerClientLimit) {
  ConnectionLimits limits;
  limits.per_client = 2;
  limits.total = 10;
  ConnectionTable table(limits);
  SocketPair a, b, c, d;
  uint64_t id = 0;
  EXPECT_EQ(table.Admit("10.0.0.2", a.fds[0], id), ConnectionTable::Admission::kAdmitted);
  EXPECT_EQ(table.Admit("10.0.0.2", b.fds[0], id), ConnectionTable::Admission::kAdmitted);
  EXPECT_EQ(table.Admit("10.0.0.2", c.fds[0], id), ConnectionTable::Admission::kClientFull);
  EXPECT_EQ(table.Admit("10.0.0.3", d.fds[0], id), ConnectionTable::Admission::kAdmitted);
  EXPECT_EQ(table.count_for("10.0.0.2"), 2);
  EXPECT_EQ(table.refused(), 1u);
  // A refused client evicts nobody.
  EXPECT_FALSE(a.ShutDown());
  EXPECT_FALSE(b.ShutDown());
  table.Release(id);
  EXPECT_EQ(table.count_for("10.0.0.3"), 0);
}

TEST(ConnectionTable, AtTheTotalTheLongestIdleConnectionMakesRoom) {
  ConnectionLimits limits;
  limits.per_client = 2;
  limits.total = 3;
  ConnectionTable table(limits);
  SocketPair busy, idle_old, idle_new, fresh;
  uint64_t busy_id = 0, old_id = 0, new_id = 0, fresh_id = 0;
  ASSERT_EQ(table.Admit("a", busy.fds[0], busy_id), ConnectionTable::Admission::kAdmitted);
  ASSERT_EQ(table.Admit("b", idle_old.fds[0], old_id), ConnectionTable::Admission::kAdmitted);
  ASSERT_EQ(table.Admit("c", idle_new.fds[0], new_id), ConnectionTable::Admission::kAdmitted);
  table.SetIdle(busy_id, false);  // serving a request: never evicted
  ASSERT_EQ(table.Admit("d", fresh.fds[0], fresh_id), ConnectionTable::Admission::kAdmitted);
  EXPECT_TRUE(idle_old.ShutDown());
  EXPECT_FALSE(idle_new.ShutDown());
  EXPECT_FALSE(busy.ShutDown());
  EXPECT_EQ(table.evicted(), 1u);
}

TEST(ConnectionTable, TheClientHoldingTheMostLosesOneFirst) {
  ConnectionLimits limits;
  limits.per_client = 3;
  limits.total = 3;
  ConnectionTable table(limits);
  SocketPair lone, heavy1, heavy2, fresh;
  uint64_t id = 0;
  ASSERT_EQ(table.Admit("lone", lone.fds[0], id), ConnectionTable::Admission::kAdmitted);
  ASSERT_EQ(table.Admit("heavy", heavy1.fds[0], id), ConnectionTable::Admission::kAdmitted);
  ASSERT_EQ(table.Admit("heavy", heavy2.fds[0], id), ConnectionTable::Admission::kAdmitted);
  ASSERT_EQ(table.Admit("new", fresh.fds[0], id), ConnectionTable::Admission::kAdmitted);
  EXPECT_FALSE(lone.ShutDown());  // older, but its client holds only one
  EXPECT_TRUE(heavy1.ShutDown());
  EXPECT_FALSE(heavy2.ShutDown());
}

TEST(ConnectionTable, AllBusyRefusesAndStopShutsEverythingDown) {
  ConnectionLimits limits;
  limits.per_client = 1;
  limits.total = 1;
  ConnectionTable table(limits);
  SocketPair first, second;
  uint64_t id = 0, other = 0;
  ASSERT_EQ(table.Admit("a", first.fds[0], id), ConnectionTable::Admission::kAdmitted);
  table.SetIdle(id, false);
  EXPECT_EQ(table.Admit("b", second.fds[0], other), ConnectionTable::Admission::kClientFull);
  table.ShutdownAll();
  EXPECT_TRUE(first.ShutDown());
  EXPECT_EQ(table.Admit("b", second.fds[0], other), ConnectionTable::Admission::kStopping);
}

TEST(ConnectionLimits, ValidateNamesTheField) {
  ConnectionLimits limits;
  limits.total = 2;
  limits.per_client = 3;
  EXPECT_THROW(limits.Validate(), std::invalid_argument);
  limits.total = 8;
  limits.header_timeout = milliseconds(0);
  EXPECT_THROW(limits.Validate(), std::invalid_argument);
}

TEST(FailedTokenLimiter, BurstThenOneTryPerRefill) {
  auto now = std::chrono::steady_clock::time_point{} + std::chrono::hours(1);
  FailedTokenLimiter::Options options;
  options.burst = 3;
  options.refill = milliseconds(1000);
  FailedTokenLimiter limiter(options, [&] { return now; });
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(limiter.RetryAfterMs("x"), 0) << i;
    limiter.RecordFailure("x");
  }
  EXPECT_GT(limiter.RetryAfterMs("x"), 900);
  EXPECT_EQ(limiter.RetryAfterMs("y"), 0);  // other addresses are not affected
  now += milliseconds(500);
  EXPECT_GT(limiter.RetryAfterMs("x"), 400);
  now += milliseconds(501);
  EXPECT_EQ(limiter.RetryAfterMs("x"), 0);
  limiter.RecordFailure("x");
  EXPECT_GT(limiter.RetryAfterMs("x"), 0);
}

TEST(FailedTokenLimiter, RemembersABoundedNumberOfAddresses) {
  FailedTokenLimiter::Options options;
  options.burst = 1;
  options.max_clients = 4;
  FailedTokenLimiter limiter(options);
  for (int i = 0; i < 100; ++i) limiter.RecordFailure("10.0.0." + std::to_string(i));
  // The newest addresses are still limited; memory stayed at four buckets.
  EXPECT_GT(limiter.RetryAfterMs("10.0.0.99"), 0);
}

}  // namespace
}  // namespace mirrorscan::service
