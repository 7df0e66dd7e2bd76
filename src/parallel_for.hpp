#pragma once
// The one parallel loop of the engine: fixed blocks, results written by index, so the output
// does not depend on the thread count; exceptions and cancellation are carried out of OpenMP.

#include <m3c2/errors.hpp>
#include <m3c2/run_options.hpp>

#include "threads.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>

namespace m3c2::detail {

/// Calls fn(begin, end, scratch) on consecutive blocks of [0, n). run.progress, if set, is
/// called under a lock after each block with the number of items done; when it returns false
/// the remaining blocks are skipped and Cancelled is thrown. `Scratch` is default-constructed
/// once per thread and passed to fn, for buffers reused across items.
///
/// The first blocks run on the calling thread alone, for up to kSerialLead: only what is left
/// after that is shared among the threads. Waking and joining the OpenMP team costs ~0.1 ms on
/// an idle machine but up to a scheduler time slice (measured: ~28 ms per call with 2 threads
/// on the shared 2-core machine under load, against ~1 ms for the whole run on one thread),
/// which small runs (a few hundred core points) then pay many times over. A long run loses at
/// most kSerialLead * (threads - 1) / threads. A caller whose team has just run (and so spins,
/// awake) passes `team_awake` and skips the lead. Which thread runs a block never changes its bits.
template <class Scratch, class Fn>
void parallel_blocks(std::size_t n, const RunOptions& run, Fn&& fn, std::size_t block = 64, bool team_awake = false) {
  constexpr auto kSerialLead = std::chrono::milliseconds(2);
  const int threads = run.threads > 0 ? run.threads : max_threads();
  const auto blocks = static_cast<std::int64_t>((n + block - 1) / block);
  std::exception_ptr failure;
  std::atomic<bool> stop{false};
  std::mutex lock;
  std::size_t done = 0;
  const auto run_block = [&](std::int64_t b, Scratch& scratch) {
    if (stop.load(std::memory_order_relaxed)) return;
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
  };
  std::int64_t first = 0;  // blocks before this one ran serially
  {
    Scratch scratch;
    const auto start = std::chrono::steady_clock::now();
    while (first < blocks && !stop.load(std::memory_order_relaxed) &&
           (threads <= 1 || (!team_awake && std::chrono::steady_clock::now() - start < kSerialLead)))
      run_block(first++, scratch);
  }
  if (first < blocks && !stop.load(std::memory_order_relaxed)) {
    // Without OpenMP (a serial build) the pragmas are not compiled: one thread runs every block.
#if defined(_OPENMP)
#pragma omp parallel num_threads(threads)
#endif
    {
      Scratch scratch;
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
      for (std::int64_t b = first; b < blocks; ++b) run_block(b, scratch);
    }
  }
  if (failure) std::rethrow_exception(failure);
  if (stop) throw Cancelled();
}

}  // namespace m3c2::detail
