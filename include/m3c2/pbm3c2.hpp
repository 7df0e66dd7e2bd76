#pragma once
// PB-M3C2, correspondence-driven plane-based M3C2 (Zahs et al. 2022, ISPRS J. 183: 541-559): both
// epochs are cut into planar segments, each reference segment is paired with the compared
// segment of the same surface, and the change is the distance between the two planes along the
// reference plane's normal, with eq. (1)'s LOD from the planes' fit (Lague et al. 2013, 3.3).
// docs/pbm3c2.md derives each step.

#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace m3c2 {

/// Region growing on normals (Rabbani et al. 2006, the segmentation of Zahs et al. 2022, 3.2).
/// Lengths are in the cloud's unit.
struct PlaneSegmentationParams {
  /// D: each point's normal and roughness sigma(D) come from its neighbours within this DIAMETER (3.1.2).
  double normal_diameter = 0.0;
  /// A segment grows to the points within this DIAMETER of its points; 0: normal_diameter.
  double growth_diameter = 0.0;
  /// A point joins when its normal is within this angle of the segment plane's (unoriented).
  double max_angle_degrees = 10.0;
  /// ... and it lies within this distance of the segment's plane; 0: normal_diameter / 4.
  double max_plane_distance = 0.0;
  /// Segments of fewer points are dropped: their points stay unsegmented (kSmallSegment).
  std::uint32_t min_points = 50;
  /// Fewest neighbours a normal is fitted from (fewer: kNoNormal).
  std::uint32_t min_normal_points = 6;
};

/// Why a point is in no segment.
enum class SegmentStatus : std::uint8_t {
  kSegmented = 0,
  kNoNormal = 1,      ///< fewer than min_normal_points within D, or a degenerate neighbourhood
  kSmallSegment = 2,  ///< it grew into a segment of fewer than min_points
};

struct PlaneSegmentation {
  std::vector<std::int64_t> labels;   ///< per point: its segment 0..segments-1, or -1
  std::vector<SegmentStatus> status;  ///< per point
  std::uint64_t segments = 0;
};

/// Segments `points` into planes. Seeds are taken flattest first (smallest sigma(D), then lowest
/// index); a segment's plane is refitted to its points whenever it has doubled. Normals are
/// computed in parallel, the growth is sequential: the same labels for any thread count.
/// Throws InvalidArgument for bad parameters or a non-finite coordinate; Cancelled.
PlaneSegmentation segment_planes(PointsView points, const PlaneSegmentationParams& params, const RunOptions& run = {});

/// The planes of the segments, struct of arrays, one row per segment (ascending label).
struct PlaneSegments {
  std::vector<std::int64_t> label;
  std::vector<std::uint64_t> count;
  std::vector<double> centroid;     ///< 3 per segment
  std::vector<double> normal;       ///< 3 per segment, unit, oriented; NaN below 3 points or degenerate
  std::vector<double> eigenvalues;  ///< 3 per segment, descending, of the covariance (divided by n)
  std::vector<double> major_axis;   ///< 3 per segment: the eigenvector of the largest eigenvalue
  /// sqrt(sum h^2 / (n - 3)): the points' spread about their least-squares plane (h: distances to
  /// it; three parameters fitted). NaN below 4 points.
  std::vector<double> roughness;
  std::size_t size() const { return label.size(); }
};

/// The least-squares plane of each segment: points with label l >= 0 form segment l (a label
/// < 0 is no segment). Two passes (the mean, then centred moments), summed in point order: exact
/// at projected coordinates and the same bits for any thread count. Normals by `orientation`.
PlaneSegments plane_segments(PointsView points, std::span<const std::int64_t> labels, const Orientation& orientation,
                             const RunOptions& run = {});

/// Which compared segment each reference segment is paired with.
enum class PairStatus : std::uint8_t {
  kPaired = 0,
  kNoPlane = 1,        ///< the reference segment has no plane (too few points, degenerate)
  kNoCandidate = 2,    ///< no compared plane within search_radius and max_angle_degrees
  kNotMutual = 3,      ///< its compared segment's own choice is another reference segment (mutual)
  kNotClassified = 4,  ///< the classifier accepted no candidate (m3c2kit.pbm3c2's random forest)
};

/// The geometric rule (py4dgeo's nearest neighbour, with an angle gate): the compared segment
/// whose centroid is nearest the reference segment's, among those within search_radius whose
/// plane is within max_angle_degrees; ties to the lower row.
struct CorrespondenceParams {
  double search_radius = 0.0;
  double max_angle_degrees = 30.0;
  /// Keep a pair only when the reference segment is also the compared one's nearest (same gates).
  bool mutual = false;
};

struct SegmentPairs {
  std::vector<std::int64_t> compared;  ///< per reference row: the compared row, or -1
  std::vector<PairStatus> status;      ///< per reference row
};

