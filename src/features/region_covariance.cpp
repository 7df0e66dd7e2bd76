// region_covariance_sum(): sum_i sum_j C(|x_i - x_j|) over a region's points by bins, and the
// exact O(N^2) sum it is tested against (include/m3c2/region_covariance.hpp; docs/algorithm.md,
// "Aggregates over a region"). Per-bin (per-point) partial sums written by index and added in
// index order: the same bits for any thread count.

#include <m3c2/errors.hpp>
#include <m3c2/region_covariance.hpp>

#include "support/parallel_for.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

namespace m3c2 {
namespace {

struct NoScratch {};

void check(std::span<const double> xy, std::span<const CovarianceComponent> components) {
  if (xy.size() % 2 != 0) throw InvalidArgument("xy: an odd number of values (expected x0, y0, x1, y1, ...)");
  if (xy.size() / 2 > std::size_t(0x7FFFFFFF)) throw InvalidArgument("xy: at most 2^31 - 1 points");
  for (const double v : xy)
    if (!std::isfinite(v)) throw InvalidArgument("xy: every coordinate must be finite");
  for (const auto& c : components) {
    if (c.kind != CovarianceKind::kSpherical && c.kind != CovarianceKind::kExponential)
      throw InvalidArgument("components: unknown covariance kind");
    if (!(std::isfinite(c.sill) && c.sill >= 0)) throw InvalidArgument("components: a sill must be finite and >= 0");
    if (!(std::isfinite(c.range) && c.range > 0)) throw InvalidArgument("components: a range must be finite and > 0");
  }
}

/// C(h), C'(h), C''(h) of one component (h > 0).
std::tuple<double, double, double> covariance_and_derivatives(const CovarianceComponent& c, double h) {
  const double R = c.range, r = h / R;
  if (c.kind == CovarianceKind::kSpherical) {
    if (r >= 1.0) return {0.0, 0.0, 0.0};
    return {c.sill * (1.0 - 1.5 * r + 0.5 * r * r * r), c.sill * (-1.5 + 1.5 * r * r) / R, c.sill * 3.0 * r / (R * R)};
  }
  const double e = c.sill * std::exp(-3.0 * r);
  return {e, -3.0 * e / R, 9.0 * e / (R * R)};
}

/// S of one component by bins; `side` receives the bin side used.
double binned_sum(std::span<const double> xy, const CovarianceComponent& c, const CovarianceSumOptions& o,
                  const RunOptions& run, double& side) {
  const std::size_t n = xy.size() / 2;
  side = o.bin_fraction * c.range;
  if (n == 0 || c.sill == 0) return 0.0;
  const double reach = c.kind == CovarianceKind::kSpherical ? c.range : o.exponential_reach * c.range;
  double x0 = xy[0], y0 = xy[1], x1 = xy[0], y1 = xy[1];
  for (std::size_t i = 0; i < n; ++i) {
    x0 = std::min(x0, xy[2 * i]), x1 = std::max(x1, xy[2 * i]);
    y0 = std::min(y0, xy[2 * i + 1]), y1 = std::max(y1, xy[2 * i + 1]);
  }
  std::uint64_t cols = 0, rows = 0;
  for (;;) {  // bins over the bounding box; larger bins while there would be too many
    cols = std::uint64_t(std::floor((x1 - x0) / side)) + 1;
    rows = std::uint64_t(std::floor((y1 - y0) / side)) + 1;
    if (double(cols) * double(rows) <= double(o.max_bins)) break;
    side *= 1.25;
  }
  // each point's bin (row-major), the points sorted by bin (index order within one: deterministic)
  std::vector<std::uint64_t> key(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto col = std::min(cols - 1, std::uint64_t((xy[2 * i] - x0) / side));
    const auto row = std::min(rows - 1, std::uint64_t((xy[2 * i + 1] - y0) / side));
    key[i] = row * cols + col;
  }
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  std::vector<std::uint64_t> bin_key;
  std::vector<std::uint32_t> start;  // CSR over `order`
  for (std::size_t k = 0; k < n; ++k)
    if (k == 0 || key[order[k]] != key[order[k - 1]])
      bin_key.push_back(key[order[k]]), start.push_back(std::uint32_t(k));
  start.push_back(std::uint32_t(n));
  const std::size_t bins = bin_key.size();
  std::vector<std::int32_t> lookup(cols * rows, -1);
  // per bin: count, centroid, and the points' covariance about it (the second-order term)
  std::vector<double> cx(bins), cy(bins), count(bins), vxx(bins), vyy(bins), vxy(bins);
  for (std::size_t b = 0; b < bins; ++b) {
    lookup[bin_key[b]] = std::int32_t(b);
    double sx = 0, sy = 0;
    for (std::uint32_t k = start[b]; k < start[b + 1]; ++k) sx += xy[2 * order[k]], sy += xy[2 * order[k] + 1];
    count[b] = double(start[b + 1] - start[b]);
    cx[b] = sx / count[b], cy[b] = sy / count[b];
    double sxx = 0, syy = 0, sxy = 0;
    for (std::uint32_t k = start[b]; k < start[b + 1]; ++k) {
      const double dx = xy[2 * order[k]] - cx[b], dy = xy[2 * order[k] + 1] - cy[b];
      sxx += dx * dx, syy += dy * dy, sxy += dx * dy;
    }
    vxx[b] = sxx / count[b], vyy[b] = syy / count[b], vxy[b] = sxy / count[b];
  }
  // half the stencil of bin offsets (the other half by symmetry), only offsets whose bins can
  // hold centroids within reach (two centroids are at least (|offset| - 1) sides apart per axis)
  const auto span = std::int64_t(std::ceil(reach / side)) + 1;
  std::vector<std::pair<std::int64_t, std::int64_t>> lags;
  for (std::int64_t dr = 0; dr <= span; ++dr)
    for (std::int64_t dc = -span; dc <= span; ++dc) {
      if (dr == 0 && dc <= 0) continue;
      const double gx = double(std::max<std::int64_t>(0, std::abs(dc) - 1)) * side;
      const double gy = double(std::max<std::int64_t>(0, dr - 1)) * side;
      if (std::hypot(gx, gy) <= reach) lags.emplace_back(dr, dc);
    }
  std::vector<double> partial(bins);
  detail::parallel_blocks<NoScratch>(
      bins, run,
      [&](std::size_t begin, std::size_t end, NoScratch&) {
        for (std::size_t a = begin; a < end; ++a) {
          // within the bin: every ordered pair exactly (i == j gives C(0) = sill)
          double within = 0;
          for (std::uint32_t k = start[a]; k < start[a + 1]; ++k) {
            const std::uint32_t i = order[k];
            for (std::uint32_t l = k + 1; l < start[a + 1]; ++l) {
              const std::uint32_t j = order[l];
              within += component_covariance(c, std::hypot(xy[2 * i] - xy[2 * j], xy[2 * i + 1] - xy[2 * j + 1]));
            }
          }
          within = count[a] * c.sill + 2.0 * within;
          const auto row = std::int64_t(bin_key[a] / cols), col = std::int64_t(bin_key[a] % cols);
          double across = 0, near = 0;
          for (const auto& [dr, dc] : lags) {
            const std::int64_t r = row + dr, q = col + dc;
            if (r >= std::int64_t(rows) || q < 0 || q >= std::int64_t(cols)) continue;
            const std::int32_t b = lookup[std::uint64_t(r) * cols + std::uint64_t(q)];
            if (b < 0) continue;
            if (dr <= 1 && std::abs(dc) <= 1) {
              // a touching bin: every pair exactly (the centroids' distance is furthest from the
              // pairs' mean distance when the bins touch)
              for (std::uint32_t k = start[a]; k < start[a + 1]; ++k) {
                const std::uint32_t i = order[k];
                for (std::uint32_t l = start[b]; l < start[b + 1]; ++l) {
                  const std::uint32_t j = order[l];
                  const double h = std::hypot(xy[2 * i] - xy[2 * j], xy[2 * i + 1] - xy[2 * j + 1]);
                  if (h <= reach) near += component_covariance(c, h);
                }
              }
              continue;
            }
            // the mean of C(|x_i - x_j|) over the two bins' pairs, to second order about the
            // centroids' distance h (delta method): C(h) + (C''(h) s_par + C'(h) s_perp / h) / 2, with
            // s_par, s_perp the variance of x_i - x_j along and across the centroids' direction
            const double ux = cx[b] - cx[a], uy = cy[b] - cy[a];
            const double h = std::hypot(ux, uy);
            if (h > reach) continue;
            const double sxx = vxx[a] + vxx[b], syy = vyy[a] + vyy[b], sxy = vxy[a] + vxy[b];
            const double par = (ux * ux * sxx + 2 * ux * uy * sxy + uy * uy * syy) / (h * h);
            const double perp = sxx + syy - par;
            const auto [f, d1, d2] = covariance_and_derivatives(c, h);
            across += count[b] * (f + 0.5 * (d2 * par + d1 * perp / h));
          }
          partial[a] = within + 2.0 * (near + count[a] * across);
        }
      },
      256);
  double sum = 0;
  for (const double v : partial) sum += v;
  return sum;
}

}  // namespace

double component_covariance(const CovarianceComponent& c, double h) {
  const double r = std::abs(h) / c.range;
  if (c.kind == CovarianceKind::kSpherical) return r < 1.0 ? c.sill * (1.0 - 1.5 * r + 0.5 * r * r * r) : 0.0;
  return c.sill * std::exp(-3.0 * r);
}

double component_variogram(const CovarianceComponent& c, double h) {
  const double r = std::abs(h) / c.range;
  if (c.kind == CovarianceKind::kSpherical) return r < 1.0 ? c.sill * (1.5 * r - 0.5 * r * r * r) : c.sill;
  return -c.sill * std::expm1(-3.0 * r);
}

CovarianceSum region_covariance_sum(std::span<const double> xy, std::span<const CovarianceComponent> components,
                                    const CovarianceSumOptions& options, const RunOptions& run) {
  check(xy, components);
  if (!(options.bin_fraction > 0 && options.bin_fraction <= 1))
    throw InvalidArgument("bin_fraction: must be in (0, 1]");
  if (!(options.exponential_reach >= 1 && std::isfinite(options.exponential_reach)))
    throw InvalidArgument("exponential_reach: must be finite and >= 1");
  if (options.max_bins < 1) throw InvalidArgument("max_bins: must be >= 1");
  CovarianceSum out;
  for (const auto& c : components) {
    double side = 0;
    out.sum += binned_sum(xy, c, options, run, side);
    out.bin_side.push_back(side);
  }
  return out;
}

double region_covariance_exact(std::span<const double> xy, std::span<const CovarianceComponent> components,
                               const RunOptions& run) {
  check(xy, components);
  const std::size_t n = xy.size() / 2;
  double c0 = 0;
  for (const auto& c : components) c0 += c.sill;
  std::vector<double> partial(n);
  detail::parallel_blocks<NoScratch>(
      n, run,
      [&](std::size_t begin, std::size_t end, NoScratch&) {
        for (std::size_t i = begin; i < end; ++i) {
          double s = 0;
          for (std::size_t j = i + 1; j < n; ++j) {
            const double h = std::hypot(xy[2 * i] - xy[2 * j], xy[2 * i + 1] - xy[2 * j + 1]);
            for (const auto& c : components) s += component_covariance(c, h);
          }
          partial[i] = c0 + 2.0 * s;
        }
      },
      16);
  double sum = 0;
  for (const double v : partial) sum += v;
  return sum;
}

}  // namespace m3c2
