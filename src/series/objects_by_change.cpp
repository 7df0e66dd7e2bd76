// 4D objects-by-change (Anders et al. 2021): seeds from change points (2.3.1), sorted by their
// similarity to their neighbourhood, grown by region growing on the normalised DTW with the
// adaptive threshold (2.3.2), filtered (2.3.3). The rules follow py4dgeo's RegionGrowingAlgorithm,
// the reference implementation; where this differs it says so (docs/series.md).

#include <m3c2/errors.hpp>
#include <m3c2/objects_by_change.hpp>

#include "index/kdtree.hpp"
#include "series/dtw_many.hpp"
#include "series/objects_baseline.hpp"
#include "series/upper_quantile.hpp"
#include "support/parallel_for.hpp"
#include "support/threads.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>

namespace m3c2 {
namespace {

/// The messages name ObjectsParams' fields (the engine's terms); the command line maps them to
/// its own options.
void validate(const ObjectsParams& p, std::size_t epochs) {
  if (p.min_period < 1) throw InvalidArgument("min_period must be >= 1 epoch, got 0");
  if (p.seed_subsampling < 1) throw InvalidArgument("seed_subsampling must be >= 1, got 0");
  if (!(p.neighbourhood_radius > 0.0) || !std::isfinite(p.neighbourhood_radius))
    throw InvalidArgument("neighbourhood_radius must be finite and > 0, got " + std::to_string(p.neighbourhood_radius));
  if (p.thresholds.empty()) throw InvalidArgument("thresholds must hold at least one value");
  for (const double t : p.thresholds)
    if (!(t > 0.0) || t > 1.0) throw InvalidArgument("thresholds must lie in (0, 1], got " + std::to_string(t));
  if (p.change_points.width >= epochs)
    throw InvalidArgument("the change-point window (" + std::to_string(p.change_points.width) +
                          " epochs) must be shorter than the series (" + std::to_string(epochs) + " epochs)");
}

/// np.interp of the NaN epochs from the finite ones (constant beyond the first and last), its
/// arithmetic: slope (f_r - f_l) / (r - l) times (k - l) plus f_l, the same bits as py4dgeo's.
void interpolate_gaps(std::vector<double>& ts) {
  std::vector<std::size_t> good;
  for (std::size_t k = 0; k < ts.size(); ++k)
    if (!std::isnan(ts[k])) good.push_back(k);
  if (good.size() == ts.size() || good.empty()) return;
  std::size_t g = 0;
  for (std::size_t k = 0; k < ts.size(); ++k) {
    if (!std::isnan(ts[k])) continue;
    while (g + 1 < good.size() && good[g + 1] < k) ++g;
    if (k < good.front())
      ts[k] = ts[good.front()];
    else if (k > good.back())
      ts[k] = ts[good.back()];
    else {
      const std::size_t l = good[g], r = good[g + 1];
      const double slope = (ts[r] - ts[l]) / (double(r) - double(l));
      ts[k] = slope * (double(k) - double(l)) + ts[l];
    }
  }
}

/// The seeds of one series (py4dgeo's find_seedpoints): from each change point, the volume
/// sum (x - x_start) of the change (the series flipped when it falls) grows until it decreases.
void py4dgeo_seeds(std::uint32_t core, std::vector<double> ts, const std::vector<std::uint32_t>& starts,
                   const ObjectsParams& p, std::vector<Seed>& out) {
  const std::size_t n = ts.size();
  const double lowest = *std::min_element(ts.begin(), ts.end());
  for (double& v : ts) v += std::abs(lowest + 0.1);
  const double highest = *std::max_element(ts.begin(), ts.end());
  std::vector<double> flipped(n);
  for (std::size_t k = 0; k < n; ++k) flipped[k] = -ts[k] + std::abs(highest) + 0.1;
  const std::size_t first = out.size();
  for (const std::uint32_t start : starts) {
    if (out.size() > first && start <= out.back().end) continue;
    if (start + p.min_period >= n) break;
    const std::vector<double>& used = ts[start] >= ts[start + p.min_period] ? flipped : ts;
    double previous = -999.9, volume = 0.0, hi = used[start], lo = used[start];
    const double height = used[start];
    for (std::size_t target = start + 1; target < n; ++target) {
      volume += used[target] - height;  // (used[start] - height) is 0
      hi = std::max(hi, used[target]), lo = std::min(lo, used[target]);
      if (previous > volume) {
        if (target - start >= p.min_period && std::abs(hi - lo) >= p.height_threshold)
          out.push_back({core, start, static_cast<std::uint32_t>(target), start, 0.0});
        break;
      }
      previous = volume;
      if (target == n - 1 && p.use_unfinished)  // py4dgeo 1.2.0: no height test for an unfinished seed
        out.push_back({core, start, static_cast<std::uint32_t>(n - 1), start, 0.0});
    }
  }
}

/// The seeds of one series under ObjectsDtw::kBaseline: a change point b is where the detector
/// split its window into [b - w/2, b) and [b, b + w/2), so the change happens between epochs
/// b - 1 and b. The seed starts at b - 1, its baseline is the median of [base, b - 1] with
/// base = max(b - w/2, the previous change point) (src/series/objects_baseline.hpp), its sign is
/// that of the median of [b, b + w/2) above the baseline, and its volume sum s (x - baseline) - MAD
/// (the baseline window's median absolute deviation) grows until it decreases, i.e. until the
/// series is back within the baseline's spread. py4dgeo's rule
/// measures the volume from x_b: after a step x_b is already the new level, the volume is noise
/// and stops within a few epochs (no seed); after a slow ramp x_b is one noisy epoch of it.
void baseline_seeds(std::uint32_t core, const std::vector<double>& ts, const std::vector<std::uint32_t>& cps,
                    const ObjectsParams& p, std::vector<Seed>& out) {
  const std::size_t n = ts.size(), half = p.change_points.width / 2;
  const std::size_t first = out.size();
  std::size_t previous_cp = 0;
  for (const std::uint32_t b : cps) {
    const std::size_t base = std::max(previous_cp, b >= half ? b - half : 0);
    previous_cp = b;
    if (b == 0) continue;
    const std::uint32_t start = b - 1;
    if (out.size() > first && b <= out.back().end) continue;  // inside the previous seed's change
    if (start + p.min_period >= n) break;
    const double level = detail::nan_median(ts.data(), base, start);
    const double after = detail::nan_median(ts.data(), b, std::min(n, b + std::max<std::size_t>(half, 1)) - 1);
    const double sign = after >= level ? 1.0 : -1.0;
    // The baseline's spread (median absolute deviation): the change ends when the series is back
    // within it of the level.
    std::vector<double> deviation;
    for (std::size_t k = base; k <= start; ++k) deviation.push_back(std::abs(ts[k] - level));
    const double spread = detail::nan_median(deviation.data(), 0, deviation.size() - 1);
    // A later change point where the series is back by more than half the change ends it too: the
    // detector saw the reversal there, and a level a millimetre off the baseline (an offset of the
    // smoothed series after a pile's removal) would keep the volume growing epochs past it.
    const auto later = std::upper_bound(cps.begin(), cps.end(), b);
    const std::size_t reversal = later == cps.end() ? n : *later;
    double previous = -999.9, volume = sign * (ts[start] - level) - spread, peak = std::abs(ts[start] - level);
    for (std::size_t target = b; target < n; ++target) {
      const double change = sign * (ts[target] - level);
      volume += change - spread;
      const bool reversed = target >= reversal && change < peak / 2;
      peak = std::max(peak, change);
      if (previous > volume || reversed) {
        if (target - start >= p.min_period && peak >= p.height_threshold)
          out.push_back({core, start, static_cast<std::uint32_t>(target), static_cast<std::uint32_t>(base), 0.0});
        break;
      }
      previous = volume;
      // A change still going on at the last epoch: a seed too when asked, under the same least
      // height (its period is at least min_period: start + min_period < n above). py4dgeo's rule
      // (py4dgeo_seeds) keeps such a seed whatever its height, as py4dgeo 1.2.0 does.
      if (target == n - 1 && p.use_unfinished && peak >= p.height_threshold)
        out.push_back({core, start, static_cast<std::uint32_t>(n - 1), static_cast<std::uint32_t>(base), 0.0});
    }
  }
}

void seeds_of(std::uint32_t core, std::vector<double> ts, const ObjectsParams& p, std::vector<Seed>& out) {
  const std::size_t n = ts.size();
  std::size_t nans = 0;
  for (const double v : ts) nans += std::isnan(v);
  if (nans + 3 > n) return;  // fewer than 3 finite epochs
  interpolate_gaps(ts);
  const std::vector<std::uint32_t> cps = change_points(ts.data(), n, p.change_points);
  if (p.dtw == ObjectsDtw::kBaseline)
    baseline_seeds(core, ts, cps, p, out);
  else
    py4dgeo_seeds(core, std::move(ts), cps, p, out);
}

/// How one seed's DTW reads a series (ObjectsDtw): the epochs compared are the seed's
/// [start, end] under every rule; each series' offset and D_max's origin differ.
struct Alignment {
  const Seed& seed;
  ObjectsDtw rule;
  std::size_t begin() const { return seed.start; }
  std::size_t length() const { return std::size_t(seed.end) - seed.start + 1; }
  double norm(const double* row) const {
    switch (rule) {
      case ObjectsDtw::kPy4dgeo: return row[0];  // py4dgeo: data.distances(n, 0)
      case ObjectsDtw::kSeedStart: return row[seed.start];
      case ObjectsDtw::kBaseline: break;
    }
    return detail::nan_median(row, seed.base, seed.start);
  }
  /// D_max = sum |a - origin| over the seed's epochs; py4dgeo sums the raw slice.
  double dmax_origin(double norm_a) const { return rule == ObjectsDtw::kPy4dgeo ? 0.0 : norm_a; }
};

struct Grown {
  std::vector<std::pair<std::uint32_t, double>> members;  // (core, DTW to the seed), ascending by core
  double threshold = 0.0;
};

/// The core points within the neighbourhood radius of each core point, ascending. Kept for the
/// whole run when the table fits in ObjectsParams::neighbour_table_bytes (region growing searched
/// the ball of each candidate at each threshold of each seed again: 12 % of 4D-OBC's time); the
/// table grows with the radius squared (4 bytes per pair), so beyond the limit each ball is
/// searched when it is needed, into the thread's buffer. Either way the same lists: the same objects.
class Neighbours {
 public:
  struct List {
    const std::uint32_t *first, *last;
    const std::uint32_t* begin() const { return first; }
    const std::uint32_t* end() const { return last; }
    std::size_t size() const { return std::size_t(last - first); }
  };

