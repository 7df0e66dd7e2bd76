// variogram_pairs(): the pair sums of the empirical variogram over sampled pairs
// (include/m3c2/variogram.hpp; docs/analysis.md, "m3c2 variogram"). Short lags from each sampled
// centre's neighbours in a kd-tree ball, long lags from random pairs; every draw a hash of
// (seed, stream, counter), sums per fixed block reduced in block order: the same bits for any
// thread count.

#include <m3c2/errors.hpp>
#include <m3c2/variogram.hpp>

#include "index/kdtree.hpp"
#include "pipeline/validation.hpp"
#include "support/parallel_for.hpp"
#include "support/portable.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace m3c2 {
namespace {

/// SplitMix64's finaliser over (seed, stream, counter): independent uniform 64-bit draws.
std::uint64_t draw(std::uint64_t seed, std::uint64_t stream, std::uint64_t counter) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ULL + stream * 0xD1B54A32D192ED03ULL + counter * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z = (z ^ (z >> 31));
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/// A draw in [0, n) (Lemire's multiply-shift; the bias is below n / 2^64).
std::uint64_t below(std::uint64_t r, std::uint64_t n) { return detail::mul_high(r, n); }

enum Stream : std::uint64_t { kCentre = 1, kThin = 2, kFar = 3 };

struct Bins {
  const std::vector<double>& edges;
  std::size_t size() const { return edges.size() - 1; }
  /// The bin of lag h, or size() when outside [front, back).
  std::size_t of(double h) const {
    if (!(h >= edges.front()) || !(h < edges.back())) return size();
    return std::size_t(std::upper_bound(edges.begin(), edges.end(), h) - edges.begin()) - 1;
  }
};

struct BlockSums {
  std::vector<std::uint64_t> pairs;
  std::vector<double> lag, half_sq;
  void resize(std::size_t bins) {
    pairs.assign(bins, 0);
    lag.assign(bins, 0.0);
    half_sq.assign(bins, 0.0);
  }
  void add(std::size_t k, double h, double dv) {
    ++pairs[k];
    lag[k] += h;
    half_sq[k] += 0.5 * dv * dv;
  }
};

struct Scratch {
  std::vector<std::uint32_t> ball;
};

void check(PointsView points, const std::vector<double>& values, const std::vector<double>& edges,
           const VariogramSampling& s) {
  detail::require_finite_points("points", points);
  if (values.size() != points.size())
    throw InvalidArgument("values: " + std::to_string(values.size()) + " values for " + std::to_string(points.size()) +
                          " points");
  for (const double v : values)
    if (!std::isfinite(v)) throw InvalidArgument("values: every value must be finite (drop NaN before)");
  if (points.size() > 0xFFFFFFFFull) throw InvalidArgument("points: at most 2^32 - 1 points");
  if (edges.size() < 2) throw InvalidArgument("edges: at least two lag-bin edges are needed");
  for (std::size_t k = 0; k < edges.size(); ++k)
    if (!std::isfinite(edges[k]) || edges[k] < 0 || (k > 0 && !(edges[k] > edges[k - 1])))
      throw InvalidArgument("edges: lag-bin edges must be finite, >= 0 and strictly increasing");
  if (!(std::isfinite(s.near_radius) && s.near_radius >= 0))
    throw InvalidArgument("near_radius must be finite and >= 0");
}

}  // namespace

