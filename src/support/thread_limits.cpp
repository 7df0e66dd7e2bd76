#include "support/thread_limits.hpp"

#include "support/threads.hpp"

#include <pthread.h>
#include <sys/resource.h>

#include <algorithm>
#include <condition_variable>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace m3c2::detail {
namespace {

constexpr int kThreadsPerHardwareThread = 4;
constexpr int kMaxThreads = 1024;

/// libgomp keeps a team's threads (all but the caller) idle after a region and reuses them for
/// the calling thread's next one; a smaller team ends the surplus. So a region of n threads
/// creates max(0, n - 1 - kept) new ones. Per calling thread, as libgomp's pools are.
thread_local int kept_by_openmp = 0;

/// Serialises probe + team start among runs in one process (OpenMpTeam).
std::mutex probe_lock;

/// A number from a small text file (pids.max, pids.current); "max" or unreadable: -1.
long read_count(const std::string& path) {
  std::ifstream in(path);
  long v = -1;
  if (!(in >> v)) return -1;
  return v;
}

/// Threads of the whole system (the denominator of /proc/loadavg's "running/total"): an upper
/// bound on the threads of this user, which RLIMIT_NPROC counts. -1 when unknown.
long system_threads() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c, running;
  if (!(in >> a >> b >> c >> running)) return -1;
  const auto slash = running.find('/');
  if (slash == std::string::npos) return -1;
  try {
    return std::stol(running.substr(slash + 1));
  } catch (...) {
    return -1;
  }
}

/// The cgroup v2 folder of this process (its "0::/path" line), else the v1 pids controller's.
std::vector<std::string> pids_folders() {
  std::vector<std::string> out;
  std::ifstream in("/proc/self/cgroup");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("0::", 0) == 0) out.push_back("/sys/fs/cgroup" + line.substr(3));
  out.push_back("/sys/fs/cgroup");
  out.push_back("/sys/fs/cgroup/pids");
  return out;
}

/// Whether creating `extra` threads might hit a limit: RLIMIT_NPROC within reach of the
/// system's thread count, or a cgroup's pids.max within reach of its pids.current. Cheap
/// (getrlimit and a few small /proc, /sys reads), so only runs near a limit pay for a probe.
bool near_a_limit(int extra) {
  rlimit r{};
  if (getrlimit(RLIMIT_NPROC, &r) == 0 && r.rlim_cur != RLIM_INFINITY) {
    const long used = system_threads();
    if (used < 0 || static_cast<rlim_t>(used) + static_cast<rlim_t>(extra) >= r.rlim_cur) return true;
  }
  for (const std::string& folder : pids_folders()) {
    std::ifstream exists(folder + "/pids.max");
    if (!exists) continue;
    const long max = read_count(folder + "/pids.max");  // "max": -1, no limit
    if (max < 0) return false;
    const long current = read_count(folder + "/pids.current");
    return current < 0 || current + extra >= max;
  }
  return false;
}

/// Threads that block until released, so that all of them exist at once.
struct Gate {
  std::mutex m;
  std::condition_variable cv;
  bool open = false;
};

void* wait_at_gate(void* arg) {
  auto* gate = static_cast<Gate*>(arg);
  std::unique_lock lock(gate->m);
  gate->cv.wait(lock, [&] { return gate->open; });
  return nullptr;
}

/// How many of `n` threads can exist at once now (each created, kept waiting, then joined).
int creatable_threads(int n) {
  Gate gate;
  pthread_attr_t attr;
  pthread_attr_init(&attr);
  pthread_attr_setstacksize(&attr, 64 * 1024);  // a probe needs no stack; the count is what matters
  std::vector<pthread_t> made;
  made.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    pthread_t t;
    if (pthread_create(&t, &attr, wait_at_gate, &gate) != 0) break;
    made.push_back(t);
  }
  pthread_attr_destroy(&attr);
  {
    std::lock_guard lock(gate.m);
    gate.open = true;
  }
  gate.cv.notify_all();
  for (const pthread_t t : made) pthread_join(t, nullptr);
  return static_cast<int>(made.size());
}

}  // namespace

int thread_cap() {
  const unsigned hardware = std::max(1u, std::thread::hardware_concurrency());
  return static_cast<int>(std::min<unsigned>(kMaxThreads, kThreadsPerHardwareThread * hardware));
}

int requested_threads(const RunOptions& run) {
  const int wanted = run.threads > 0 ? run.threads : max_threads();
  return std::clamp(wanted, 1, thread_cap());
}

OpenMpTeam::OpenMpTeam(int want) {
#if !defined(_OPENMP)
  want = 1;  // a serial build starts no thread
#endif
  want = std::clamp(want, 1, thread_cap());
  if (want < 2) return;
  const int to_create = want - 1 - kept_by_openmp;
  size_ = want;
  if (to_create > 0 && near_a_limit(to_create)) {
    probing_ = std::unique_lock(probe_lock);
    size_ = std::min(want, 1 + kept_by_openmp + creatable_threads(to_create));
  }
  if (size_ >= 2) kept_by_openmp = size_ - 1;
}

void OpenMpTeam::started() {
  kept_by_openmp = team_size() - 1;  // OMP_THREAD_LIMIT or OMP_DYNAMIC may give fewer
  if (probing_.owns_lock()) probing_.unlock();
}

}  // namespace m3c2::detail
