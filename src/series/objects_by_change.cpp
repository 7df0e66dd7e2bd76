// 4D objects-by-change (Anders et al. 2021): seeds from change points (2.3.1), sorted by their
// similarity to their neighbourhood, grown by region growing on the normalised DTW with the
// adaptive threshold (2.3.2), filtered (2.3.3). The rules follow py4dgeo's RegionGrowingAlgorithm,
// the reference implementation; where this differs it says so (docs/series.md).

#include <m3c2/errors.hpp>
#include <m3c2/objects_by_change.hpp>

#include "index/kdtree.hpp"
#include "series/dtw_many.hpp"
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

/// np.interp of the NaN epochs from the finite ones (constant beyond the first and last).
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
      ts[k] = ts[l] + (ts[r] - ts[l]) * (double(k - l) / double(r - l));
    }
  }
}

/// The seeds of one series (py4dgeo's find_seedpoints): from each change point, the volume
/// sum (x - x_start) of the change (the series flipped when it falls) grows until it decreases.
void seeds_of(std::uint32_t core, std::vector<double> ts, const ObjectsParams& p, std::vector<Seed>& out) {
  const std::size_t n = ts.size();
  std::size_t nans = 0;
  for (const double v : ts) nans += std::isnan(v);
  if (nans + 3 > n) return;  // fewer than 3 finite epochs
  interpolate_gaps(ts);
  const std::vector<std::uint32_t> starts = change_points(ts.data(), n, p.change_points);
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
          out.push_back({core, start, static_cast<std::uint32_t>(target), 0.0});
        break;
      }
      previous = volume;
      if (target == n - 1 && p.use_unfinished) out.push_back({core, start, static_cast<std::uint32_t>(n - 1), 0.0});
    }
  }
}

/// The series of 4D-OBC's DTW for one seed: the epochs compared and each series' origin.
struct Span {
  std::size_t begin, length;
  bool whole;
  double norm(const double* row) const { return whole ? row[0] : row[begin]; }
  double dmax_origin(const double* row) const { return whole ? 0.0 : row[begin]; }
};

Span span_of(const Seed& s, std::size_t epochs, const ObjectsParams& p) {
  if (p.whole_series) return {0, epochs, true};
  return {s.start, std::size_t(s.end) - s.start + 1, false};
}

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

  Neighbours(const detail::KdTree& tree, double radius, std::uint64_t table_bytes, const RunOptions& run)
      : tree_(tree), radius_(radius) {
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
              tree_.ball(tree_.points()[c], radius_, chunk.cores);
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
      tree_.ball(tree_.points()[c], radius_, buffer);
      std::sort(buffer.begin(), buffer.end());
      return {buffer.data(), buffer.data() + buffer.size()};
    }
    const Chunk& chunk = chunks_[c / kChunk];
    const std::size_t i = c % kChunk;
    return {chunk.cores.data() + chunk.offsets[i], chunk.cores.data() + chunk.offsets[i + 1]};
  }

  std::size_t rows() const { return tree_.points().size(); }

 private:
  // Chunks of core points, each filled by one thread: no copy of the table into one array.
  static constexpr std::size_t kChunk = 4096;
  struct Chunk {
    std::vector<std::uint64_t> offsets;  // kChunk + 1 (fewer in the last chunk)
    std::vector<std::uint32_t> cores;
  };
  const detail::KdTree& tree_;
  double radius_;
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
  const detail::KdTree tree(core);
  const auto row = [&](std::size_t r) { return distances + r * epochs; };

  // Seed score: the mean normalised DTW to its neighbours over the seed's epochs (py4dgeo's
  // neighborhood_similarity; raw series in py4dgeo's mode, series from the start otherwise).
  auto& seeds = result.seeds;
  RunOptions quiet = run;
  quiet.progress = nullptr;
  const Neighbours adjacent(tree, p.neighbourhood_radius, p.neighbour_table_bytes, quiet);
  using Buffer = std::vector<std::uint32_t>;
  detail::parallel_blocks<Buffer>(seeds.size(), run, [&](std::size_t begin, std::size_t end, Buffer& buffer) {
    for (std::size_t k = begin; k < end; ++k) {
      Seed& s = seeds[k];
      const Neighbours::List around = adjacent.of(s.core, buffer);
      if (around.size() < 2) {
        s.score = 9999999.0;
        continue;
      }
      const std::size_t len = std::size_t(s.end) - s.start + 1;
      const double* a = row(s.core) + s.start;
      const double origin = p.whole_series ? 0.0 : a[0];
      double sum = 0.0;
      for (const std::uint32_t nb : around) {
        const double* b = row(nb) + s.start;
        sum += normalised_dtw(a, b, len, origin, p.whole_series ? 0.0 : b[0], origin);
      }
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
  const auto inside = [&](const Seed& seed) {
    for (const ChangeObject& o : result.objects)
      if (o.seed.end > seed.start && seed.end > o.seed.start &&
          std::binary_search(o.cores.begin(), o.cores.end(), seed.core))
        return true;
    return false;
  };
  const auto grow_seed = [&](const Seed& seed, Seen& seen) -> std::optional<ChangeObject> {
    const Span span = span_of(seed, epochs, p);
    const double* a = row(seed.core) + span.begin;
    const double norm_a = span.norm(row(seed.core)), origin = span.dmax_origin(row(seed.core));
    std::unordered_map<std::uint32_t, double> memo;
    const auto dtw = [&](std::uint32_t nb) {
      const auto it = memo.find(nb);
      if (it != memo.end()) return it->second;
      // Values >= the largest threshold only ever fail the comparisons: stop early there.
      const double d =
          normalised_dtw(a, row(nb) + span.begin, span.length, norm_a, span.norm(row(nb)), origin, thresholds.back());
      memo.emplace(nb, d);
      return d;
    };
    // The DTWs a candidate's unseen neighbours will ask for, computed together (dtw_many.hpp:
    // the same values, 61 % of 4D-OBC's time at 100k points before), where no series has a NaN.
    const auto finite = [&](const double* v) {
      return std::none_of(v, v + span.length, [](double x) { return std::isnan(x); });
    };
    const bool lanes = finite(a);
    std::vector<std::uint32_t> pending;
    std::vector<const double*> series;
    std::vector<double> norms, values;
    const auto prepare = [&](const Neighbours::List& around, const Seen& seen) {
      if (!lanes) return;
      pending.clear(), series.clear(), norms.clear();
      for (const std::uint32_t nb : around) {
        if (seen.test(nb) || memo.count(nb) || !finite(row(nb) + span.begin)) continue;
        pending.push_back(nb), series.push_back(row(nb) + span.begin), norms.push_back(span.norm(row(nb)));
      }
      if (pending.size() < detail::kDtwLanes) return;  // asked one at a time
      values.resize(pending.size());
      detail::normalised_dtw_many(a, series.data(), norms.data(), pending.size(), span.length, norm_a, origin,
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
    const Grown* chosen = nullptr;
    double last_ratio = 0.5;
    for (std::size_t i = 0; i + 1 < thresholds.size(); ++i) {
      if (grown_at(i).members.size() >= max_segments) {
        chosen = &grown_at(i);
        break;
      }
      const double ratio = double(grown_at(i).members.size()) / double(grown_at(i + 1).members.size());
      if (ratio <= last_ratio) {
        chosen = &grown_at(i);
        break;
      }
      last_ratio = ratio;
    }
    if (!chosen) chosen = &grown_at(thresholds.size() - 1);
    // Filters (2.3.3): the object's size, and the coefficient of variation of its DTW values.
    if (chosen->members.size() < p.min_segments) return std::nullopt;
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