SegmentPairs nearest_segments(const PlaneSegments& reference, const PlaneSegments& compared,
                              const CorrespondenceParams& params);

/// The overlap rule: each reference point of a segment votes for the segment of its nearest
/// compared point within search_radius, when that point is in a segment (an unsegmented nearest
/// point votes for nothing: the surface is there, unsegmented) whose plane is within
/// max_angle_degrees of its own; a reference segment's pair is the compared segment with the most
/// votes (ties to the lower row). A surface moved by less than its distance to other surfaces
/// overlaps its old self whatever the extents the two segmentations gave it, where centroids of
/// partly covered surfaces drift apart. `mutual`: the compared segment's own vote (its points for
/// reference segments) must name the reference segment back. Labels as plane_segments() reads
/// them (< 0: no segment); the planes are plane_segments()'s of the same labels.
SegmentPairs overlapping_segments(PointsView reference, std::span<const std::int64_t> reference_labels,
                                  const PlaneSegments& reference_planes, PointsView compared,
                                  std::span<const std::int64_t> compared_labels, const PlaneSegments& compared_planes,
                                  const CorrespondenceParams& params, const RunOptions& run = {});

/// How well each paired compared plane represents its surface where the reference segment is: the
/// mean signed distance to it of the paired segment's points over the reference segment's footprint,
/// and how many. A compared point is over it when its foot on the reference plane lies within two
/// spacings of one of the segment's points, measured in that plane (the spacing sqrt(A / n), A =
/// 12 sqrt(lambda1 lambda2) the segment's area, exact for a rectangle). Each point counts once per
/// reference segment, whatever the segment's other pairs, and is chosen by its position in the plane,
/// not by its residual: for a true plane the mean is 0 +- sigma2 / sqrt(points) at most. A plane grown
/// over a curved or stepped surface is off there by more than its points' noise, and the distance by as
/// much, which no LOD accounts for (docs/pbm3c2.md). NaN and 0 where compared_of_reference[i] < 0, a
/// plane is missing or no compared point is over the footprint. Each pair is summed alone, in point
/// order: the same bits for any thread count. InvalidArgument for a compared row out of range.
struct PlaneMisfit {
  std::vector<double> mean_residual;
  std::vector<std::uint64_t> points;
};

PlaneMisfit compared_plane_misfit(PointsView reference, std::span<const std::int64_t> reference_labels,
                                  const PlaneSegments& reference_planes, PointsView compared,
                                  std::span<const std::int64_t> compared_labels, const PlaneSegments& compared_planes,
                                  std::span<const std::int64_t> compared_of_reference, const RunOptions& run = {});

/// Every (reference row, compared row) whose centroids are within search_radius, both planes
/// defined, in row order: the candidates a classifier scores. InvalidArgument beyond 2e7 pairs
/// (a radius that pairs every segment with every other).
struct SegmentCandidates {
  std::vector<std::int64_t> reference, compared;
};

SegmentCandidates segment_candidates(const PlaneSegments& reference, const PlaneSegments& compared,
                                     double search_radius);

/// What a classifier sees of a pair (py4dgeo's PBM3C2 features, Zahs et al. 2022, 3.4).
struct PairFeatures {
  std::vector<double> centroid_distance;     ///< |c2 - c1|
  std::vector<double> normal_angle;          ///< radians between the planes (unoriented)
  std::vector<double> roughness_difference;  ///< |sigma1 - sigma2|
};

/// The features of the pairs (reference[k], compared[k]); InvalidArgument for a row out of range.
PairFeatures pair_features(const PlaneSegments& reference, const PlaneSegments& compared,
                           std::span<const std::int64_t> reference_rows, std::span<const std::int64_t> compared_rows);

/// The change of one pair: the distance from the reference centroid c1 along its normal n1 to
/// the compared plane (c2, n2), t = (c2 - c1) . n2 / (n1 . n2), and eq. (1)'s LOD with the
/// centres' standard errors sigma_k / sqrt(n_k) and reg (Zahs et al. 2022, eq. 3).
struct PlaneChanges {
  std::vector<double> distance;
  std::vector<double> lod;
  std::vector<std::uint8_t> significant;  ///< |distance| > lod
  std::vector<double> normal_angle;       ///< degrees between the two planes (unoriented)
};

/// `params` gives confidence, registration_error, correlated_variance and lod (kAuto: Student's t
/// with eq. (2)'s degrees of freedom below 30 points; kBootstrap is refused). The compared plane's
/// standard error is its height's where the distance meets it, from its fit (docs/pbm3c2.md).
/// NaN where compared_of_reference[i] < 0 or a plane is missing.
PlaneChanges plane_changes(const PlaneSegments& reference, const PlaneSegments& compared,
                           std::span<const std::int64_t> compared_of_reference, const Params& params);

}  // namespace m3c2
