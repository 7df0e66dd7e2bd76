#pragma once
// The order in which core points are processed: along a Morton (Z-order) curve, so that
// consecutive core points share most of their neighbours and those stay in cache.

#include <m3c2/points_view.hpp>

#include <cstdint>
#include <vector>

namespace m3c2::detail {

/// A permutation of [0, points.size()) sorting the points along a 3D Morton curve over their
/// bounding box (1024 cells per axis; ties keep input order). Only the processing order depends on
/// it: results are written by index, so they do not.
std::vector<std::uint32_t> morton_order(PointsView points);

}  // namespace m3c2::detail
