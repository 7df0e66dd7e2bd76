#pragma once
// Parameters of an M3C2 run (Lague et al. 2013). Lengths are in the clouds' unit.
// D and d are DIAMETERS, as in the paper and CloudCompare; max_depth is a half-length.

#include <m3c2/uncertainty.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace m3c2 {

/// Where the normal of each core point comes from (section 3.1.2).
enum class NormalSource : std::uint8_t {
  kReference,   ///< PCA of the reference cloud (the paper's default)
  kCompared,    ///< PCA of the compared cloud
  kMean,        ///< normalised sum of both oriented normals: the reversible measurement
  kVertical,    ///< imposed (0, 0, 1): the 2D / DEM-of-difference mode
  kHorizontal,  ///< reference normal with z dropped, renormalised (vertical faces, CloudCompare mode 4)
  kCorePoints,  ///< one normal per core point supplied by the caller
};

/// Central position and spread of the points in a cylinder (section 3.1.3).
enum class Statistic : std::uint8_t {
  kMean,    ///< mean and standard deviation
  kMedian,  ///< median and interquartile range (sigma = IQR / kIqrToSigma); LOD as median_lod says
};

/// The statistic of the level of detection (section 3.3, Appendix B; docs/algorithm.md#6).
enum class Lod : std::uint8_t {
  kZ,          ///< eq. (1) with the normal critical value z (the paper's routine choice, CloudCompare's)
  kT,          ///< eq. (1) with Welch's t and eq. (2)'s degrees of freedom at every n
  kAuto,       ///< the paper's rule (3.3): Welch t when n1 or n2 < 30, else z (the median: z, see median_lod)
  kBootstrap,  ///< Appendix B: z (sd of bootstrap_samples resampled distances + reg)
};

/// Standard error of a cylinder's median in eq. (1) (section 3.3, Appendix B: the paper gives no
/// parametric LOD for the median; docs/algorithm.md#6.4).
enum class MedianLod : std::uint8_t {
  kMaritzJarrett,  ///< the exact bootstrap standard error of the median order statistic (Maritz & Jarrett 1978)
  kCloudCompare,   ///< CloudCompare's: IQR / kIqrToSigma in eq. (1) as if it were a mean's spread (understates)
};

/// Denominator of every variance: sample (n - 1, as py4dgeo) or population (n, as CloudCompare).
enum class Variance : std::uint8_t { kSample, kPopulation };

/// How the cylinder's length is searched (sections 3.1.3 and 5.3).
enum class DepthSearch : std::uint8_t {
  kSinglePass,   ///< one cylinder of half-length max_depth
  kTwoPass,      ///< half-length first_pass_depth first; max_depth where that found no point in a cloud
  kProgressive,  ///< CloudCompare's: per cloud, grow by d/2 per pass until |i| + 2 sigma < half-length
};

/// Scale selection rule of multi-scale normals (section 3.2).
enum class ScaleSelection : std::uint8_t {
  kMostPlanar,    ///< smallest lambda3 / (lambda1 + lambda2 + lambda3), the paper's rule
  kCloudCompare,  ///< CloudCompare's largest 2 s0 + 4 s1 - 2 with s_k = lambda_k^2 / sum lambda^2
  kPy4dgeo,       ///< py4dgeo's largest planarity (lambda2 - lambda3) / lambda1 (lambda1 the largest)
};

/// Orientation of normals (section 3.1.2): towards the closest orientation point when any are
/// given (the paper's scanner positions), otherwise along `direction` (+Z by default).
struct Orientation {
  std::array<double, 3> direction = {0.0, 0.0, 1.0};
  std::vector<double> points;  ///< row-major x, y, z of orientation points; may be empty
  /// Away from the closest orientation point instead of towards it (CloudCompare's "+"
  /// barycentre, origin and sensor modes: n . (core - point) >= 0); needs points.
  bool away = false;
};

/// IQR of a normal distribution in units of its standard deviation: 2 * Phi^-1(0.75).
inline constexpr double kIqrToSigma = 1.3489795003921634;

/// The most bootstrap resamples per core point (Appendix B). The sd of B resampled distances has
/// a relative sampling error of about 1 / sqrt(2 (B - 1)): 0.22 % at this bound, far below the
/// spread of the LOD itself, while each resample costs n1 + n2 draws per core point, so a larger
/// B only makes a run that cannot finish (10^9 resamples also took 8 GB per thread).
inline constexpr std::uint32_t kMaxBootstrapSamples = 100000;

struct Params {
  // Normals (3.1.2, 3.2)
  std::vector<double> normal_diameters;  ///< D; several values = multi-scale
  NormalSource normal_source = NormalSource::kReference;
  ScaleSelection scale_selection = ScaleSelection::kMostPlanar;
  std::uint32_t min_points_normal = 3;       ///< fewest neighbours for a plane fit (one scale)
  std::uint32_t min_points_multiscale = 10;  ///< fewest neighbours at a chosen scale (3.2)
  double normal_subsample_spacing = 0.0;     ///< > 0: normals on a copy subsampled to this spacing (5.1)
  Orientation orientation;

  // Projection (3.1.3)
  double projection_diameter = 0.0;  ///< d: cylinder diameter
  double max_depth = 0.0;            ///< cylinder half-length along the normal, on each side
  DepthSearch depth_search = DepthSearch::kSinglePass;
  double first_pass_depth = 0.0;      ///< kTwoPass: half-length of the first, short cylinder
  bool positive_search_only = false;  ///< search only t in [0, max_depth] (CloudCompare option)
  Statistic statistic = Statistic::kMean;
  Variance variance = Variance::kSample;

