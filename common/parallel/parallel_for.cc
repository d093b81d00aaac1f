#include "common/parallel/parallel_for.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace mirrorscan {

int ResolveThreads(int requested) {
  if (requested > 0) return requested;
  return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

size_t ChunkCount(size_t n, int threads) {
  if (n == 0) return 0;
  const size_t per_thread = threads > 1 ? 8 : 1;
  return std::min(n, static_cast<size_t>(std::max(1, threads)) * per_thread);
}

void ForEachChunk(size_t n, int threads,
                  const std::function<void(size_t chunk, size_t begin, size_t end)>& body) {
  const size_t chunks = ChunkCount(n, threads);
  if (chunks == 0) return;
  auto range = [&](size_t c, size_t* begin, size_t* end) {
    *begin = n * c / chunks;
    *end = n * (c + 1) / chunks;
  };
  if (chunks == 1 || threads <= 1) {
    for (size_t c = 0; c < chunks; ++c) {
      size_t begin, end;
      range(c, &begin, &end);
      body(c, begin, end);
    }
    return;
  }
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&] {
    for (size_t c = next++; c < chunks && !failed; c = next++) {
      size_t begin, end;
      range(c, &begin, &end);
      try {
        body(c, begin, end);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  const size_t helpers = std::min<size_t>(static_cast<size_t>(threads), chunks) - 1;
  std::vector<std::thread> pool;
  pool.reserve(helpers);
  for (size_t t = 0; t < helpers; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

}  // namespace mirrorscan
