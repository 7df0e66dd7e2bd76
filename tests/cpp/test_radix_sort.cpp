// The index build's sort (src/index/radix_sort.hpp) against std::stable_sort, and the parallel build
// (Octree's `threads`) against the serial one: the same order, slots and moment bits. The
// sizes pass the thresholds of the parallel paths (radix::kParallelSort, the blocks of
// parallel_blocks), which the pipeline's small test scenes stay below.

#include "test_support.hpp"

#include "index/octree.hpp"
#include "index/radix_sort.hpp"
#include "support/portable.hpp"

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>

namespace m3c2::test {
namespace {

constexpr std::size_t kLarge = 3 * detail::radix::kParallelSort + 12345;

RunOptions threads(int n) {
  RunOptions run;
  run.threads = n;
  return run;
}

/// The (key, index) order a stable sort gives.
template <class K>
std::vector<std::uint32_t> stable_order(const std::vector<K>& keys) {
  std::vector<std::uint32_t> order(keys.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::uint32_t a, std::uint32_t b) { return detail::key_less(keys[a], keys[b]); });
  return order;
}

/// n keys varying in their low `bits` bits above a shared prefix: `distinct` values drawn
/// (heavy ties), or each key drawn (0).
std::vector<std::uint64_t> keys64(std::uint64_t seed, std::size_t n, int bits, std::size_t distinct) {
  std::mt19937_64 rng(seed);
  const std::uint64_t mask = (std::uint64_t(1) << bits) - 1, prefix = std::uint64_t(0x5) << bits;
  std::vector<std::uint64_t> values(distinct);
  for (auto& v : values) v = (rng() & mask) | prefix;
  std::vector<std::uint64_t> keys(n);
  for (auto& k : keys) k = distinct ? values[rng() % distinct] : (rng() & mask) | prefix;
  return keys;
}

/// The order sort_in_place() gives `keys` (sorted alike, checked against the keys) on t threads.
template <class K>
std::vector<std::uint32_t> radix_order(const std::vector<K>& keys, int t) {
  std::vector<K> k = keys;
  std::vector<std::uint32_t> order(k.size());
  std::iota(order.begin(), order.end(), 0u);
  detail::sort_in_place(k.data(), order.data(), k.size(), threads(t));
  for (std::size_t s = 0; s < k.size(); ++s)
    if (!(k[s] == keys[order[s]])) ADD_FAILURE() << "slot " << s << ": the key did not move with its index";
  return order;
}

TEST(RadixSort, PairsSortAsAStableSortOnAnyThreadCount) {
  for (const std::size_t distinct : {1, 40, 0}) {
    const std::vector<std::uint64_t> keys = keys64(3, kLarge, 50, distinct);
    const std::vector<std::uint32_t> want = stable_order(keys);
    for (const int t : {1, 4})
      ASSERT_EQ(radix_order(keys, t), want) << distinct << " distinct keys, " << t << " threads";
  }
}

TEST(RadixSort, RangesSortedByDigitsKeepTiesInIndexOrder) {
  // 24 varying bits: after the first split each range is small and varies in a few digits, so it
  // takes sort_by_digits's LSD passes; its ties come from the split in no particular order. Runs
  // of equal keys of about 40 (std::sort), about 4 (insertion), and almost none.
  for (const std::size_t distinct : {5000, 50000, 0}) {
    const std::vector<std::uint64_t> keys = keys64(11, kLarge, 24, distinct);
    const std::vector<std::uint32_t> want = stable_order(keys);
    for (const int t : {1, 2})
      ASSERT_EQ(radix_order(keys, t), want) << distinct << " distinct keys, " << t << " threads";
  }
}

TEST(RadixSort, WideKeysVaryingAcrossTheirHalvesSortAsAStableSort) {
  // Bits 50 to 69 vary: digits straddle the two 64-bit halves, in the LSD passes and the splits.
  std::mt19937_64 rng(9);
  std::vector<detail::Uint128> keys(kLarge);
  for (auto& k : keys) k = detail::Uint128(rng() % 600000) << 50;
  const std::vector<std::uint32_t> want = stable_order(keys);
  for (const int t : {1, 2}) ASSERT_EQ(radix_order(keys, t), want) << t << " threads";
}

TEST(RadixSort, WideKeysSortAsAStableSort) {
  std::mt19937_64 rng(5);
  std::vector<detail::Uint128> keys(kLarge);
  for (auto& k : keys) {  // ties, and bits above the low 64 varying
    const std::uint64_t high = rng() % 7, low = rng() % 1000;
    k = (detail::Uint128(high) << 64 | detail::Uint128(low)) << 20;
  }
  const std::vector<std::uint32_t> want = stable_order(keys);
  for (const int t : {1, 3}) ASSERT_EQ(radix_order(keys, t), want) << t << " threads";
}

bool same_bits(const detail::Moments& a, const detail::Moments& b) {
  return std::memcmp(&a.count, &b.count, sizeof(double)) == 0 &&
         std::memcmp(a.mean.data(), b.mean.data(), 3 * sizeof(double)) == 0 &&
         std::memcmp(a.comoment.data(), b.comoment.data(), sizeof(a.comoment)) == 0;
}

TEST(ParallelBuild, GivesTheSerialBuildsSlotsAndBits) {
  // A rough surface straddling the origin (64-bit keys) and the same at UTM-sized coordinates
  // with a far cell (128-bit keys), with duplicates, in input order shuffled.
  for (const double shift : {0.0, 4.0e5}) {
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> u(-20.0, 20.0), noise(-0.01, 0.01);
    std::vector<double> xyz;
    for (std::size_t i = 0; i < kLarge; ++i) {
      const double x = u(rng), y = u(rng);
      const std::array<double, 3> p{x + shift, y, 0.2 * std::sin(x) * std::cos(y) + noise(rng)};
      xyz.insert(xyz.end(), p.begin(), p.end());
      if (i % 101 == 0) xyz.insert(xyz.end(), p.begin(), p.end());
    }
    if (shift > 0.0) xyz.insert(xyz.end(), {-shift, -3.0e5, 50.0});
    const PointsView cloud(xyz.data(), xyz.size() / 3);
    const detail::OctreeGrid grid = detail::octree_grid(0.5, 1.0);
    const detail::Octree serial(cloud, grid, {.node_moments = true, .cloud_name = "cloud", .build_threads = 1});
    for (const int t : {2, 4}) {
      const detail::Octree parallel(cloud, grid, {.node_moments = true, .cloud_name = "cloud", .build_threads = t});
      ASSERT_EQ(parallel.size(), serial.size());
      for (std::size_t s = 0; s < serial.size(); ++s) ASSERT_EQ(parallel.original_index(s), serial.original_index(s));
      detail::OctreeScratch a, b;
      std::vector<detail::Moments> ma, mb;
      const std::vector<double> radii = {0.25, 0.5, 2.0};
      for (std::size_t q = 0; q < 200; ++q) {
        const std::size_t i = q * 997 % cloud.size();
        const Vec3 c(cloud.coord(i, 0), cloud.coord(i, 1), cloud.coord(i, 2));
        serial.ball_moments(c, radii, a, ma);
        parallel.ball_moments(c, radii, b, mb);
        for (std::size_t k = 0; k < radii.size(); ++k) ASSERT_TRUE(same_bits(ma[k], mb[k])) << "query " << q;
        EXPECT_GT(ma[0].count, 0.0);
      }
    }
  }
}

}  // namespace
}  // namespace m3c2::test