  /// strict: only the points closer than the radius (py4dgeo's nanoflann result set keeps
  /// squared distance < radius^2; ours keeps <=, which on a grid whose spacing divides the radius
  /// adds the four points at exactly the radius).
  Neighbours(const detail::KdTree& tree, double radius, bool strict, std::uint64_t table_bytes, const RunOptions& run)
      : tree_(tree), radius_(radius), strict_(strict) {
    if (table_bytes == 0) return;
    const std::size_t n = tree.points().size(), chunks = (n + kChunk - 1) / kChunk;
    chunks_.resize(chunks);
    std::atomic<std::uint64_t> pairs{0};
    std::atomic<bool> over{false};
    const std::uint64_t limit = table_bytes / sizeof(std::uint32_t);
    detail::parallel_blocks<int>(
        chunks, run,
        [&](std::size_t begin, std::size_t end, int&) {
          for (std::size_t k = begin; k < end && !over.load(std::memory_order_relaxed); ++k) {
            Chunk& chunk = chunks_[k];
            chunk.offsets.push_back(0);
            for (std::size_t c = k * kChunk; c < std::min(n, (k + 1) * kChunk); ++c) {
              const std::size_t before = chunk.cores.size();
              search(std::uint32_t(c), chunk.cores);
              std::sort(chunk.cores.begin() + std::ptrdiff_t(before), chunk.cores.end());
              chunk.offsets.push_back(chunk.cores.size());
              const std::uint64_t added = chunk.cores.size() - before;
              if (pairs.fetch_add(added, std::memory_order_relaxed) + added > limit) {
                over = true;
                break;
              }
            }
          }
        },
        1);
    if (over) std::vector<Chunk>().swap(chunks_);
  }

