// Resources a parameter sizes are bounded (issue 15, docs/errors.md "Run limits"): thread
// counts are clamped to thread_cap() with the same bits, bootstrap resamples are capped, and a
// long bootstrap inside one core point is cancellable.

#include "pipeline/validation.hpp"
#include "support/thread_limits.hpp"
#include "test_support.hpp"

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <thread>

namespace m3c2::test {
namespace {

TEST(RunLimits, ThreadCapIsFourPerHardwareThreadAndAtMost1024) {
  const int hardware = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  EXPECT_EQ(detail::thread_cap(), std::min(1024, 4 * hardware));
  EXPECT_EQ(detail::requested_threads(with_threads(100000)), detail::thread_cap());
  EXPECT_EQ(detail::requested_threads(with_threads(1)), 1);
  EXPECT_GE(detail::requested_threads(with_threads(0)), 1);
}

// --threads 100000 ended in SIGSEGV and threads=10**8 killed the Python interpreter: libgomp
// was asked for that many threads. Now clamped, and every count gives the same bits.
TEST(RunLimits, HugeThreadCountsRunAndGiveTheSameBits) {
  const Pair pr = rough_pair(21, 3000);
  Params p = basic_params(1.0, 0.5, 2.0);
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 20;
  const Result one = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(1));
  for (const int threads : {100000, 100000000, 2147483647}) {
    const Result many = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(threads));
    EXPECT_TRUE(BitIdentical(one.distance, many.distance)) << threads;
    EXPECT_TRUE(BitIdentical(one.lod, many.lod)) << threads;
    EXPECT_TRUE(BitIdentical(one.normal, many.normal)) << threads;
    const NormalsResult normals = compute_normals(pr.reference.view(), pr.cores.view(), p, with_threads(threads));
    EXPECT_TRUE(BitIdentical(one.normal_scale, normals.normal_scale)) << threads;
  }
  std::size_t ok = 0;
  for (const PointStatus s : one.status) ok += s == PointStatus::kOk;
  EXPECT_GT(ok, one.size() / 2);
}

TEST(RunLimits, BootstrapAboveTheMaximumIsRefusedBeforeTheRun) {
  const Pair pr = rough_pair(22, 500);
  Params p = basic_params(1.0, 0.5, 2.0);
  p.bootstrap_samples = kMaxBootstrapSamples;
  EXPECT_NO_THROW(detail::validate_params(p));
  p.bootstrap_samples = kMaxBootstrapSamples + 1;
  try {
    compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(1));
    FAIL() << "accepted " << p.bootstrap_samples << " resamples";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(std::string(e.what()), "bootstrap_samples must be at most 100000, got 100001");
  }
}

// --bootstrap 1000000000 ignored SIGINT and SIGTERM: cancellation was only checked between
// blocks of core points. Now the bootstrap polls the progress callback (where Python notices
// signals) inside its resample loop: here the one core point's bootstrap (~10^8 draws) is
// cancelled by the first poll, which comes before the core point is done (done == 0).
struct LongBootstrap {
  Cloud reference, compared, core;
  Params p;
};

LongBootstrap long_bootstrap() {
  LongBootstrap b;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int i = 0; i < 2000; ++i) {
    b.reference.add(u(rng), u(rng), u(rng));
    b.compared.add(u(rng), u(rng), 0.5 + u(rng));
  }
  b.core.add(0.0, 0.0, 0.0);
  b.p.normal_source = NormalSource::kVertical;
  b.p.projection_diameter = 1.0;
  b.p.max_depth = 2.0;
  b.p.lod = Lod::kBootstrap;
  b.p.bootstrap_samples = kMaxBootstrapSamples;
  return b;
}

