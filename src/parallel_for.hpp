#pragma once
// The one parallel loop of the engine: fixed blocks, results written by index, so the output
// does not depend on the thread count; exceptions and cancellation are carried out of OpenMP.

#include <m3c2/errors.hpp>
#include <m3c2/run_options.hpp>

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>

namespace m3c2::detail {

/// Calls fn(begin, end, thread_id) on consecutive blocks of [0, n). run.progress, if set, is
/// called under a lock after each block with the number of items done; when it returns false
/// the remaining blocks are skipped and Cancelled is thrown. `Scratch` is default-constructed
/// once per thread and passed to fn, for buffers reused across items.
template <class Scratch, class Fn>
void parallel_blocks(std::size_t n, const RunOptions& run, Fn&& fn, std::size_t block = 64) {
  const int threads = run.threads > 0 ? run.threads : omp_get_max_threads();
  const auto blocks = static_cast<std::int64_t>((n + block - 1) / block);
  std::exception_ptr failure;
  std::atomic<bool> stop{false};
  std::mutex lock;
  std::size_t done = 0;
#pragma omp parallel num_threads(threads)
  {
    Scratch scratch;
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t b = 0; b < blocks; ++b) {
      if (stop.load(std::memory_order_relaxed)) continue;
      const std::size_t begin = std::size_t(b) * block, end = std::min(n, begin + block);
      try {
        fn(begin, end, scratch);
        if (run.progress) {
          std::lock_guard guard(lock);
          done += end - begin;
          if (!stop && !run.progress(done, n)) stop = true;
        }
      } catch (...) {
        std::lock_guard guard(lock);
        if (!failure) failure = std::current_exception();
        stop = true;
      }
    }
  }
  if (failure) std::rethrow_exception(failure);
  if (stop) throw Cancelled();
}

}  // namespace m3c2::detail
