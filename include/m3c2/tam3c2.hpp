#pragma once
// Time-adaptive M3C2, TAM3C2 (docs/series.md, "TAM3C2"), after Huang, Letard, Lague, Hoefle,
// Tabernig, Leroy & Anders (ISPRS Annals 2026) and its description in xyuhuang/py4dgeo
// (tam3c2_readme.md). A pool of epochs (clouds with times) and core points. Per core point,
// once: the (normal radius, window ratio) whose time-aggregated sphere around the reference is
// the most planar ((l1 - l0) / l2), and that sphere's normal. Per core point and target epoch:
// a cylinder on that normal aggregated around the reference's time and, independently, around
// the target's, epochs taken nearest in time first until `min_points` points, never further than
// W = |t_target - t_reference| * ratio; the distance is the difference of the (weighted) means
// of the two sides' projections, the LOD c sqrt(s1^2 / n1 + s2^2 / n2) + reg with Kish's
// effective n for weighted sides, c the reference's z or Welch's t (Tam3c2Lod). Every core point
// is independent: the same bits for any thread count and any split of the core points into blocks.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace m3c2 {

/// How points of a side are weighted (tam3c2_readme.md 4.5): not at all, or by a kernel of the
/// radial distance to the cylinder's axis over the cylinder radius times one of |dt| over the
/// effective window W * space_time_ratio: linear (triangular) or Gaussian of width sigma_ratio.
enum class Tam3c2Weights : std::uint8_t { kNone, kLinear, kGaussian };

/// The LOD's statistic. kZ: the reference's z sqrt(s1^2 / n1 + s2^2 / n2) + reg (weighted sides
/// with their weighted population spread). kT: Welch's t (Lague et al. 2013, eq. (2)) at the
/// sides' (effective) n instead of z, the weighted spreads made unbiased (x n / (n - 1),
/// reliability weights): a side of effective n <= 1 then bounds nothing (LOD +inf). kAuto: kT
/// where n1 or n2 < 30, else kZ's critical value with kT's spreads (the paper's rule, as the
/// engine's Lod::kAuto). Only kT and kAuto flag about 1 - confidence of unchanged cells at small n.
enum class Tam3c2Lod : std::uint8_t { kZ, kT, kAuto };

struct Tam3c2Params {
  std::vector<double> normal_radii;   ///< radii of the normal's sphere (> 0); several: chosen per core point
  std::vector<double> window_ratios;  ///< W / |t_target - t_reference|, each in (0, 1]
  std::uint32_t min_points = 10;      ///< aggregation stops when a side holds this many points
  double cylinder_radius = 0.0;       ///< radius of the projection cylinder (> 0)
  double max_distance = 0.0;          ///< the cylinder's half-length along the normal (> 0)
  Tam3c2Weights weights = Tam3c2Weights::kNone;
  double sigma_ratio = 1.0;       ///< Gaussian width in units of the radius / window
  double space_time_ratio = 1.0;  ///< r_st > 0: the temporal kernel's window is W r_st
  double registration_error = 0.0;
  double critical_value = 1.96;     ///< z of the LOD (1.96: the reference's 95 %)
  Tam3c2Lod lod = Tam3c2Lod::kZ;    ///< the LOD's statistic (kZ: the reference's)
  double confidence = 0.95;         ///< the level of kT's and kAuto's t quantile
  Vec3 orientation{0.0, 0.0, 1.0};  ///< normals point to this side (n . o >= 0), unless `orientations` says
};

/// The pool: one cloud per epoch with its time (any unit), the views' memory outliving the pool.
/// Each cloud's spatial index (the engine's k-d tree) is built once here.
class Tam3c2Pool {
 public:
  Tam3c2Pool(std::vector<PointsView> clouds, std::vector<double> times);
  ~Tam3c2Pool();
  Tam3c2Pool(Tam3c2Pool&&) noexcept;
  std::size_t size() const { return times_.size(); }
  const std::vector<double>& times() const { return times_; }
  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  std::vector<double> times_;
  std::unique_ptr<Impl> impl_;
};

/// Per core point: normal (3), the chosen (radius, ratio)'s index (radius-major: radius i,
/// ratio j -> i * ratios + j; -1 when no sphere held 3 points, the normal then its orientation).
/// Per core point and target (row-major, core x targets): distance, lod, the sides' spreads
/// (standard deviation, sample for unweighted sides, weighted population otherwise), their n
/// (count or Kish's effective n), and the epochs aggregated on each side; NaN distance when a
/// side holds fewer than 2 points.
struct Tam3c2Result {
  std::vector<double> normal;
  std::vector<std::int32_t> scale;
  std::vector<double> distance, lod, spread1, spread2, n1, n2;
  std::vector<std::uint32_t> epochs1, epochs2, points1, points2;
};

/// TAM3C2 of `core` between the pool's epoch `reference` and each of `targets` (pool indices).
/// `orientations`: empty, or one direction per core point that its normal points to (n . o >= 0),
/// such as the normal the store's M3C2 used, so that both distances share a sign; a direction
/// not finite or zero falls back to `params.orientation`.
Tam3c2Result tam3c2(const Tam3c2Params& params, const Tam3c2Pool& pool, std::size_t reference,
                    const std::vector<std::size_t>& targets, PointsView core, PointsView orientations = {},
                    const RunOptions& run = {});

}  // namespace m3c2
