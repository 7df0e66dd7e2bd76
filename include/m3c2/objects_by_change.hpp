#pragma once
// Analysis of an M3C2 time series (docs/series.md): temporal median smoothing, the change-point
// detection and the 4D objects-by-change (4D-OBC) of Anders et al. (2021, "Fully automatic
// spatiotemporal segmentation of 3D LiDAR time series for the extraction of natural surface
// changes", ISPRS J. Photogramm. 173: 297-308), whose reference implementation is py4dgeo's
// RegionGrowingAlgorithm. Time series are rows of a row-major [core point][epoch] float64
// array; NaN marks an epoch without a distance. Every function is deterministic: the same
// bits for any thread count.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace m3c2 {

/// Median of each row over the epochs [t - window / 2, t + window / 2] (clipped to the series),
/// ignoring NaN; NaN where the window holds none. window >= 1 (1: a copy).
std::vector<double> temporal_median(const double* values, std::size_t rows, std::size_t epochs, std::uint32_t window,
                                    const RunOptions& run = {});

/// Sliding-window change-point detection with the L1 cost (Anders et al. 2021, 2.3.1; the
/// window method of Truong et al. 2020): the gain of splitting each window of `width` epochs at
/// its centre, its local maxima (within max(width, 2 min_size) / (2 jump) epochs, the series
/// treated as circular as ruptures and py4dgeo do), then the maxima by decreasing gain while
/// each lowers the total cost by more than `penalty`.
struct ChangePointParams {
  std::uint32_t width = 24;
  std::uint32_t min_size = 12;
  std::uint32_t jump = 1;
  double penalty = 1.0;  ///< > 0
};

/// The change points of one series (no NaN), ascending, without the series' end.
std::vector<std::uint32_t> change_points(const double* series, std::size_t epochs, const ChangePointParams& p);

/// DTW distance (absolute differences, steps (1,0), (0,1), (1,1)) between a - norm_a and
/// b - norm_b over the epochs where both are finite, divided by D_max = sum |a - dmax_origin|
/// over the finite epochs of a, capped at 1 (Anders et al. 2021, eq. 3). NaN when no epoch is
/// shared. O(n) memory. The computation may stop as soon as the result is known to be >= at_least
/// (a lower bound on the cost, src/series/dtw_bound.hpp, or a row's minimum plus the bound of the rows
/// below it: every warping path crosses each row) and then returns 1: exact for any comparison
/// with a threshold <= at_least, and the exact value with at_least = 1 (the result is capped).
double normalised_dtw(const double* a, const double* b, std::size_t n, double norm_a, double norm_b, double dmax_origin,
                      double at_least = 1.0);

/// Where a seed starts and from what level 4D-OBC's DTW measures each series (docs/series.md,
/// "Analysis"). Every rule compares the seed's epochs [start, end] only; they differ in each
/// series' offset, in D_max and in the seeds.
enum class ObjectsDtw : std::uint8_t {
  /// Ours (the default): a seed starts at the last epoch before its change point and its volume
  /// is measured from a baseline, the median of the epochs [base, start] (the half window of the
  /// change-point detection before the change, cut at the previous change point); the DTW offsets
  /// each series by its own median over those epochs and D_max = sum |a - baseline_a|. The median
  /// is the level the L1 cost of the detection fitted to that segment (Truong et al. 2020; Anders
  /// et al. 2021, 2.3.1), so steps, reversals and slow ramps are measured from before the change,
  /// not from one noisy epoch after it. A seed ends when the series is back within the baseline
  /// window's median absolute deviation, or at a later change point by more than half the change.
  /// The ratio rule starts at the first threshold with min_segments core points, and a seed
  /// adjacent to an earlier object's core point over shared epochs is skipped.
  kBaseline,
  /// py4dgeo's seeds (a seed starts at its change point); each series offset by its value at the
  /// seed's start, D_max = sum |a - a_start|: the rule before the baseline (eq. 3 of Anders et al.
  /// 2021 with the seed's first epoch as "no change").
  kSeedStart,
  /// py4dgeo 1.2.0's RegionGrowingAlgorithm exactly (lib/segmentation.cpp, segmentation.py): its
  /// seeds; growth: each series offset by its value at the series' first epoch, D_max = sum |a| of
  /// the raw seed slice; seed score: raw slices, no offsets; min_segments applied only to an object
  /// chosen by the ratio rule (not to one at max_segments or the largest threshold).
  kPy4dgeo,
};

/// Parameters of 4D-OBC; the defaults are py4dgeo's RegionGrowingAlgorithm's but for `dtw`.
struct ObjectsParams {
  ChangePointParams change_points;
  std::uint32_t min_period = 24;       ///< fewest epochs from a seed's start to its end
  double height_threshold = 0.0;       ///< least |max - min| of a seed's change
  bool use_unfinished = true;          ///< seeds still growing at the last epoch are kept
  std::uint32_t seed_subsampling = 1;  ///< every k-th core point is searched for seeds
  double neighbourhood_radius = 1.0;   ///< core points within it are adjacent (3D)
  std::vector<double> thresholds{0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9};  ///< of the normalised DTW
  std::uint32_t min_segments = 20;                                              ///< fewest core points of an object
  std::uint64_t max_segments = 0;                                               ///< 0: no limit
  double max_cv = 0.8;  ///< objects whose DTW values have a larger coefficient of variation are dropped
  ObjectsDtw dtw = ObjectsDtw::kBaseline;
  /// Memory for the table of every core point's neighbours (4 bytes a pair); a build that would
  /// pass it stops and drops the table, and each neighbourhood is searched when region growing
  /// needs it (same objects, slower).
  std::uint64_t neighbour_table_bytes = std::uint64_t(1) << 30;
};

struct Seed {
  std::uint32_t core = 0, start = 0, end = 0;  ///< epochs [start, end]
  std::uint32_t base = 0;  ///< the baseline's epochs [base, start] (ObjectsDtw::kBaseline; start otherwise)
  double score = 0.0;      ///< mean normalised DTW to its neighbours (ascending = first grown)
};

struct ChangeObject {
  Seed seed;
  double threshold = 0.0;            ///< the DTW threshold chosen by the adaptive rule
  std::vector<std::uint32_t> cores;  ///< ascending
  std::vector<double> dtw;           ///< of each core's series to the seed's (0 for the seed)
};

struct ObjectsResult {
  std::vector<Seed> seeds;  ///< in growing order
  std::vector<ChangeObject> objects;
};

/// Seeds of every (subsampled) core point: change points, then the change's volume grown
/// until it decreases (py4dgeo's rule; from the baseline under ObjectsDtw::kBaseline); NaN epochs
/// interpolated linearly first, series with fewer than 3 finite epochs skipped. Unsorted: core
/// order, then time.
std::vector<Seed> find_seeds(const double* distances, std::size_t rows, std::size_t epochs, const ObjectsParams& p,
                             const RunOptions& run = {});

/// The whole 4D-OBC: seeds scored and sorted, each grown by region growing at every threshold
/// (candidates in ascending DTW, only those under the 95th percentile of the object's DTW values
/// growing it further), the threshold picked before the object's size doubles, objects with
/// fewer than min_segments core points or a larger coefficient of variation than max_cv
/// dropped; a seed inside an earlier object's extent in space and time is skipped (under
/// ObjectsDtw::kBaseline also one adjacent to such an object's core point).
ObjectsResult objects_by_change(const double* distances, std::size_t rows, std::size_t epochs, PointsView core,
                                const ObjectsParams& p, const RunOptions& run = {});

}  // namespace m3c2
