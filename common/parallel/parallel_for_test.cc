#include "common/parallel/parallel_for.h"

#include <atomic>
#include <mutex>
#include <numeric>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace mirrorscan {
namespace {

TEST(ParallelFor, VisitsEveryIndexExactlyOnce) {
  for (int threads : {1, 2, 3, 8}) {
    for (size_t n : {size_t{0}, size_t{1}, size_t{7}, size_t{1000}, size_t{100003}}) {
      std::vector<std::atomic<int>> visits(n);
      ParallelFor(n, threads, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i) ++visits[i];
      });
      for (size_t i = 0; i < n; ++i)
        ASSERT_EQ(visits[i].load(), 1) << "index " << i << " of " << n << ", " << threads;
    }
  }
}

TEST(ParallelFor, ChunksAreContiguousAndTheSameForAnyThreadCount) {
  const size_t n = 12345;
  // The ranges are fixed by the chunk's index and the chunk count alone.
  auto ranges = [&](int threads) {
    std::vector<std::pair<size_t, size_t>> r(ChunkCount(n, threads));
    ForEachChunk(n, threads, [&](size_t c, size_t begin, size_t end) { r[c] = {begin, end}; });
    return r;
  };
  for (int threads : {1, 2, 4}) {
    const auto r = ranges(threads);
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(r.front().first, 0u);
    EXPECT_EQ(r.back().second, n);
    for (size_t c = 1; c < r.size(); ++c) EXPECT_EQ(r[c].first, r[c - 1].second);
  }
  // Ordered gathering: per-chunk sums in chunk order give the serial prefix sums.
  std::vector<size_t> sums(ChunkCount(n, 2));
  ForEachChunk(n, 2, [&](size_t c, size_t begin, size_t end) {
    for (size_t i = begin; i < end; ++i) sums[c] += i;
  });
  EXPECT_EQ(std::accumulate(sums.begin(), sums.end(), size_t{0}), n * (n - 1) / 2);
}

TEST(ParallelFor, UsesMoreThanOneThreadWhenAsked) {
  std::mutex m;
  std::set<std::thread::id> ids;
  std::atomic<int> inside{0};
  std::atomic<bool> overlapped{false};
  ParallelFor(64, 2, [&](size_t, size_t) {
    if (++inside > 1) overlapped = true;
    {
      const std::lock_guard<std::mutex> lock(m);
      ids.insert(std::this_thread::get_id());
    }
    // Long enough for the other thread to take a chunk meanwhile.
    for (int i = 0; i < 200 && !overlapped; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    --inside;
  });
  EXPECT_EQ(ids.size(), 2u);
  EXPECT_TRUE(overlapped);
}

TEST(ParallelFor, RethrowsTheBodysExceptionAfterEveryThreadStopped) {
  for (int threads : {1, 2}) {
    std::atomic<int> running{0};
    EXPECT_THROW(ParallelFor(1000, threads,
                             [&](size_t, size_t end) {
                               ++running;
                               if (end > 600) {
                                 --running;
                                 throw std::runtime_error("bad chunk");
                               }
                               // Still running here when the throw is rethrown would be
                               // a thread left behind.
                               std::this_thread::sleep_for(std::chrono::milliseconds(2));
                               --running;
                             }),
                 std::runtime_error);
    EXPECT_EQ(running.load(), 0);
  }
}

TEST(ParallelFor, ResolvesThreads) {
  EXPECT_EQ(ResolveThreads(3), 3);
  EXPECT_GE(ResolveThreads(0), 1);
  EXPECT_EQ(ChunkCount(0, 2), 0u);
  EXPECT_EQ(ChunkCount(5, 2), 5u);
  EXPECT_EQ(ChunkCount(1000, 1), 1u);
}

}  // namespace
}  // namespace mirrorscan
