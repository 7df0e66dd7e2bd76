// Which reference point each core point is, by identical coordinates: how the command line
// carries the core points' own attributes into its output (m3c2kit.io.fields.core_attributes).
// A hash table of the distinct query rows, then one pass over the points in input order, so that
// each distinct row keeps the first point equal to it. It replaced a numpy hash-and-argsort of
// every point (0.23 s of a 2-second whole process on 1M points, issue 19); this takes one probe
// per point and stops as soon as every query is found.

#include <m3c2/m3c2.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <numeric>

namespace m3c2 {
namespace {

using RowBits = std::array<std::uint64_t, 3>;
constexpr std::uint64_t kNone = ~std::uint64_t(0);

/// The bits of row p with -0.0 made +0.0, so that rows equal as numbers have equal bits; false
/// for a row holding a NaN, which equals no row.
bool row_bits(const double* p, RowBits& out) {
  for (int a = 0; a < 3; ++a) {
    if (std::isnan(p[a])) return false;
    out[a] = std::bit_cast<std::uint64_t>(p[a] + 0.0);
  }
  return true;
}

/// A 64-bit finaliser (MurmurHash3's fmix64): every input bit reaches every output bit.
std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ULL;
  h ^= h >> 33;
  return h;
}

std::uint64_t row_hash(const RowBits& r) { return mix(r[0] ^ mix(r[1] ^ mix(r[2]))); }

/// The distinct rows of the queries in an open-addressing table (linear probing, at most half
/// full, so a probe for a row that is not there ends after about two slots).
class DistinctRows {
 public:
  explicit DistinctRows(std::size_t rows) : slots_(std::bit_ceil(std::max<std::size_t>(16, 2 * rows)), kNone) {
    rows_.reserve(rows);
  }

  /// The id of `r` among the rows added so far, added if new.
  std::uint64_t add(const RowBits& r) {
    std::uint64_t& slot = slots_[find_slot(r)];
    if (slot == kNone) {
      slot = rows_.size();
      rows_.push_back(r);
    }
    return slot;
  }
  /// The id of `r`, or kNone when it is not among the rows.
  std::uint64_t find(const RowBits& r) const { return slots_[find_slot(r)]; }
  std::size_t size() const { return rows_.size(); }

 private:
  /// The slot holding `r`, or the empty slot where it would go.
  std::size_t find_slot(const RowBits& r) const {
    const std::size_t mask = slots_.size() - 1;
    std::size_t s = row_hash(r) & mask;
    while (slots_[s] != kNone && rows_[slots_[s]] != r) s = (s + 1) & mask;
    return s;
  }

  std::vector<std::uint64_t> slots_;  // id of the row in each slot, kNone where empty
  std::vector<RowBits> rows_;
};

}  // namespace

std::optional<std::vector<std::uint64_t>> match_rows(PointsView points, PointsView queries) {
  const std::size_t m = queries.size();
  std::vector<std::uint64_t> out(m);
  // The core points are often the reference itself: each is its own row, duplicates included.
  if (points.size() == m && std::equal(points.data(), points.data() + 3 * m, queries.data())) {
    std::iota(out.begin(), out.end(), std::uint64_t(0));
    return out;
  }
  DistinctRows distinct(m);
  RowBits r;
  for (std::size_t k = 0; k < m; ++k) {
    if (!row_bits(queries.data() + 3 * k, r)) return std::nullopt;
    out[k] = distinct.add(r);
  }
  std::vector<std::uint64_t> first(distinct.size(), kNone);
  std::size_t unmatched = distinct.size();
  for (std::size_t i = 0; i < points.size() && unmatched > 0; ++i) {
    if (!row_bits(points.data() + 3 * i, r)) continue;
    const std::uint64_t id = distinct.find(r);
    if (id != kNone && first[id] == kNone) first[id] = i, --unmatched;
  }
  if (unmatched > 0) return std::nullopt;
  for (auto& id : out) id = first[id];
  return out;
}

}  // namespace m3c2