// A Python caller notices signals only on its own thread (the one that called compute): when
// another thread of the team runs the long core point, the caller's thread keeps polling.
TEST(RunLimits, TheCallersThreadPollsWhileAnotherThreadRunsALongCorePoint) {
  const LongBootstrap b = long_bootstrap();
  const auto caller = std::this_thread::get_id();
  for (int trial = 0; trial < 4; ++trial) {  // which thread takes the block varies
    std::size_t caller_polls = 0;
    RunOptions run;
    run.threads = 2;
    run.progress = [&](std::size_t done, std::size_t) {
      if (std::this_thread::get_id() != caller) return true;
      caller_polls += done == 0;
      return false;
    };
    EXPECT_THROW(compute(b.reference.view(), b.compared.view(), b.core.view(), b.p, run), Cancelled);
    EXPECT_EQ(caller_polls, 1u) << "trial " << trial;
  }
}

// Under RLIMIT_NPROC libgomp aborted the process ("Thread creation failed"). The child (this
// binary again, as user nobody, whose only process it is, limited to 3 threads) runs 8 threads'
// worth of work with what it can create. RLIMIT_NPROC does not bind root, hence the new user.
TEST(RunLimits, AProcessThreadLimitRunsWithTheThreadsItCanCreate) {
  if (std::getenv("M3C2_THREAD_LIMIT_CHILD") != nullptr) {
    const Pair pr = rough_pair(23, 3000);
    Params p = basic_params(1.0, 0.5, 2.0);
    p.lod = Lod::kBootstrap;
    p.bootstrap_samples = 20;
    const Result one = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(1));
    const Result eight = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(8));
    EXPECT_TRUE(BitIdentical(one.lod, eight.lod));
    return;
  }
  if (geteuid() != 0) GTEST_SKIP() << "needs root to run the child as another user";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // only async-signal-safe calls until exec
    const rlimit three{3, 3};
    if (setgid(65534) != 0 || setuid(65534) != 0 || setrlimit(RLIMIT_NPROC, &three) != 0) _exit(90);
    setenv("M3C2_THREAD_LIMIT_CHILD", "1", 1);
    // LeakSanitizer needs a thread of its own at exit, which the limit refuses (a fatal error,
    // exit 1): leaks are checked by every other test of the sanitizer build.
    setenv("ASAN_OPTIONS", "detect_leaks=0", 1);
    const char* args[] = {"/proc/self/exe", "--gtest_filter=RunLimits.AProcessThreadLimitRunsWithTheThreadsItCanCreate",
                          nullptr};
    execv("/proc/self/exe", const_cast<char* const*>(args));
    _exit(91);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status)) << "the child died of signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "libgomp exits 1 when it cannot create a thread; 90/91: set-up failed";
}

// A NaN in the reference with the reference as its own core points (the default) was reported
// as one "in the core points".
TEST(RunLimits, ANanInTheReferenceAsItsOwnCorePointsIsTheReferences) {
  Pair pr = rough_pair(24, 300);
  pr.reference.xyz[7] = kNaN;
  const Params p = basic_params(1.0, 0.5, 2.0);
  try {
    compute(pr.reference.view(), pr.compared.view(), pr.reference.view(), p, with_threads(1));
    FAIL() << "a NaN was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(std::string(e.what()), "reference cloud has 1 non-finite coordinates (NaN or Inf)");
  }
}

TEST(RunLimits, ALongBootstrapIsCancelledInsideItsCorePoint) {
  Cloud reference, compared, core;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int i = 0; i < 2000; ++i) {
    reference.add(u(rng), u(rng), u(rng));
    compared.add(u(rng), u(rng), 0.5 + u(rng));
  }
  core.add(0.0, 0.0, 0.0);
  Params p;
  p.normal_source = NormalSource::kVertical;
  p.projection_diameter = 1.0;
  p.max_depth = 2.0;
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = kMaxBootstrapSamples;
  std::vector<std::size_t> polled;
  RunOptions run;
  run.threads = 1;
  run.progress = [&](std::size_t done, std::size_t) {
    polled.push_back(done);
    return false;
  };
  EXPECT_THROW(compute(reference.view(), compared.view(), core.view(), p, run), Cancelled);
  ASSERT_EQ(polled.size(), 1u);
  EXPECT_EQ(polled[0], 0u) << "cancellation was only noticed after the core point";
}

}  // namespace
}  // namespace m3c2::test
