#pragma once
// How many threads a run may start: a cap on what the caller asks for, and the threads the
// process can actually create now (libgomp aborts the whole process, Python interpreter
// included, when it cannot create a thread of a team).

#include <m3c2/run_options.hpp>

#include <mutex>

namespace m3c2::detail {

/// The most threads a run starts: 4 per hardware thread (std::thread::hardware_concurrency),
/// at most 1024. More threads than that only add memory (a stack each) and scheduling; results
/// are the same bits for any count, so a larger request is clamped, not refused.
int thread_cap();

/// run.threads (0: OpenMP's default, all hardware threads) clamped to [1, thread_cap()].
int requested_threads(const RunOptions& run);

/// The team of one OpenMP parallel region started by the calling thread (a serial build: 1). Construct it right
/// before `#pragma omp parallel num_threads(team.size())` and call started() from thread 0 at
/// the top of the region. size() is `want`, or fewer when the process may not create that many
/// threads now: under a thread limit close to the process's use (RLIMIT_NPROC, a cgroup's
/// pids.max), the threads the region would create are first created here as a probe and joined,
/// and the team is what the probe could create (at least 1: the caller alone). Probes and team
/// starts are serialised so that two runs in one process do not both count the same free slots.
class OpenMpTeam {
 public:
  explicit OpenMpTeam(int want);
  int size() const { return size_; }
  /// The team's threads exist: lets another run probe (call on thread 0 inside the region).
  void started();

 private:
  int size_ = 1;
  std::unique_lock<std::mutex> probing_;
};

}  // namespace m3c2::detail
