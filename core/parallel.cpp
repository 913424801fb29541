#include "core/parallel.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <memory>
#include <mutex>

#include "core/check.h"

namespace genscene {

namespace {

std::mutex g_mutex;
std::unique_ptr<tbb::global_control> g_control;
int g_threads = 0;

}  // namespace

void SetThreadCount(int threads) {
  if (threads < 0) throw Error(Format("thread count ", threads, " must be >= 0 (0 = all cores)"));
  std::lock_guard<std::mutex> lock(g_mutex);
  g_control.reset();
  g_threads = threads;
  if (threads > 0) {
    g_control = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                      static_cast<size_t>(threads));
  }
}

int ThreadCount() {
  std::lock_guard<std::mutex> lock(g_mutex);
  return g_threads > 0 ? g_threads : tbb::info::default_concurrency();
}

void ParallelForChunks(size_t begin, size_t end, size_t grain,
                       const std::function<void(size_t, size_t)>& body) {
  if (end <= begin) return;
  if (grain == 0) grain = 1;
  tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, grain),
                    [&body](const tbb::blocked_range<size_t>& r) { body(r.begin(), r.end()); });
}

}  // namespace genscene
