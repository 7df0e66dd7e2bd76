#pragma once
// Bootstrap level of detection (Appendix B).

#include <m3c2/params.hpp>

#include "support/pulse.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace m3c2::detail {

/// Standard deviation (n - 1) of the distance stat(resample2) - stat(resample1) over
/// params.bootstrap_samples resamples drawn with replacement from each cylinder's offsets;
/// stat is the mean or the median as params.statistic says. The random stream depends only on
/// (params.bootstrap_seed, core_index), so results do not depend on threads or order. `pulse`
/// beats once per resample, so that a run cancels inside a long bootstrap (Cancelled).
double bootstrap_sigma(std::span<const double> t1, std::span<const double> t2, const Params& params,
                       std::uint64_t core_index, std::vector<double>& work, Pulse& pulse);

}  // namespace m3c2::detail
