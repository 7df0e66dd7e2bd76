#pragma once
// How a computation runs (not what it computes): threads, progress and cancellation.

#include <cstddef>
#include <functional>

namespace m3c2 {

/// Called with (done, total) core points, never concurrently with itself, a few hundred times
/// per run and, while one core point takes long (a large bootstrap), about every 0.1 s with
/// `done` unchanged, on the caller's thread among others. Return false to cancel: the run then
/// throws m3c2::Cancelled.
using ProgressCallback = std::function<bool(std::size_t done, std::size_t total)>;

struct RunOptions {
  /// 0 = all hardware threads; results are bit-identical for any value. At most 4 per hardware
  /// thread and 1024 are started (a larger value is clamped), and fewer when the process cannot
  /// create more (RLIMIT_NPROC, a cgroup's pids.max): src/threads.hpp.
  int threads = 0;
  ProgressCallback progress;
};

}  // namespace m3c2