VariogramSums variogram_pairs(PointsView points, const std::vector<double>& values, const std::vector<double>& edges,
                              const VariogramSampling& sampling, const RunOptions& run) {
  check(points, values, edges, sampling);
  const Bins bins{edges};
  VariogramSums out{edges, std::vector<std::uint64_t>(bins.size(), 0), std::vector<double>(bins.size(), 0.0),
                    std::vector<double>(bins.size(), 0.0)};
  const std::size_t n = points.size();
  if (n < 2) return out;

  // Plan-view lags: the same kd-tree and distances on a copy with z = 0.
  std::vector<double> flat;
  PointsView pts = points;
  if (sampling.planar) {
    flat.assign(points.data(), points.data() + 3 * n);
    for (std::size_t i = 0; i < n; ++i) flat[3 * i + 2] = 0.0;
    pts = PointsView(flat.data(), n);
  }
  const auto lag = [&](std::size_t i, std::size_t j) {
    const double dx = pts.coord(i, 0) - pts.coord(j, 0), dy = pts.coord(i, 1) - pts.coord(j, 1),
                 dz = pts.coord(i, 2) - pts.coord(j, 2);
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  };

  std::vector<BlockSums> blocks;
  const auto reduce = [&] {
    for (const BlockSums& b : blocks)
      if (!b.pairs.empty())
        for (std::size_t k = 0; k < bins.size(); ++k) {
          out.pairs[k] += b.pairs[k];
          out.lag_sum[k] += b.lag[k];
          out.half_sq_sum[k] += b.half_sq[k];
        }
  };

  // Neighbourhood pairs: `centres` distinct points (a partial Fisher-Yates shuffle of the draws).
  if (sampling.near_radius > 0 && sampling.centres > 0 && sampling.max_neighbours > 0) {
    const std::size_t m = std::min<std::uint64_t>(sampling.centres, n);
    std::vector<std::uint32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(i);
    if (m < n)
      for (std::size_t k = 0; k < m; ++k) std::swap(order[k], order[k + below(draw(sampling.seed, kCentre, k), n - k)]);
    order.resize(m);
    const detail::KdTree tree(pts);
    constexpr std::size_t kBlock = 64;
    blocks.assign((m + kBlock - 1) / kBlock, {});
    detail::parallel_blocks<Scratch>(
        m, run,
        [&](std::size_t begin, std::size_t end, Scratch& s) {
          BlockSums& b = blocks[begin / kBlock];
          b.resize(bins.size());
          for (std::size_t c = begin; c < end; ++c) {
            const std::size_t i = order[c];
            s.ball.clear();
            tree.ball(pts[i], sampling.near_radius, s.ball);
            const std::size_t found = s.ball.size();
            // Thinned to about max_neighbours by a hash of (centre, neighbour): the same subset
            // whatever the tree's order.
            const std::uint64_t keep =
                found > sampling.max_neighbours
                    ? std::uint64_t(std::ldexp(double(sampling.max_neighbours) / double(found), 63)) * 2
                    : ~std::uint64_t(0);
            for (const std::uint32_t j : s.ball) {
              if (j == i) continue;
              if (found > sampling.max_neighbours && draw(sampling.seed ^ (std::uint64_t(i) << 32), kThin, j) > keep)
                continue;
              const double h = lag(i, j);
              const std::size_t k = bins.of(h);
              if (k < bins.size()) b.add(k, h, values[i] - values[j]);
            }
          }
        },
        kBlock);
    reduce();
  }

  // Random pairs of two distinct points.
  if (sampling.far_pairs > 0) {
    constexpr std::size_t kBlock = 1 << 16;
    blocks.assign((sampling.far_pairs + kBlock - 1) / kBlock, {});
    detail::parallel_blocks<Scratch>(
        sampling.far_pairs, run,
        [&](std::size_t begin, std::size_t end, Scratch&) {
          BlockSums& b = blocks[begin / kBlock];
          b.resize(bins.size());
          for (std::size_t p = begin; p < end; ++p) {
            const std::size_t i = below(draw(sampling.seed, kFar, 2 * p), n);
            const std::size_t j = below(draw(sampling.seed, kFar, 2 * p + 1), n);
            if (i == j) continue;
            const double h = lag(i, j);
            const std::size_t k = bins.of(h);
            if (k < bins.size()) b.add(k, h, values[i] - values[j]);
          }
        },
        kBlock);
    reduce();
  }
  return out;
}

}  // namespace m3c2
