// break_segments(): TAM3C2's window breaks (tam3c2_breaks.hpp) from the change points of 4D-OBC's
// seed detection (change_points.cpp; Anders et al. 2021, 2.3.1), run on the finite epochs only:
// a gap is no evidence of a step, and interpolating it would put the step inside the gap.

#include "tam3c2_breaks.hpp"

#include <cmath>

namespace m3c2::detail {

void break_segments(const double* row, const std::vector<std::size_t>& by_time, const ChangePointParams& p,
                    std::vector<std::uint32_t>& segment, std::vector<double>& finite) {
  finite.clear();
  for (std::size_t e : by_time)
    if (std::isfinite(row[e])) finite.push_back(row[e]);
  std::vector<std::uint32_t> starts;  // indices into `finite` where a segment begins
  if (finite.size() > p.width) starts = change_points(finite.data(), finite.size(), p);
  segment.assign(by_time.size(), 0);
  std::uint32_t current = 0;
  std::size_t k = 0, next = 0;
  for (std::size_t e : by_time) {
    if (std::isfinite(row[e])) {
      if (next < starts.size() && k == starts[next]) ++current, ++next;
      ++k;
    }
    segment[e] = current;
  }
}

}  // namespace m3c2::detail
