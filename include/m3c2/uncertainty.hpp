#pragma once
// Per-point uncertainty models beside eq. (1) (section 6.2 of Lague et al. 2013 names its limit):
// M3C2-PM, precision maps (James, Robson & Smith 2017), and M3C2-EP, error propagation
// (Winiwarter, Anders & Hoefle 2021). docs/algorithm.md §6.5 derives each formula.

#include <cstdint>
#include <span>
#include <vector>

namespace m3c2 {

/// Which model gives the LOD (Params::uncertainty).
enum class Uncertainty : std::uint8_t {
  kEq1,               ///< eq. (1): the cylinders' spreads over sqrt(n), plus reg (the paper)
  kPrecisionMaps,     ///< M3C2-PM: per-point precisions sx, sy, sz projected on the normal
  kErrorPropagation,  ///< M3C2-EP: scanner and alignment covariances propagated to each point
};

/// Which points of a cylinder give its M3C2-PM sigma (Params::precision_rule).
enum class PrecisionRule : std::uint8_t {
  kNearest,    ///< the point nearest the points' centre of gravity (CloudCompare's qM3C2)
  kAllPoints,  ///< sqrt of the mean projected variance of every point of the cylinder
};

/// How M3C2-EP's centre-of-gravity covariance treats the measurement errors of a cylinder's points.
enum class EpCovariance : std::uint8_t {
  kIndependent,   ///< (sum of W_i)^-1: the covariance of the weighted mean of independent points
  kMeanOfPoints,  ///< the mean of the points' covariances (py4dgeo's code: errors fully correlated)
  kEmpirical,     ///< eq. (1)'s sigma^2 / n along n (measurement and surface sampling, as observed),
                  ///< plus the propagated alignment covariance; the distance is eq. (1)'s
};

/// How M3C2-EP weighs a cylinder's points in its centre of gravity.
enum class EpWeights : std::uint8_t {
  kNormal,  ///< scalar weights 1 / n^T S_i n: the best estimate of the offset along the normal
  kMatrix,  ///< matrix weights S_i^-1 (Winiwarter et al. 2021, py4dgeo): mixes tangential positions in
};

/// M3C2-EP's level of detection.
enum class EpLod : std::uint8_t {
  kProjected,  ///< z sqrt(n^T (S1 + S2) n): the distance's own variance (nominal rate)
  kPublished,  ///< sqrt(chi2(3, confidence) / n^T (S1 + S2)^-1 n), Winiwarter et al. 2021
};

/// A scanner position of M3C2-EP: origin and the polar measurement's standard deviations.
/// sigma_range is in the clouds' unit; sigma_range_ppm adds b 1e-6 r in quadrature (the
/// distance-dependent part of a range specification "a + b ppm"); the angles are in radians:
/// sigma_scan the vertical (zenith) angle, sigma_yaw the horizontal one.
struct ScanPosition {
  std::uint32_t id = 0;
  double origin[3] = {0.0, 0.0, 0.0};
  double sigma_range = 0.0;
  double sigma_range_ppm = 0.0;
  double sigma_scan = 0.0;
  double sigma_yaw = 0.0;
};

/// One cloud's per-point uncertainty inputs (views: the memory must outlive the run).
struct CloudUncertainty {
  std::span<const double> precision;             ///< PM: sx, sy, sz per point (3 per point)
  std::span<const std::uint32_t> scan_position;  ///< EP: scan-position id of each point
  std::vector<ScanPosition> scan_positions;      ///< EP: the table the ids refer to
};

/// The inputs of Params::uncertainty beyond the clouds.
struct UncertaintyInputs {
  CloudUncertainty reference, compared;
  /// EP: the compared epoch's 3x4 affine transformation [R | t], row-major, applied about the
  /// reduction point: p' = R (p - red) + t + red.
  double transform[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
  /// EP: 12x12 covariance (row-major) of the parameters (r11, r12, r13, r21, ..., r33, tx, ty, tz);
  /// empty: no alignment error.
  std::vector<double> alignment_covariance;
  double reduction_point[3] = {0.0, 0.0, 0.0};
  /// EP: the compared cloud is given already transformed (its points are p').
  bool transform_applied = false;
  /// EP: also return each centre of gravity's 3x3 covariance (Result::covariance1/2).
  bool covariances = false;
};

/// The false-discovery-rate procedure of fdr_q_values().
enum class FdrMethod : std::uint8_t {
  kBenjaminiHochberg,   ///< BH step-up (Benjamini & Hochberg 1995): FDR <= Q under independence or PRDS
  kBenjaminiYekutieli,  ///< BY (Benjamini & Yekutieli 2001): BH times c(m) = sum_{i<=m} 1/i, any dependence
};

/// The adjusted p-values (q-values) of `p`: with the m finite p-values ranked by a stable sort on
/// (p, index), q_(i) = min_{j >= i} min(1, max(p_(j), c p_(j) m / j)), c = 1 (BH) or c(m) (BY) (the
/// max only undoes rounding: c m / j >= 1); NaN where p is
/// NaN (or infinite). A core point is a discovery at level Q iff q <= Q: the step-up procedure's
/// rejections exactly. O(m log m), float64, the same bits for the same p whatever the order of
/// the run's tiles (docs/algorithm.md, "False-discovery control").
std::vector<double> fdr_q_values(std::span<const double> p, FdrMethod method);

}  // namespace m3c2
