// False-discovery control over a run's p-values (Benjamini & Hochberg 1995; Benjamini &
// Yekutieli 2001): the adjusted p-values of the step-up procedure, one global ranking of every
// core point (docs/algorithm.md, "False-discovery control").

#include <m3c2/errors.hpp>
#include <m3c2/uncertainty.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace m3c2 {

std::vector<double> fdr_q_values(std::span<const double> p, FdrMethod method) {
  std::vector<double> q(p.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<std::uint64_t> order;
  order.reserve(p.size());
  for (std::size_t i = 0; i < p.size(); ++i)
    if (std::isfinite(p[i])) {
      if (p[i] < 0.0 || p[i] > 1.0)
        throw InvalidArgument("p-value " + std::to_string(i) + " is " + std::to_string(p[i]) + ", outside [0, 1]");
      order.push_back(i);
    }
  const std::size_t m = order.size();
  if (m == 0) return q;
  // Ties keep the core points' order (stable): the ranking is a function of (p, index) alone.
  std::stable_sort(order.begin(), order.end(), [&](std::uint64_t a, std::uint64_t b) { return p[a] < p[b]; });
  // c(m) = sum 1/i, summed from the smallest term up (the same bits for the same m).
  double c = 1.0;
  if (method == FdrMethod::kBenjaminiYekutieli) {
    c = 0.0;
    for (std::size_t i = m; i >= 1; --i) c += 1.0 / double(i);
  }
  // Step-up: q_(j) = min over k >= j of c m p_(k) / k, clamped to 1, from the largest rank down.
  double running = 1.0;
  for (std::size_t j = m; j >= 1; --j) {
    // c m / j >= 1: q >= p, which rounding alone could break (m p / m may round below p).
    const double pj = p[order[j - 1]];
    const double v = std::max(pj, c * (double(m) * pj / double(j)));
    running = std::min(running, v);
    q[order[j - 1]] = running;
  }
  return q;
}

}  // namespace m3c2
