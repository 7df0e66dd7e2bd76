#pragma once
// Projection cylinder of section 3.1.3: axis through the core point along the normal.

#include "kdtree.hpp"

#include <vector>

namespace m3c2::detail {

/// The cylinder of radius `radius` (d / 2) whose axis passes through `core` along the unit
/// `normal`, restricted to axial offsets t in [t_min, t_max]. Both boundaries are inclusive:
/// p is inside iff |v - t n|^2 <= radius^2 and t_min <= t <= t_max, with v = p - core and
/// t = v . n, computed in that order in float64 (docs/algorithm.md#boundaries).
struct Cylinder {
  Vec3 core;
  Vec3 normal;
  double radius = 0.0;
  double t_min = 0.0;
  double t_max = 0.0;
};

/// Reusable per-thread buffers of cylinder_offsets().
struct CylinderScratch {
  std::vector<std::uint32_t> candidates;
  std::vector<std::pair<std::uint32_t, double>> hits;
};

/// Axial offsets t of the points of `tree` inside `cyl`, ordered by point index (so that the
/// statistics do not depend on how the index is built). Replaces the contents of `t_out`.
///
/// The axis is cut into segments no longer than the diameter; each segment is searched with the
/// smallest ball containing it, and a point is kept only by the segment that owns its t
/// (half-open segments, the last one closed), so nothing on a segment boundary is lost or doubled.
void cylinder_offsets(const KdTree& tree, const Cylinder& cyl, CylinderScratch& scratch,
                      std::vector<double>& t_out);

}  // namespace m3c2::detail
