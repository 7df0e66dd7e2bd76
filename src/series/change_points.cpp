// change_points(): the sliding-window change-point detection of 4D-OBC's seeds (Anders et al.
// 2021, 2.3.1), with the L1 cost: sum |x - median| over a segment (Truong et al. 2020, the
// "window" search method; py4dgeo's change_point_detection).

#include <m3c2/errors.hpp>
#include <m3c2/objects_by_change.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

namespace m3c2 {
namespace {

/// sum |x - median| over series[begin, end); 0 for an empty segment. The sum runs in time order.
double l1_cost(const double* series, std::size_t begin, std::size_t end, std::vector<double>& work) {
  if (end <= begin) return 0.0;
  work.assign(series + begin, series + end);
  const std::size_t m = work.size() / 2;
  std::nth_element(work.begin(), work.begin() + m, work.end());
  double median = work[m];
  if (work.size() % 2 == 0) median = 0.5 * (*std::max_element(work.begin(), work.begin() + m) + median);
  double sum = 0.0;
  for (std::size_t k = begin; k < end; ++k) sum += std::abs(series[k] - median);
  return sum;
}

/// Total cost of the segmentation of [0, n) at `breaks` (ascending, the last one n).
double total_cost(const double* series, const std::vector<std::size_t>& breaks, std::vector<double>& work) {
  double sum = 0.0;
  std::size_t begin = 0;
  for (const std::size_t b : breaks) {
    sum += l1_cost(series, begin, b, work);
    begin = b;
  }
  return sum;
}

/// Indices k of strict local maxima of `score`: larger than every score within `order`
/// positions on either side, the sequence read as circular (scipy's argrelmax, mode "wrap").
std::vector<std::size_t> local_maxima(const std::vector<double>& score, std::size_t order) {
  std::vector<std::size_t> out;
  const std::size_t m = score.size();
  if (m < 2) return out;
  for (std::size_t k = 0; k < m; ++k) {
    bool peak = true;
    for (std::size_t j = 1; j <= order && peak; ++j)
      peak = score[k] > score[(k + j) % m] && score[k] > score[(k + m - j % m) % m];
    if (peak) out.push_back(k);
  }
  return out;
}

}  // namespace

std::vector<std::uint32_t> change_points(const double* series, std::size_t n, const ChangePointParams& p) {
  if (p.width < 2) throw InvalidArgument("the change-point window must be >= 2 epochs, got " + std::to_string(p.width));
  if (p.jump < 1) throw InvalidArgument("the change-point jump must be >= 1 epoch");
  if (!(p.penalty > 0.0)) throw InvalidArgument("the change-point penalty must be > 0");
  if (p.width >= n)
    throw InvalidArgument("the change-point window (" + std::to_string(p.width) +
                          " epochs) must be shorter than the "
                          "series (" +
                          std::to_string(n) + " epochs)");
  std::vector<double> work;
  const std::size_t half = p.width / 2;
  std::vector<double> score;
  std::vector<std::size_t> at;
  for (std::size_t i = 0; i < n; i += p.jump) {
    if (i < half || i >= n - half) continue;
    const double whole = l1_cost(series, i - half, i + half, work);
    score.push_back(whole - (l1_cost(series, i - half, i, work) + l1_cost(series, i, i + half, work)));
    at.push_back(i);
  }
  const std::size_t order =
      std::max<std::size_t>(std::max<std::size_t>(p.width, 2 * std::size_t(p.min_size)) / (2 * p.jump), 1);
  std::vector<std::size_t> peaks = local_maxima(score, order);
  // The peaks by decreasing gain (ties: the later first), each kept while it pays the penalty.
  std::stable_sort(peaks.begin(), peaks.end(), [&](std::size_t a, std::size_t b) { return score[a] < score[b]; });
  std::vector<std::size_t> breaks{n};
  double error = total_cost(series, breaks, work);
  while (!peaks.empty()) {
    const std::size_t candidate = at[peaks.back()];
    peaks.pop_back();
    std::vector<std::size_t> trial = breaks;
    trial.insert(std::upper_bound(trial.begin(), trial.end(), candidate), candidate);
    const double cost = total_cost(series, trial, work);
    if (!(error - cost > p.penalty)) break;
    breaks = std::move(trial);
    error = cost;
  }
  std::vector<std::uint32_t> out;
  for (std::size_t k = 0; k + 1 < breaks.size(); ++k) out.push_back(static_cast<std::uint32_t>(breaks[k]));
  return out;
}

}  // namespace m3c2
