#pragma once
// Projection onto the cylinder axis (section 3.1.3).

#include "kdtree.hpp"

#include <vector>

namespace m3c2::detail {

/// Reusable per-thread buffer of cylinder_offsets().
struct CylinderScratch {
  std::vector<std::pair<std::uint32_t, double>> hits;
};

/// Axial offsets t of the points of `tree` inside `cyl` (KdTree::cylinder), ordered by point
/// index so that the statistics do not depend on how the index is built. Replaces `t_out`.
void cylinder_offsets(const KdTree& tree, const Cylinder& cyl, CylinderScratch& scratch,
                      std::vector<double>& t_out);

}  // namespace m3c2::detail
