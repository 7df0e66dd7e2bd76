#pragma once
// Checks at the API boundary: a caller's mistake throws InvalidArgument naming the value.

#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>

#include <string_view>

namespace m3c2::detail {

void require_positive(std::string_view name, double value);
void require_finite_points(std::string_view name, PointsView points);
/// Cell indices (extent / cell) must stay exact integers: at most 2^40 cells along an axis.
void require_cell_count(std::string_view name, double cell, PointsView points);
void validate_normal_params(const Params& params);
void validate_orientation(const Orientation& orientation);
void validate_params(const Params& params);

}  // namespace m3c2::detail
