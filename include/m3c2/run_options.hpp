#pragma once
// How a computation runs (not what it computes): threads, progress and cancellation.

#include <cstddef>
#include <functional>

namespace m3c2 {

/// Called with (done, total) core points, never concurrently with itself and at most a few
/// hundred times per run. Return false to cancel: the run then throws m3c2::Cancelled.
using ProgressCallback = std::function<bool(std::size_t done, std::size_t total)>;

struct RunOptions {
  int threads = 0;  ///< 0 = all hardware threads; results are bit-identical for any value
  ProgressCallback progress;
};

}  // namespace m3c2
