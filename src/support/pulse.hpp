#pragma once
// Progress and cancellation shared by the threads of one parallel loop, and the Pulse that lets
// a long computation inside one item (a large bootstrap, Appendix B) be cancelled mid-item.

#include <m3c2/errors.hpp>
#include <m3c2/run_options.hpp>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <mutex>

namespace m3c2::detail {

/// The state of one parallel loop of n items: run.progress is called under `lock`, never
/// concurrently with itself; once it returns false `stop` is set and stays set.
struct LoopControl {
  LoopControl(const RunOptions& r, std::size_t items) : run(r), n(items) {}
  /// Adds `items` finished ones and reports them; false when the loop is to stop.
  bool finished(std::size_t items) {
    std::lock_guard guard(lock);
    done += items;
    return report();
  }
  /// Reports the items done so far again (a thread in a long item); false when the loop is to stop.
  bool poll() {
    std::lock_guard guard(lock);
    return report();
  }

  const RunOptions& run;
  const std::size_t n;
  std::atomic<bool> stop{false};
  std::mutex lock;
  std::size_t done = 0;

 private:
  bool report() {
    if (!stop && run.progress && !run.progress(done, n)) stop = true;
    return !stop;
  }
};

/// One thread's handle on its loop, for code that may run long inside one item: beat() costs
/// a counter increment; every kStride beats it reads the clock and, at most every kInterval on
/// this thread, calls run.progress (which is where a Python caller notices Ctrl-C and SIGTERM,
/// on the thread that started the run: each thread polls on its own). Throws Cancelled once
/// the run is to stop. A default Pulse (no loop) never polls.
class Pulse {
 public:
  Pulse() = default;
  explicit Pulse(LoopControl* control) : control_(control), last_(std::chrono::steady_clock::now()) {}

  void beat() {
    if (control_ == nullptr || ++count_ % kStride != 0) return;
    if (control_->stop.load(std::memory_order_relaxed)) throw Cancelled();
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < kInterval) return;
    last_ = now;
    if (!control_->poll()) throw Cancelled();
  }

 private:
  static constexpr unsigned kStride = 16;
  static constexpr auto kInterval = std::chrono::milliseconds(100);
  LoopControl* control_ = nullptr;
  unsigned count_ = 0;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace m3c2::detail
