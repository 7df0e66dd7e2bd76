#pragma once
// The one parallel loop of the engine: fixed blocks, results written by index, so the output
// does not depend on the thread count; exceptions and cancellation are carried out of OpenMP.

#include <m3c2/errors.hpp>
#include <m3c2/run_options.hpp>

#include "support/pulse.hpp"
#include "support/thread_limits.hpp"
#include "support/threads.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <type_traits>

namespace m3c2::detail {

/// Calls fn(begin, end, scratch) on consecutive blocks of [0, n). run.progress, if set, is
/// called under a lock after each block with the number of items done; when it returns false
/// the remaining blocks are skipped and Cancelled is thrown. `Scratch` is default-constructed
/// once per thread and passed to fn, for buffers reused across items; fn may take a fourth
/// argument, the thread's Pulse, to be cancellable inside a long item (pulse.hpp). The team is
/// requested_threads(run), or fewer when the process cannot create that many (threads.hpp).
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
  constexpr auto kCallerPoll = std::chrono::milliseconds(100);
  const int threads = requested_threads(run);
  const auto blocks = static_cast<std::int64_t>((n + block - 1) / block);
  std::exception_ptr failure;
  LoopControl control(run, n);
  const auto run_block = [&](std::int64_t b, Scratch& scratch, Pulse& pulse) {
    if (control.stop.load(std::memory_order_relaxed)) return;
    const std::size_t begin = std::size_t(b) * block, end = std::min(n, begin + block);
    try {
      if constexpr (std::is_invocable_v<Fn&, std::size_t, std::size_t, Scratch&, Pulse&>)
        fn(begin, end, scratch, pulse);
      else
        fn(begin, end, scratch);
      if (run.progress && !control.finished(end - begin)) control.stop = true;
    } catch (...) {
      std::lock_guard guard(control.lock);
      if (!failure) failure = std::current_exception();
      control.stop = true;
    }
  };
  std::int64_t first = 0;  // blocks before this one ran serially
  const auto serial = [&](bool lead) {
    Scratch scratch;
    Pulse pulse(&control);
    const auto start = std::chrono::steady_clock::now();
    while (first < blocks && !control.stop.load(std::memory_order_relaxed) &&
           (!lead || (!team_awake && std::chrono::steady_clock::now() - start < kSerialLead)))
      run_block(first++, scratch, pulse);
  };
  serial(threads > 1);
  if (first < blocks && !control.stop.load(std::memory_order_relaxed)) {
    OpenMpTeam team(threads);
    if (team.size() < 2) {
      serial(false);  // the process cannot create another thread now
    } else {
      // Blocks done or skipped; the thread that finishes the last one wakes thread 0's watch.
      std::atomic<std::int64_t> finished{first};
      std::mutex watch_lock;
      std::condition_variable all_done;
      // Without OpenMP (a serial build) the pragmas are not compiled: one thread runs every block.
#if defined(_OPENMP)
#pragma omp parallel num_threads(team.size())
#endif
      {
        const bool caller = thread_num() == 0;
        if (caller) team.started();
        Scratch scratch;
        Pulse pulse(&control);
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1) nowait
#endif
        for (std::int64_t b = first; b < blocks; ++b) {
          run_block(b, scratch, pulse);
          if (finished.fetch_add(1) + 1 == blocks) {
            std::lock_guard guard(watch_lock);
            all_done.notify_all();
          }
        }
        // Thread 0 is the caller's thread, the only one on which a Python caller's progress
        // callback can notice Ctrl-C and SIGTERM: once out of blocks it keeps polling while
        // the others finish theirs (one long core point would otherwise run to its end).
        if (caller && run.progress) {
          std::unique_lock wait(watch_lock);
          while (!all_done.wait_for(wait, kCallerPoll, [&] { return finished.load() >= blocks; })) {
            wait.unlock();
            control.poll();
            wait.lock();
          }
        }
      }
    }
  }
  if (failure) std::rethrow_exception(failure);
  if (control.stop) throw Cancelled();
}

}  // namespace m3c2::detail
