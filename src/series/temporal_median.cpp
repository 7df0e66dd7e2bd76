// temporal_median(): the smoothing of a series before 4D-OBC (Anders et al. 2021, 2.2: a
// temporal median filter suppresses noise and outlier epochs while keeping the change's onset).

#include <m3c2/errors.hpp>
#include <m3c2/objects_by_change.hpp>

#include "support/parallel_for.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace m3c2 {

std::vector<double> temporal_median(const double* values, std::size_t rows, std::size_t epochs, std::uint32_t window,
                                    const RunOptions& run) {
  if (window < 1) throw InvalidArgument("the smoothing window must be >= 1 epoch, got 0");
  std::vector<double> out(rows * epochs, std::numeric_limits<double>::quiet_NaN());
  const std::size_t half = window / 2;
  detail::parallel_blocks<std::vector<double>>(
      rows, run, [&](std::size_t begin, std::size_t end, std::vector<double>& w) {
        for (std::size_t r = begin; r < end; ++r) {
          const double* row = values + r * epochs;
          for (std::size_t t = 0; t < epochs; ++t) {
            w.clear();
            const std::size_t lo = t >= half ? t - half : 0, hi = std::min(epochs - 1, t + half);
            for (std::size_t k = lo; k <= hi; ++k)
              if (!std::isnan(row[k])) w.push_back(row[k]);
            if (w.empty()) continue;
            const std::size_t m = w.size() / 2;
            std::nth_element(w.begin(), w.begin() + m, w.end());
            double median = w[m];
            if (w.size() % 2 == 0) median = 0.5 * (*std::max_element(w.begin(), w.begin() + m) + median);
            out[r * epochs + t] = median;
          }
        }
      });
  return out;
}

}  // namespace m3c2
