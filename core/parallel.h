// The one parallel-for of the project (STYLE.md 3), on TBB. Kernels are small pure functions;
// loops call them through ParallelFor. Reductions use DeterministicReduce, whose chunking does
// not depend on the thread count, so float sums come out bit-identical with 1 or N threads.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

namespace genscene {

// Limits the worker threads of every later ParallelFor (0 = all cores). Lasts until changed.
void SetThreadCount(int threads);
// Worker threads currently allowed.
int ThreadCount();

// Calls body(chunk_begin, chunk_end) over [begin, end) split into chunks of at most `grain`.
void ParallelForChunks(size_t begin, size_t end, size_t grain,
                       const std::function<void(size_t, size_t)>& body);

// Calls body(i) for every i in [begin, end), in parallel. Writes from body(i) must go to
// distinct locations.
template <typename Body>
void ParallelFor(size_t begin, size_t end, const Body& body, size_t grain = 256) {
  ParallelForChunks(begin, end, grain, [&body](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) body(i);
  });
}

// Reduction with a fixed order: [0, n) is cut into chunks of `chunk` indices (independent of the
// thread count), map_chunk(begin, end) runs per chunk in parallel, then the partial results are
// combined left to right: combine(combine(p0, p1), p2) ...
template <typename T, typename MapChunk, typename Combine>
T DeterministicReduce(size_t n, size_t chunk, const T& identity, const MapChunk& map_chunk,
                      const Combine& combine) {
  if (chunk == 0) chunk = 1;
  const size_t chunks = (n + chunk - 1) / chunk;
  std::vector<T> partial(chunks, identity);
  ParallelFor(
      0, chunks, [&](size_t c) { partial[c] = map_chunk(c * chunk, std::min(n, (c + 1) * chunk)); },
      1);
  T result = identity;
  for (const T& p : partial) result = combine(result, p);
  return result;
}

}  // namespace genscene
