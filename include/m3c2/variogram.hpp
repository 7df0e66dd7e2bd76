#pragma once
// The empirical variogram of a value over points (the M3C2 distance over stable core points),
// over SAMPLED pairs: the pair sums of `m3c2 variogram` (docs/analysis.md; Rolstad et al. 2009,
// Hugonnet et al. 2022). Python fits the model (python/m3c2kit/analysis/variogram.py).

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstdint>
#include <vector>

namespace m3c2 {

/// Which pairs are sampled. Random pairs are almost never close (the share of pairs within h of
/// each other is ~ pi h^2 / area), so the short lags come from neighbourhoods: `centres` points
/// drawn at random (all when centres >= n) pair with their neighbours within `near_radius` (at
/// most `max_neighbours` of them, thinned by a seeded hash when more); the long lags from
/// `far_pairs` pairs of two points drawn at random. Every draw is a hash of (seed, counter): the
/// same pairs, and the same bits, for any thread count.
struct VariogramSampling {
  std::uint64_t seed = 0;
  std::uint64_t centres = 20000;
  double near_radius = 0;  ///< 0: no neighbourhood pairs
  std::uint32_t max_neighbours = 512;
  std::uint64_t far_pairs = 10000000;
  bool planar = false;  ///< lag in plan view (x, y) instead of 3D
};

/// Per lag bin [edges[k], edges[k+1]): pairs, the sum of their lags and the sum of
/// 0.5 (v_i - v_j)^2 (the semivariance is the mean). A pair of lag outside [edges.front(),
/// edges.back()) is not counted, nor a point with itself.
struct VariogramSums {
  std::vector<double> edges;
  std::vector<std::uint64_t> pairs;
  std::vector<double> lag_sum;
  std::vector<double> half_sq_sum;
};

/// The sums over the sampled pairs of `points` with `values` (one per point, finite). `edges`
/// strictly increasing, >= 0, at least two. Memory: the index (about 40 B a point) and per-block
/// sums; never the pairs. Throws InvalidArgument on bad inputs.
VariogramSums variogram_pairs(PointsView points, const std::vector<double>& values, const std::vector<double>& edges,
                              const VariogramSampling& sampling, const RunOptions& run = {});

}  // namespace m3c2