  /// The neighbours of core point c; `buffer` (the thread's) holds them when there is no table.
  List of(std::uint32_t c, std::vector<std::uint32_t>& buffer) const {
    if (chunks_.empty()) {
      buffer.clear();
      search(c, buffer);
      std::sort(buffer.begin(), buffer.end());
      return {buffer.data(), buffer.data() + buffer.size()};
    }
    const Chunk& chunk = chunks_[c / kChunk];
    const std::size_t i = c % kChunk;
    return {chunk.cores.data() + chunk.offsets[i], chunk.cores.data() + chunk.offsets[i + 1]};
  }

  std::size_t rows() const { return tree_.points().size(); }

 private:
  /// Appends the neighbours of core point c (tree order).
  void search(std::uint32_t c, std::vector<std::uint32_t>& out) const {
    const std::size_t before = out.size();
    const Vec3 centre = tree_.points()[c];
    tree_.ball(centre, radius_, out);
    if (!strict_) return;
    const double r2 = radius_ * radius_;
    const auto on_the_sphere = [&](std::uint32_t k) { return (tree_.points()[k] - centre).squaredNorm() >= r2; };
    out.erase(std::remove_if(out.begin() + std::ptrdiff_t(before), out.end(), on_the_sphere), out.end());
  }

  // Chunks of core points, each filled by one thread: no copy of the table into one array.
  static constexpr std::size_t kChunk = 4096;
  struct Chunk {
    std::vector<std::uint64_t> offsets;  // kChunk + 1 (fewer in the last chunk)
    std::vector<std::uint32_t> cores;
  };
  const detail::KdTree& tree_;
  double radius_;
  bool strict_;
  std::vector<Chunk> chunks_;  // empty: each ball is searched when needed
};

/// Per-thread marks of the core points a growth has seen (a member or rejected): mark[c] ==
/// generation, a new generation per growth instead of a hash set per growth.
struct Seen {
  std::vector<std::uint32_t> mark;
  std::uint32_t generation = 0;
  void start(std::size_t rows) {
    if (mark.size() != rows || ++generation == 0) mark.assign(rows, 0), generation = 1;
  }
  bool test_and_set(std::uint32_t c) {
    const bool seen = mark[c] == generation;
    mark[c] = generation;
    return seen;
  }
  bool test(std::uint32_t c) const { return mark[c] == generation; }
  std::vector<std::uint32_t> ball;  // Neighbours::of's buffer
};

/// Region growing at one threshold (py4dgeo's fixed_threshold_region_growing): candidates in
/// ascending DTW; a neighbour under the threshold joins, and grows the object further only if
/// its DTW is under the 95th percentile of the distinct DTW values so far (once the object has
/// min_segments members). `dtw(core)` is the memoised DTW to the seed; `prepare(list, seen)` may
/// compute those a candidate's neighbours will ask for, all at once.
template <class Dtw, class Prepare>
Grown grow(const Seed& seed, double threshold, const Neighbours& adjacent, const ObjectsParams& p, Dtw&& dtw,
           Prepare&& prepare, Seen& seen) {
  Grown g;
  g.threshold = threshold;
  seen.start(adjacent.rows());
  std::multimap<double, std::uint32_t> candidates{{0.0, seed.core}};
  detail::UpperQuantile used(0.0);
  g.members.emplace_back(seed.core, 0.0);
  seen.test_and_set(seed.core);
  double residual = threshold;
  while (!candidates.empty()) {
    const std::uint32_t candidate = candidates.begin()->second;
    candidates.erase(candidates.begin());
    const Neighbours::List around = adjacent.of(candidate, seen.ball);
    prepare(around, seen);
    for (const std::uint32_t nb : around) {
      if (seen.test_and_set(nb)) continue;
      const double d = dtw(nb);
      if (d < threshold) {
        g.members.emplace_back(nb, d);
        used.insert(d);
      }
      if (d < residual) candidates.insert({d, nb});
      if (g.members.size() >= p.min_segments) residual = used.value();
    }
  }
  std::sort(g.members.begin(), g.members.end());
  return g;
}

}  // namespace

std::vector<Seed> find_seeds(const double* distances, std::size_t rows, std::size_t epochs, const ObjectsParams& p,
                             const RunOptions& run) {
  validate(p, epochs);
  const std::size_t candidates = (rows + p.seed_subsampling - 1) / p.seed_subsampling;
  std::vector<std::vector<Seed>> per_core(candidates);
  detail::parallel_blocks<int>(candidates, run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t k = begin; k < end; ++k) {
      const std::size_t r = k * p.seed_subsampling;
      const double* row = distances + r * epochs;
      seeds_of(static_cast<std::uint32_t>(r), std::vector<double>(row, row + epochs), p, per_core[k]);
    }
  });
  std::vector<Seed> out;
  for (auto& s : per_core) out.insert(out.end(), s.begin(), s.end());
  return out;
}