  // Confidence (3.3, Appendix B)
  double registration_error = 0.0;  ///< reg in eq. (1)
  double confidence = 0.95;         ///< two-tailed level of the LOD
  std::uint32_t min_points = 4;     ///< per cylinder, below it no LOD and not significant (5.2.1)
  Lod lod = Lod::kZ;                ///< the statistic of the LOD (the command line's default is its own)
  MedianLod median_lod = MedianLod::kMaritzJarrett;  ///< with Statistic::kMedian and a parametric lod
  std::uint32_t bootstrap_samples = 0;               ///< resamples of Lod::kBootstrap (>= 2 there, at most
                                                     ///< kMaxBootstrapSamples), App. B
  std::uint64_t bootstrap_seed = 0;                  ///< Lod::kBootstrap: the stream of core point i is (seed, i)
  /// sigma_c^2: the variance of the spatially correlated error of a cylinder mean at this d (an
  /// error model's partial sills, `m3c2 variogram`), added inside every eq. (1) LOD's square root:
  /// z sqrt(s1^2/n1 + s2^2/n2 + sigma_c^2) + reg (docs/algorithm.md, "Spatially correlated errors";
  /// Rolstad et al. 2009, Hugonnet et al. 2022). 0: off. Refused with PM and EP.
  double correlated_variance = 0.0;

  // Per-point uncertainty (6.2; include/m3c2/uncertainty.hpp, docs/algorithm.md §6.5)
  Uncertainty uncertainty = Uncertainty::kEq1;             ///< eq. (1), M3C2-PM or M3C2-EP
  PrecisionRule precision_rule = PrecisionRule::kNearest;  ///< PM: which points give sigma
  double precision_scale1 = 1.0;  ///< PM: scale of the reference cloud's sigmas (qM3C2's PM1Scale)
  double precision_scale2 = 1.0;  ///< PM: scale of the compared cloud's sigmas (PM2Scale)
  EpCovariance ep_covariance = EpCovariance::kEmpirical;  ///< EP: the centres' covariance (docs/validation.md §7)
  EpLod ep_lod = EpLod::kProjected;                       ///< EP: the level of detection
  EpWeights ep_weights = EpWeights::kNormal;              ///< EP: the weights of the centres of gravity
};

/// Every field of Params once, with the name the bindings and the Python parameter table use
/// (docs/architecture.md): `visit(name, access)` where `access(params)` returns a reference to
/// the field. The binding builds its properties and its pickling from this list, and a test checks
/// it against the Python table, so a new field is added here and nowhere else in C++.
template <class Visitor>
constexpr void visit_param_fields(Visitor&& visit) {
  visit(
      "normal_diameters", [](auto& p) -> auto& { return p.normal_diameters; });
  visit(
      "normal_source", [](auto& p) -> auto& { return p.normal_source; });
  visit(
      "scale_selection", [](auto& p) -> auto& { return p.scale_selection; });
  visit(
      "min_points_normal", [](auto& p) -> auto& { return p.min_points_normal; });
  visit(
      "min_points_multiscale", [](auto& p) -> auto& { return p.min_points_multiscale; });
  visit(
      "normal_subsample_spacing", [](auto& p) -> auto& { return p.normal_subsample_spacing; });
  visit(
      "orientation_direction", [](auto& p) -> auto& { return p.orientation.direction; });
  visit(
      "orientation_points", [](auto& p) -> auto& { return p.orientation.points; });
  visit(
      "orientation_away", [](auto& p) -> auto& { return p.orientation.away; });
  visit(
      "projection_diameter", [](auto& p) -> auto& { return p.projection_diameter; });
  visit(
      "max_depth", [](auto& p) -> auto& { return p.max_depth; });
  visit(
      "depth_search", [](auto& p) -> auto& { return p.depth_search; });
  visit(
      "first_pass_depth", [](auto& p) -> auto& { return p.first_pass_depth; });
  visit(
      "positive_search_only", [](auto& p) -> auto& { return p.positive_search_only; });
  visit(
      "statistic", [](auto& p) -> auto& { return p.statistic; });
  visit(
      "variance", [](auto& p) -> auto& { return p.variance; });
  visit(
      "registration_error", [](auto& p) -> auto& { return p.registration_error; });
  visit(
      "confidence", [](auto& p) -> auto& { return p.confidence; });
  visit(
      "min_points", [](auto& p) -> auto& { return p.min_points; });
  visit(
      "lod", [](auto& p) -> auto& { return p.lod; });
  visit(
      "median_lod", [](auto& p) -> auto& { return p.median_lod; });
  visit(
      "bootstrap_samples", [](auto& p) -> auto& { return p.bootstrap_samples; });
  visit(
      "bootstrap_seed", [](auto& p) -> auto& { return p.bootstrap_seed; });
  visit(
      "correlated_variance", [](auto& p) -> auto& { return p.correlated_variance; });
  visit(
      "uncertainty", [](auto& p) -> auto& { return p.uncertainty; });
  visit(
      "precision_rule", [](auto& p) -> auto& { return p.precision_rule; });
  visit(
      "precision_scale1", [](auto& p) -> auto& { return p.precision_scale1; });
  visit(
      "precision_scale2", [](auto& p) -> auto& { return p.precision_scale2; });
  visit(
      "ep_covariance", [](auto& p) -> auto& { return p.ep_covariance; });
  visit(
      "ep_lod", [](auto& p) -> auto& { return p.ep_lod; });
  visit(
      "ep_weights", [](auto& p) -> auto& { return p.ep_weights; });
}

}  // namespace m3c2
