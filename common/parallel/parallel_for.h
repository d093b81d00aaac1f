#pragma once
// A loop over [0, n) cut into contiguous chunks that a few threads take in turn. Chunk c is
// always the same range whatever thread runs it, so per-chunk results gathered in chunk
// order are the same for any thread count (the reconstruction's cloud is byte-identical on
// 1 or 2 threads). Threads are started per call: the calls this is for take milliseconds,
// starting a thread tens of microseconds, and nothing spins while waiting.
#include <cstddef>
#include <functional>

namespace mirrorscan {

// Threads to use for `requested`: itself when > 0, else every core (at least 1).
int ResolveThreads(int requested);

// The number of chunks ForEachChunk cuts n items into for this many threads: a few per
// thread, so an uneven chunk does not leave the others idle; never more than n.
size_t ChunkCount(size_t n, int threads);

// Calls body(chunk, begin, end) once for every chunk of ChunkCount(n, threads), on up to
// `threads` threads (the caller's among them). The first exception a body throws is
// rethrown here once every thread has stopped; chunks not yet started are then skipped.
void ForEachChunk(size_t n, int threads,
                  const std::function<void(size_t chunk, size_t begin, size_t end)>& body);

// The same without the chunk's index: body(begin, end).
inline void ParallelFor(size_t n, int threads,
                        const std::function<void(size_t begin, size_t end)>& body) {
  ForEachChunk(n, threads, [&](size_t, size_t begin, size_t end) { body(begin, end); });
}

}  // namespace mirrorscan
