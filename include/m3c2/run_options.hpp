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
  /// create more (RLIMIT_NPROC, a cgroup's pids.max): src/support/threads.hpp.
  int threads = 0;
  ProgressCallback progress;
  /// compute() may order the reference's and the compared cloud's arrays in place (their rows
  /// in its index's key order) instead of copying them, 24 B per point less, and puts every row
  /// back before it returns or throws: for arrays the caller owns, writeable, that nothing else
  /// reads during the call. The results are the same bits. A cloud read by input order during
  /// the run (normal subsampling, the uncertainty models' inputs) or sharing memory with the
  /// other cloud or with core points other than the reference itself is copied anyway.
  bool order_clouds_in_place = false;
};

}  // namespace m3c2
