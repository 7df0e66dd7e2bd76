// Every function is deterministic: the same inputs give the same bits for any thread count
// (m3c2.hpp, run_options.hpp); progress and cancellation follow the RunOptions contract.

#include "test_support.hpp"

#include <atomic>
#include <mutex>

namespace m3c2::test {
namespace {

Params rough_params() {
  Params p;
  p.normal_diameters = {0.4, 0.8, 1.6, 3.2};  // multi-scale
  p.projection_diameter = 0.5;
  p.max_depth = 2.0;
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 50;
  p.bootstrap_seed = 987654321;
  return p;
}

::testing::AssertionResult SameBits(const Result& a, const Result& b) {
#define M3C2_SAME(field) \
  if (auto r = BitIdentical(a.field, b.field); !r) return r << " in " #field;
  M3C2_SAME(distance)
  M3C2_SAME(lod)
  M3C2_SAME(significant)
  M3C2_SAME(n1)
  M3C2_SAME(n2)
  M3C2_SAME(sigma1)
  M3C2_SAME(sigma2)
  M3C2_SAME(i1)
  M3C2_SAME(i2)
  M3C2_SAME(normal)
  M3C2_SAME(normal_scale)
  M3C2_SAME(roughness)
  M3C2_SAME(status)
#undef M3C2_SAME
  return ::testing::AssertionSuccess();
}

TEST(Determinism, ResultIsBitIdenticalFor1And2And8Threads) {
  const Pair pr = rough_pair(1234);
  const Params p = rough_params();
  const Result r1 = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(1));
  const Result r2 = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(2));
  const Result r8 = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(8));
  ASSERT_EQ(r1.size(), pr.cores.size());
  EXPECT_TRUE(SameBits(r1, r2));
  EXPECT_TRUE(SameBits(r1, r8));
  // Non-vacuity: the scene exercises several scales and mostly succeeds.
  std::size_t ok = 0;
  bool scale_varies = false;
  for (std::size_t i = 0; i < r1.size(); ++i) {
    ok += r1.status[i] == PointStatus::kOk;
    scale_varies |= r1.normal_scale[i] != r1.normal_scale[0];
  }
  EXPECT_GT(ok, r1.size() * 8 / 10);
  EXPECT_TRUE(scale_varies);
}

TEST(Determinism, RepeatedRunsAreBitIdentical) {
  const Pair pr = rough_pair(99);
  const Params p = rough_params();
  const Result a = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(2));
  const Result b = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(2));
  EXPECT_TRUE(SameBits(a, b));
}

TEST(Determinism, NormalsAreBitIdenticalFor1And8Threads) {
  const Pair pr = rough_pair(77);
  const Params p = rough_params();
  const NormalsResult a = compute_normals(pr.reference.view(), pr.cores.view(), p, with_threads(1));
  const NormalsResult b = compute_normals(pr.reference.view(), pr.cores.view(), p, with_threads(8));
  EXPECT_TRUE(BitIdentical(a.normal, b.normal));
  EXPECT_TRUE(BitIdentical(a.normal_scale, b.normal_scale));
  EXPECT_TRUE(BitIdentical(a.roughness, b.roughness));
  EXPECT_TRUE(BitIdentical(a.count, b.count));
  EXPECT_TRUE(BitIdentical(a.status, b.status));
}

TEST(Determinism, RoughnessByScaleIsBitIdenticalFor1And8Threads) {
  const Pair pr = rough_pair(55);
  const std::vector<double> scales = {0.5, 1.0, 2.0};
  const auto a =
      roughness_by_scale(pr.reference.view(), pr.cores.view(), scales, Variance::kSample, 3, with_threads(1));
  const auto b =
      roughness_by_scale(pr.reference.view(), pr.cores.view(), scales, Variance::kSample, 3, with_threads(8));
  EXPECT_TRUE(BitIdentical(a, b));
}

TEST(Progress, DoneNeverExceedsTotalAndLastCallIsComplete) {
  const Pair pr = rough_pair(3);
  Params p = rough_params();
  p.lod = Lod::kZ;
  std::vector<std::pair<std::size_t, std::size_t>> calls;
  std::mutex m;
  std::atomic<int> concurrent{0};
  bool overlapped = false;
  RunOptions run;
  run.threads = 4;
  run.progress = [&](std::size_t done, std::size_t total) {
    if (concurrent.fetch_add(1) != 0) overlapped = true;
    {
      std::lock_guard lock(m);
      calls.emplace_back(done, total);
    }
    concurrent.fetch_sub(1);
    return true;
  };
  compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, run);
  ASSERT_FALSE(calls.empty());
  for (const auto& [done, total] : calls) {
    EXPECT_EQ(total, pr.cores.size());
    EXPECT_LE(done, total);
  }
  EXPECT_EQ(calls.back().first, pr.cores.size());
  EXPECT_FALSE(overlapped) << "progress called concurrently with itself";
  EXPECT_LE(calls.size(), 1000u) << "'at most a few hundred times per run'";
}

