#pragma once
// py4dgeo's 95th percentile of a growth's distinct DTW values (4D-OBC region growing,
// src/series/objects_by_change.cpp), kept as the values arrive.

#include <cstddef>
#include <functional>
#include <queue>
#include <unordered_set>
#include <vector>

namespace m3c2::detail {

/// The distinct DTW values of a growth so far and the largest but k of them, k = floor(0.05 n)
/// for n values: py4dgeo's 95th percentile of the distinct values. Two heaps split at that rank
/// (the k + 1 largest, the others), so that each value costs O(log n); walking an ordered set to
/// the rank cost O(n) per neighbour, quadratic in an object's size (a quarter of 4D-OBC's time
/// at 100k core points). The same values, so the same objects.
class UpperQuantile {
 public:
  explicit UpperQuantile(double first) { insert(first); }

  void insert(double v) {
    if (!distinct_.insert(v).second) return;  // 0.0 and -0.0 are one value, as in an ordered set
    if (!top_.empty() && v > top_.top()) {
      top_.push(v);
      rest_.push(top_.top());
      top_.pop();
    } else {
      rest_.push(v);
    }
    const std::size_t want = static_cast<std::size_t>(0.05 * double(distinct_.size())) + 1;
    while (top_.size() < want) top_.push(rest_.top()), rest_.pop();  // the rank only grows
  }

  /// The (k + 1)-th largest distinct value.
  double value() const { return top_.top(); }

 private:
  std::unordered_set<double> distinct_;
  std::priority_queue<double, std::vector<double>, std::greater<>> top_;  // the k + 1 largest
  std::priority_queue<double> rest_;
};

}  // namespace m3c2::detail
