#pragma once
// Step 2 of the algorithm (section 3.1.3): the two clouds' offsets along the normal.

#include "index/octree.hpp"

#include <m3c2/params.hpp>

#include <vector>

namespace m3c2::detail {

struct ProjectionScratch {
  std::vector<double> full, work;
  std::vector<std::uint32_t> full_index;
  DescentCache descent;
};

/// Offsets of both clouds in the cylinder at `core` along `normal` (in the octree's key order,
/// the same in any tile), with the depth search of
/// params.depth_search:
/// - kSinglePass: half-length max_depth.
/// - kTwoPass (5.3): half-length first_pass_depth; the full max_depth only when that short
///   cylinder held no point of one of the clouds (the core point "could not be projected").
/// - kProgressive (CloudCompare): for each cloud on its own, the half-length grows by d/2 up to
///   max_depth; at each length that added points, the search stops if the cloud has
///   >= min_points points and |i| + 2 sigma < h; the offsets of that truncated cylinder are kept.
/// `index1`, `index2`, if given, receive the original indices of the points of t1, t2 (same order).
void project(const Octree& reference, const Octree& compared, const Vec3& core, const Vec3& normal,
             const Params& params, ProjectionScratch& scratch, std::vector<double>& t1, std::vector<double>& t2,
             std::vector<std::uint32_t>* index1 = nullptr, std::vector<std::uint32_t>* index2 = nullptr);

/// project()'s two searches in one cloud, for a caller that keeps one cloud's offsets (a time
/// series' reference): project() is the first pass in both clouds (kTwoPass only), kept when
/// neither came back empty, else the full depth in both.
/// The short cylinder of kTwoPass (half-length first_pass_depth) in `cloud`.
void project_first_pass(const Octree& cloud, const Vec3& core, const Vec3& normal, const Params& params,
                        ProjectionScratch& scratch, std::vector<double>& t,
                        std::vector<std::uint32_t>* index = nullptr);
/// The full depth in `cloud`: half-length max_depth, then kProgressive's truncation.
void project_full_depth(const Octree& cloud, const Vec3& core, const Vec3& normal, const Params& params,
                        ProjectionScratch& scratch, std::vector<double>& t,
                        std::vector<std::uint32_t>* index = nullptr);

}  // namespace m3c2::detail