TEST(Progress, ReturningFalseThrowsCancelled) {
  const Pair pr = rough_pair(4);
  Params p = rough_params();
  p.lod = Lod::kZ;
  int calls = 0;
  RunOptions run;
  run.threads = 2;
  run.progress = [&](std::size_t, std::size_t) { return ++calls < 2; };
  EXPECT_THROW(compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, run), Cancelled);
  EXPECT_GE(calls, 2);
}

TEST(Progress, CancellingNormalsThrowsCancelled) {
  const Pair pr = rough_pair(5);
  RunOptions run;
  run.progress = [](std::size_t, std::size_t) { return false; };
  EXPECT_THROW(compute_normals(pr.reference.view(), pr.cores.view(), rough_params(), run), Cancelled);
}

// RunOptions::order_clouds_in_place: the indexes order the clouds' own arrays instead of copying
// them; the results are the same bits, and every row is back in place when compute() returns.
TEST(InPlace, SameBitsAsCopiedAndEveryRowBackFor1And2Threads) {
  const Pair pr = rough_pair(21);
  const Params p = rough_params();
  for (int threads : {1, 2}) {
    Pair own = pr;
    RunOptions run = with_threads(threads);
    run.order_clouds_in_place = true;
    bool reordered = false;  // non-vacuity: during the run, the arrays are in key order
    run.progress = [&](std::size_t, std::size_t) {
      reordered = reordered || (own.reference.xyz != pr.reference.xyz && own.compared.xyz != pr.compared.xyz);
      return true;
    };
    const Result copied = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p, with_threads(threads));
    const Result ordered = compute(own.reference.view(), own.compared.view(), own.cores.view(), p, run);
    EXPECT_TRUE(reordered) << threads << " threads";
    EXPECT_TRUE(SameBits(copied, ordered)) << threads << " threads";
    EXPECT_TRUE(BitIdentical(own.reference.xyz, pr.reference.xyz)) << threads << " threads";
    EXPECT_TRUE(BitIdentical(own.compared.xyz, pr.compared.xyz)) << threads << " threads";
  }
}

TEST(InPlace, CorePointsThatAreTheReferenceItselfGiveTheSameBits) {
  const Pair pr = rough_pair(22, 3000);
  Params p = rough_params();
  p.lod = Lod::kZ;
  for (int threads : {1, 2}) {
    Pair own = pr;
    RunOptions run = with_threads(threads);
    run.order_clouds_in_place = true;
    const Result copied =
        compute(pr.reference.view(), pr.compared.view(), pr.reference.view(), p, with_threads(threads));
    bool reordered = false;
    run.progress = [&](std::size_t, std::size_t) {
      return reordered = reordered || own.reference.xyz != pr.reference.xyz, true;
    };
    const Result ordered = compute(own.reference.view(), own.compared.view(), own.reference.view(), p, run);
    EXPECT_TRUE(reordered) << threads << " threads";
    EXPECT_TRUE(SameBits(copied, ordered)) << threads << " threads";
    EXPECT_TRUE(BitIdentical(own.reference.xyz, pr.reference.xyz)) << threads << " threads";
  }
}

TEST(InPlace, CancelledRunPutsEveryRowBack) {
  Pair own = rough_pair(23);
  const Pair pr = own;
  Params p = rough_params();
  p.lod = Lod::kZ;
  RunOptions run;
  run.threads = 2;
  run.order_clouds_in_place = true;
  run.progress = [](std::size_t, std::size_t) { return false; };
  EXPECT_THROW(compute(own.reference.view(), own.compared.view(), own.cores.view(), p, run), Cancelled);
  EXPECT_TRUE(BitIdentical(own.reference.xyz, pr.reference.xyz));
  EXPECT_TRUE(BitIdentical(own.compared.xyz, pr.compared.xyz));
}

TEST(InPlace, OneArrayForBothCloudsIsCopied) {
  const Pair pr = rough_pair(24, 3000);
  Params p = rough_params();
  p.lod = Lod::kZ;
  Pair own = pr;
  RunOptions run = with_threads(2);
  run.order_clouds_in_place = true;
  const Result copied = compute(pr.reference.view(), pr.reference.view(), pr.cores.view(), p, with_threads(2));
  const Result ordered = compute(own.reference.view(), own.reference.view(), own.cores.view(), p, run);
  EXPECT_TRUE(SameBits(copied, ordered));
  EXPECT_TRUE(BitIdentical(own.reference.xyz, pr.reference.xyz));
}

}  // namespace
}  // namespace m3c2::test
