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
// Two extensions of ours (issue 41), off by default: the epoch's own M3C2 where the windows fall
// short (Tam3c2Fallback) and windows that stop at the change points of the core point's per-epoch
// M3C2 series (Tam3c2Breaks).

#include <m3c2/objects_by_change.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <array>
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

/// A cell whose windows do not bring both sides to `min_points` points, or that has no distance.
/// kNone (the authors' rule): its TAM3C2 distance from what the windows held (>= 2 points a side),
/// else none. kM3c2: the epoch's own M3C2 (distance, LOD, significance, n1, n2 of
/// Tam3c2Epochwise) where it has a distance, else as kNone: TAM3C2 then never has fewer distances
/// than per-epoch M3C2 in any epoch, and a short window's borrowed epochs (their change, their
/// too few points) never replace the epoch's own measurement.
enum class Tam3c2Fallback : std::uint8_t { kNone, kM3c2 };

/// Where the aggregation windows stop. kNone (the authors' rule): nowhere. kChangePoints: at the
/// change points (change_points(), Tam3c2Params::change_points) of the core point's per-epoch
/// M3C2 distance series in time order (Tam3c2Epochwise; NaN epochs left out, each belonging to
/// the segment of the finite epoch before it; a series of no more than `width` finite epochs has
/// none): a side aggregates only epochs of its centre's segment (the reference's side and the
/// normal's spheres the reference's), so that no window borrows across a step.
enum class Tam3c2Breaks : std::uint8_t { kNone, kChangePoints };

/// Where a cell's numbers came from (Tam3c2Result::source).
enum class Tam3c2Source : std::uint8_t { kNone = 0, kWindows = 1, kEpoch = 2 };

/// The enums' option names (the CLI's, the binding's), in the enums' order: their one place.
inline constexpr std::array<const char*, 3> kTam3c2WeightsNames{"none", "linear", "gaussian"};
inline constexpr std::array<const char*, 3> kTam3c2LodNames{"z", "t", "auto"};
inline constexpr std::array<const char*, 2> kTam3c2FallbackNames{"none", "m3c2"};
inline constexpr std::array<const char*, 2> kTam3c2BreaksNames{"none", "changepoints"};

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
  Tam3c2Lod lod = Tam3c2Lod::kZ;    ///< the LOD's statistic (kZ: the reference's)
  double confidence = 0.95;         ///< the LOD's level: kZ's normal quantile (1.96 at 0.95), kT's t quantile
  Vec3 orientation{0.0, 0.0, 1.0};  ///< normals point to this side (n . o >= 0), unless `orientations` says
  Tam3c2Fallback fallback = Tam3c2Fallback::kNone;  ///< kM3c2 needs Tam3c2Epochwise
  Tam3c2Breaks breaks = Tam3c2Breaks::kNone;        ///< kChangePoints needs Tam3c2Epochwise
  /// The breaks' detection: a window of 6 epochs (a step 3 epochs from either end of the series
  /// can be found), segments of >= 3, a split kept when it lowers the series' L1 cost by more than
  /// 0.05 in the distance's unit (5 cm: a 1 cm step held 5 epochs is not a break; 4D-OBC's 24, 12
  /// and 1 m are for hourly series of months).
  ChangePointParams change_points{6, 3, 1, 0.05};
};

/// Each core point's own per-epoch M3C2 against the reference (the store's distance, lod,
/// significant 1 / 0, n1, n2; NaN where it has none), each row-major core x pool epochs; the
/// reference's own column holds distance 0 (the reference against itself). Read by the fallback
/// (a target's column) and the breaks (the distance row); empty when neither is asked for.
struct Tam3c2Epochwise {
  const double* distance = nullptr;
  const double* lod = nullptr;
  const double* significant = nullptr;
  const double* n1 = nullptr;
  const double* n2 = nullptr;
  bool empty() const { return distance == nullptr; }
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
/// side holds fewer than 2 points. significant: |distance| > lod (1, 0; -1 without a distance).
/// source: Tam3c2Source; a kEpoch cell holds the epoch's own M3C2 (spreads NaN) while epochs and
/// points still say what its windows held.
struct Tam3c2Result {
  std::vector<double> normal;
  std::vector<std::int32_t> scale;
  std::vector<double> distance, lod, spread1, spread2, n1, n2;
  std::vector<std::uint32_t> epochs1, epochs2, points1, points2;
  std::vector<std::int8_t> significant;
  std::vector<std::uint8_t> source;
};

/// TAM3C2 of `core` between the pool's epoch `reference` and each of `targets` (pool indices).
/// `orientations`: empty, or one direction per core point that its normal points to (n . o >= 0),
/// such as the normal the store's M3C2 used, so that both distances share a sign; a direction
/// not finite or zero falls back to `params.orientation`. `epochwise`: the per-epoch M3C2 that
/// the fallback and the breaks read (required by either).
Tam3c2Result tam3c2(const Tam3c2Params& params, const Tam3c2Pool& pool, std::size_t reference,
                    const std::vector<std::size_t>& targets, PointsView core, PointsView orientations = {},
                    const Tam3c2Epochwise& epochwise = {}, const RunOptions& run = {});

}  // namespace m3c2