ObjectsResult objects_by_change(const double* distances, std::size_t rows, std::size_t epochs, PointsView core,
                                const ObjectsParams& p, const RunOptions& run) {
  if (core.size() != rows)
    throw InvalidArgument("the distances have " + std::to_string(rows) + " core points, the coordinates " +
                          std::to_string(core.size()));
  ObjectsResult result;
  result.seeds = find_seeds(distances, rows, epochs, p, run);
  // The seed scores and region growing read the series the seeds were found on, NaN epochs
  // interpolated: the rows with a gap are copied and interpolated beside the caller's array (never
  // written), 8 bytes an epoch for each such row. py4dgeo's find_seedpoints interpolates each
  // series it searches in place, in the analysis' cached distance array, so its scores and growth
  // read them too; under kPy4dgeo only those rows (every seed_subsampling-th), as in py4dgeo.
  // With the raw gaps the baseline rule's DTW values were noisier: on validation/objects_truth.py's
  // scenes with 5 % of the cells NaN, a partial subsidence at the first threshold and a false
  // object, which the interpolated series do not give.
  constexpr std::size_t kCallers = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> slot(rows, kCallers);  // row r's place in `filled`, or the caller's row
  std::vector<double> filled;
  {
    std::vector<double> ts;
    const std::size_t step = p.dtw == ObjectsDtw::kPy4dgeo ? p.seed_subsampling : 1;
    for (std::size_t r = 0; r < rows; r += step) {
      const double* v = distances + r * epochs;
      const std::size_t nans = std::size_t(std::count_if(v, v + epochs, [](double x) { return std::isnan(x); }));
      if (nans == 0 || nans + 3 > epochs) continue;  // nothing to fill; skipped by the seed search
      ts.assign(v, v + epochs);
      interpolate_gaps(ts);
      slot[r] = filled.size() / epochs;
      filled.insert(filled.end(), ts.begin(), ts.end());
    }
  }
  const detail::KdTree tree(core);
  const auto row = [&](std::size_t r) {
    return slot[r] == kCallers ? distances + r * epochs : filled.data() + slot[r] * epochs;
  };

  // Seed score: the mean normalised DTW to its neighbours over the seed's epochs (py4dgeo's
  // neighborhood_similarity: the raw slices, no offsets, in py4dgeo's mode; the growth's
  // alignment otherwise).
  auto& seeds = result.seeds;
  RunOptions quiet = run;
  quiet.progress = nullptr;
  const Neighbours adjacent(tree, p.neighbourhood_radius, p.dtw == ObjectsDtw::kPy4dgeo, p.neighbour_table_bytes,
                            quiet);
  using Buffer = std::vector<std::uint32_t>;
  detail::parallel_blocks<Buffer>(seeds.size(), run, [&](std::size_t begin, std::size_t end, Buffer& buffer) {
    for (std::size_t k = begin; k < end; ++k) {
      Seed& s = seeds[k];
      const Neighbours::List around = adjacent.of(s.core, buffer);
      if (around.size() < 2) {
        s.score = 9999999.0;
        continue;
      }
      const Alignment align{s, p.dtw};
      const bool raw = p.dtw == ObjectsDtw::kPy4dgeo;
      const double* a = row(s.core) + align.begin();
      const double norm_a = raw ? 0.0 : align.norm(row(s.core)), origin = raw ? 0.0 : align.dmax_origin(norm_a);
      double sum = 0.0;
      for (const std::uint32_t nb : around)
        sum +=
            normalised_dtw(a, row(nb) + align.begin(), align.length(), norm_a, raw ? 0.0 : align.norm(row(nb)), origin);
      s.score = sum / double(around.size() - 1);
    }
  });
  std::stable_sort(seeds.begin(), seeds.end(), [](const Seed& a, const Seed& b) { return a.score < b.score; });

  std::vector<double> thresholds = p.thresholds;
  std::sort(thresholds.begin(), thresholds.end());
  const std::uint64_t max_segments = p.max_segments > 0 ? p.max_segments : rows + 1;
  // A seed's growth depends on the seed alone; only whether it is skipped depends on the objects
  // before it. So the seeds are grown in parallel, a batch at a time, and then taken in order:
  // a seed inside an object accepted before it (in this batch too) is dropped, as in a serial run.
  // Under the baseline rule nearly every core point of a change has a seed, and one at the edge of
  // an earlier object (its core point not taken by that growth, often a core point M3C2 saw only
  // part of the change at) grows a ring around it at a large threshold or the same change again:
  // such a seed, adjacent to an earlier object's core point over shared epochs, is skipped too.
  std::vector<std::uint32_t> around_seed;
  const auto inside = [&](const Seed& seed) {
    const bool edges = p.dtw == ObjectsDtw::kBaseline;
    for (const ChangeObject& o : result.objects) {
      if (!(o.seed.end > seed.start && seed.end > o.seed.start)) continue;
      if (std::binary_search(o.cores.begin(), o.cores.end(), seed.core)) return true;
      if (edges)
        for (const std::uint32_t c : adjacent.of(seed.core, around_seed))
          if (std::binary_search(o.cores.begin(), o.cores.end(), c)) return true;
    }
    return false;
  };
  const auto grow_seed = [&](const Seed& seed, Seen& seen) -> std::optional<ChangeObject> {
    const Alignment span{seed, p.dtw};
    const double* a = row(seed.core) + span.begin();
    const double norm_a = span.norm(row(seed.core)), origin = span.dmax_origin(norm_a);
    std::unordered_map<std::uint32_t, double> memo;
    const auto dtw = [&](std::uint32_t nb) {
      const auto it = memo.find(nb);
      if (it != memo.end()) return it->second;
      // Values >= the largest threshold only ever fail the comparisons: stop early there.
      const double d = normalised_dtw(a, row(nb) + span.begin(), span.length(), norm_a, span.norm(row(nb)), origin,
                                      thresholds.back());
      memo.emplace(nb, d);
      return d;
    };
    // The DTWs a candidate's unseen neighbours will ask for, computed together (dtw_many.hpp:
    // the same values, 61 % of 4D-OBC's time at 100k points before), where no series has a NaN.
    const auto finite = [&](const double* v) {
      return std::none_of(v, v + span.length(), [](double x) { return std::isnan(x); });
    };
    const bool lanes = finite(a) && !std::isnan(norm_a);
    std::vector<std::uint32_t> pending;
    std::vector<const double*> series;
    std::vector<double> norms, values;
    const auto prepare = [&](const Neighbours::List& around, const Seen& seen) {
      if (!lanes) return;
      pending.clear(), series.clear(), norms.clear();
      for (const std::uint32_t nb : around) {
        if (seen.test(nb) || memo.count(nb) || !finite(row(nb) + span.begin())) continue;
        const double norm = span.norm(row(nb));
        if (std::isnan(norm)) continue;  // asked alone (a baseline of NaN epochs only)
        pending.push_back(nb), series.push_back(row(nb) + span.begin()), norms.push_back(norm);
      }
      if (pending.size() < detail::kDtwLanes) return;  // asked one at a time
      values.resize(pending.size());
      detail::normalised_dtw_many(a, series.data(), norms.data(), pending.size(), span.length(), norm_a, origin,
                                  thresholds.back(), values.data());
      for (std::size_t k = 0; k < pending.size(); ++k) memo.emplace(pending[k], values[k]);
    };
    // Adaptive threshold: the first threshold whose object is at most half the next one's
    // (by a ratio no larger than the previous one), or the first reaching max_segments. Each
    // threshold is grown only when this rule needs it: the rule never looks past the next one,
    // and the growths at the large thresholds, which reach the most neighbours, are the most
    // expensive (most seeds stop at one of the first few).
    std::vector<Grown> grown;
    grown.reserve(thresholds.size());  // `chosen` points into it
    const auto grown_at = [&](std::size_t i) -> const Grown& {
      while (grown.size() <= i) grown.push_back(grow(seed, thresholds[grown.size()], adjacent, p, dtw, prepare, seen));
      return grown[i];
    };
    // Under the baseline rule the search starts at the first threshold whose object has
    // min_segments core points: a smaller one is not an object (2.3.3), so its doubling at the next
    // threshold is the object forming, not leaking into its surroundings. py4dgeo's rule stops at
    // that first doubling and drops the object: on raw series a 4 cm change under 6 mm of noise
    // has half its core points under the 0.1 threshold and none of it survives
    // (validation/objects_truth.py).
    std::size_t first = 0;
    if (p.dtw == ObjectsDtw::kBaseline)
      while (first + 1 < thresholds.size() && grown_at(first).members.size() < p.min_segments) ++first;
    const Grown* chosen = nullptr;
    bool by_ratio = false;
    double last_ratio = 0.5;
    for (std::size_t i = first; i + 1 < thresholds.size(); ++i) {
      if (grown_at(i).members.size() >= max_segments) {
        chosen = &grown_at(i);
        break;
      }
      const double ratio = double(grown_at(i).members.size()) / double(grown_at(i + 1).members.size());
      if (ratio <= last_ratio) {
        chosen = &grown_at(i), by_ratio = true;
        break;
      }
      last_ratio = ratio;
    }
    if (!chosen) chosen = &grown_at(thresholds.size() - 1);
    // Filters (2.3.3): the object's size (py4dgeo's region_growing checks it only for an object
    // chosen by the ratio), and the coefficient of variation of its DTW values.
    if (chosen->members.size() < p.min_segments && (by_ratio || p.dtw != ObjectsDtw::kPy4dgeo)) return std::nullopt;
    double mean = 0.0;
    for (const auto& [c, d] : chosen->members) mean += d;
    mean /= double(chosen->members.size());
    double var = 0.0;
    for (const auto& [c, d] : chosen->members) var += (d - mean) * (d - mean);
    const double sd = std::sqrt(var / double(chosen->members.size()));
    if (!(sd / (mean == 0.0 ? 1e-10 : mean) <= p.max_cv)) return std::nullopt;
    ChangeObject o;
    o.seed = seed;
    o.threshold = chosen->threshold;
    for (const auto& [c, d] : chosen->members) o.cores.push_back(c), o.dtw.push_back(d);
    return o;
  };
  const std::size_t batch = std::size_t(4) * std::max(1, run.threads > 0 ? run.threads : detail::max_threads());
  for (std::size_t first = 0; first < seeds.size(); first += batch) {
    if (run.progress && !run.progress(first, seeds.size())) throw Cancelled();
    const std::size_t last = std::min(seeds.size(), first + batch);
    std::vector<std::optional<ChangeObject>> grown(last - first);
    std::vector<char> skipped(last - first);
    for (std::size_t k = first; k < last; ++k) skipped[k - first] = inside(seeds[k]);
    detail::parallel_blocks<Seen>(
        last - first, quiet,
        [&](std::size_t begin, std::size_t end, Seen& seen) {
          for (std::size_t k = begin; k < end; ++k)
            if (!skipped[k]) grown[k] = grow_seed(seeds[first + k], seen);
        },
        1);
    for (std::size_t k = first; k < last; ++k)
      if (!skipped[k - first] && grown[k - first] && !inside(seeds[k]))
        result.objects.push_back(std::move(*grown[k - first]));
  }
  return result;
}

}  // namespace m3c2
