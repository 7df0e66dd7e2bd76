#pragma once
// The shell of a neighbour in the multi-scale sums of dimensionality.cpp: which of the nested
// balls (radii ascending) first holds a point at squared distance d2, for every neighbour of
// every core point, so at the cost of a table lookup and one comparison.

#include "support/assert.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace m3c2::detail {

/// The shell of a squared distance d2 <= r2.back(): the number of inner radii r2[0..S-2] it
/// exceeds, from a table over d2 in equal bins and one comparison (a count over the radii was a
/// third of the shell pass). bin(d2) = floor(d2 * scale) is monotone in d2, so a radius whose bin
/// is below d2's is exceeded and one whose bin is above is not; only the radii of d2's own bin
/// need their comparison, and the bins are made fine enough that each holds at most one radius.
class ShellIndex {
 public:
  /// r2: the radii squared, ascending and distinct, at most 65535 of them.
  explicit ShellIndex(const std::vector<double>& r2) : inner_(r2.begin(), r2.end() - 1) {
    inner_.push_back(INFINITY);  // compared where a bin holds no inner radius: never exceeded
    for (std::size_t bins = 64;; bins *= 2) {
      scale_ = double(bins) / r2.back();
      if (!std::isfinite(scale_)) scale_ = 0.0;  // radii below ~1e-154: one bin, radius by radius
      bool distinct = true;
      for (std::size_t q = 1; q + 1 < inner_.size(); ++q) distinct = distinct && bin(inner_[q]) != bin(inner_[q - 1]);
      if (distinct || bins >= kMaxBins) break;
    }
    first_.assign(bin(r2.back()) + 1, 0);
    for (std::size_t b = 1, q = 0; b < first_.size(); ++b) {
      while (q + 1 < inner_.size() && bin(inner_[q]) < b) ++q;
      first_[b] = static_cast<std::uint16_t>(q);
    }
    // Bins holding several radii (scales closer than r2.back() / kMaxBins apart): counted radius
    // by radius there.
    for (std::size_t q = 1; q + 1 < inner_.size(); ++q) crowded_ = crowded_ || bin(inner_[q]) == bin(inner_[q - 1]);
  }
  /// The shell of 0 <= d2 <= r2.back(): 0 within the smallest radius, ..., S - 1 in the largest.
  std::size_t operator()(double d2) const {
    const std::size_t b = bin(d2);
    M3C2_ASSERT(b < first_.size(), "a shell's squared distance within the largest radius");
    std::size_t r = first_[b];
    if (crowded_) {
      while (d2 > inner_[r]) ++r;
      return r;
    }
    return r + (d2 > inner_[r]);
  }

 private:
  static constexpr std::size_t kMaxBins = 1 << 16;
  std::size_t bin(double d2) const { return static_cast<std::size_t>(d2 * scale_); }
  std::vector<double> inner_;         // the inner radii squared, then +inf
  std::vector<std::uint16_t> first_;  // per bin: the inner radii whose bin is below it
  double scale_ = 0.0;
  bool crowded_ = false;
};

}  // namespace m3c2::detail
