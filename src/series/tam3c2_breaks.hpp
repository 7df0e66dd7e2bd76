#pragma once
// The segments of TAM3C2's window breaks (include/m3c2/tam3c2.hpp, Tam3c2Breaks::kChangePoints;
// docs/series.md, "TAM3C2"): our extension, so that no aggregation window borrows across a step.

#include <m3c2/objects_by_change.hpp>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace m3c2::detail {

/// The segment of each pool epoch (0, 1, ... in time order) from the change points of `row`, one
/// core point's per-epoch M3C2 distance per pool epoch, read in the order `by_time` (the pool's
/// indices by time): NaN epochs are left out of the detection and belong to the segment of the
/// finite epoch before them (the first segment before any); a series of no more than p.width
/// finite epochs is one segment. `finite` is scratch.
void break_segments(const double* row, const std::vector<std::size_t>& by_time, const ChangePointParams& p,
                    std::vector<std::uint32_t>& segment, std::vector<double>& finite);

}  // namespace m3c2::detail
