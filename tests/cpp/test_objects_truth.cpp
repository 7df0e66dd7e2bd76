// 4D objects-by-change (src/series/objects_by_change.cpp) on seeded synthetic scenes with a known
// truth: core points on a grid, distances stored directly as a [core point][epoch] array, the five
// events of validation/objects_scenes.py (a deposit, an erosion strip, a bump that appears then
// reverses, a 4 cm subsidence over 12 epochs, a one-epoch -12 cm rockfall) plus 6 mm of noise,
// and a scene of noise alone. The default rule (ObjectsDtw::kBaseline) must find every event with
// an object whose extent in space and time (members x [start, end]) has IoU >= 0.5 with the
// event's (footprint x [first changed epoch - 1, last]), raw and smoothed, on two seeds, and
// nothing on the noise. The rule before it (kSeedStart) misses the rockfall's step and the raw
// subsidence: a test shows it, so that these tests can fail. A one-epoch step has a seed on every
// core point of it, from the epoch before the step. Each rule's DTW values are
// checked against a brute-force O(n^2) DTW with the rule's offsets and D_max, and each rule's seed
// score against its formula (py4dgeo's: raw slices, neighbours closer than the radius).

#include <m3c2/objects_by_change.hpp>
#include "dtw_oracle.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace m3c2::test {
namespace {

constexpr std::size_t kEpochs = 100, kSide = 32;
constexpr double kSpacing = 0.5, kNoise = 0.006;

struct Event {
  std::string name;
  int first, last;                               // the change's epochs (last: kEpochs - 1 when kept)
  std::vector<std::pair<double, double>> knots;  // (epoch, change), linear between, constant outside
  bool (*inside)(double x, double y);
  double change(double t) const {
    if (t <= knots.front().first) return knots.front().second;
    for (std::size_t k = 1; k < knots.size(); ++k)
      if (t <= knots[k].first) {
        const auto [t0, v0] = knots[k - 1];
        const auto [t1, v1] = knots[k];
        return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
      }
    return knots.back().second;
  }
};

bool disc(double x, double y, double cx, double cy, double r) {
  return (x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r;
}

const std::vector<Event>& events() {
  static const std::vector<Event> e = {
      {"deposit", 30, 99, {{29, 0.0}, {32, 0.10}}, [](double x, double y) { return disc(x, y, 4.0, 4.0, 2.0); }},
      {"erosion strip",
       40,
       99,
       {{39, 0.0}, {44, -0.08}},
       [](double x, double y) { return x >= 9.0 && x <= 15.0 && y >= 1.0 && y <= 3.0; }},
      {"bump",
       18,
       72,
       {{17, 0.0}, {18, 0.12}, {71, 0.12}, {72, 0.0}},
       [](double x, double y) { return disc(x, y, 4.0, 11.5, 2.2); }},
      {"subsidence", 45, 99, {{44, 0.0}, {56, -0.04}}, [](double x, double y) { return disc(x, y, 11.5, 8.0, 2.2); }},
      {"rockfall", 50, 99, {{49, 0.0}, {50, -0.12}}, [](double x, double y) { return disc(x, y, 11.5, 13.5, 1.8); }},
  };
  return e;
}

struct Scene {
  std::vector<double> xyz, d;  // d[c * kEpochs + t]
  std::size_t rows() const { return xyz.size() / 3; }
  PointsView core() const { return {xyz.data(), rows()}; }
};

Scene scene(std::uint64_t seed, bool with_events) {
  Scene s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, kNoise);
  for (std::size_t j = 0; j < kSide; ++j)
    for (std::size_t i = 0; i < kSide; ++i) {
      const double x = double(i) * kSpacing, y = double(j) * kSpacing;
      s.xyz.insert(s.xyz.end(), {x, y, 0.0});
      for (std::size_t t = 0; t < kEpochs; ++t) {
        double v = noise(rng);
        if (with_events)
          for (const Event& e : events())
            if (e.inside(x, y)) v += e.change(double(t));
        s.d.push_back(v);
      }
    }
  return s;
}

/// IoU of two extents in space and time: (core points, [t0, t1]) each.
double iou(const std::vector<std::uint32_t>& a, int a0, int a1, const std::vector<std::uint32_t>& b, int b0, int b1) {
  std::vector<std::uint32_t> both;
  std::set_intersection(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(both));
  const double shared = double(both.size()) * std::max(0, std::min(a1, b1) - std::max(a0, b0) + 1);
  const double total = double(a.size()) * (a1 - a0 + 1) + double(b.size()) * (b1 - b0 + 1) - shared;
  return total > 0 ? shared / total : 0.0;
}

/// Per event, the best IoU of an object.
std::vector<double> best_iou(const Scene& s, const ObjectsResult& r) {
  std::vector<double> best;
  for (const Event& e : events()) {
    std::vector<std::uint32_t> footprint;
    for (std::uint32_t c = 0; c < s.rows(); ++c)
      if (e.inside(s.xyz[3 * c], s.xyz[3 * c + 1])) footprint.push_back(c);
    double b = 0.0;
    for (const ChangeObject& o : r.objects)
      b = std::max(b, iou(footprint, e.first - 1, e.last, o.cores, int(o.seed.start), int(o.seed.end)));
    best.push_back(b);
  }
  return best;
}

ObjectsResult run(const Scene& s, bool smoothed, ObjectsDtw rule = ObjectsDtw::kBaseline) {
  ObjectsParams p;
  p.dtw = rule;
  if (!smoothed) return objects_by_change(s.d.data(), s.rows(), kEpochs, s.core(), p);
  const std::vector<double> m = temporal_median(s.d.data(), s.rows(), kEpochs, 5);
  return objects_by_change(m.data(), s.rows(), kEpochs, s.core(), p);
}

TEST(ObjectsTruth, TheDefaultFindsEveryEventAndNothingElse) {
  for (const std::uint64_t seed : {1u, 2u})
    for (const bool smoothed : {false, true}) {
      const Scene s = scene(seed, true);
      const ObjectsResult r = run(s, smoothed);
      const std::vector<double> best = best_iou(s, r);
      for (std::size_t k = 0; k < best.size(); ++k)
        EXPECT_GE(best[k], 0.5) << events()[k].name << ", seed " << seed << (smoothed ? ", smoothed" : ", raw");
      EXPECT_EQ(r.objects.size(), events().size()) << "seed " << seed << (smoothed ? ", smoothed" : ", raw");
    }
}

TEST(ObjectsTruth, NothingOnNoise) {
  for (const std::uint64_t seed : {1u, 2u})
    for (const bool smoothed : {false, true})
      for (const ObjectsDtw rule : {ObjectsDtw::kBaseline, ObjectsDtw::kSeedStart, ObjectsDtw::kPy4dgeo})
        EXPECT_EQ(run(scene(seed, false), smoothed, rule).objects.size(), 0u) << "seed " << seed;
}

TEST(ObjectsTruth, TheSeedStartRuleMissesTheStep) {
  // The reason for the baseline: measured from the seed's first epoch, which after a step is
  // already the new level, the rockfall has no seed (its volume is noise) and no object.
  for (const std::uint64_t seed : {1u, 2u}) {
    const Scene s = scene(seed, true);
    EXPECT_LT(best_iou(s, run(s, false, ObjectsDtw::kSeedStart))[4], 0.5) << "seed " << seed;
  }
}

TEST(ObjectsTruth, AOneEpochStepHasASeedFromTheEpochBeforeIt) {
  // -12 cm at epoch 50 and kept, 6 mm of noise: the change point is 50; the baseline seed starts
  // at 49 (the last epoch at the old level) and runs to the end, on every core point of the
  // rockfall and both seeds. py4dgeo's rule (the volume from x_50, already the new level) gives a
  // seed only where x_50 happens to be an extreme of the noise after it.
  for (const std::uint64_t seed : {1u, 2u}) {
    const Scene s = scene(seed, true);
    std::vector<double> rows;
    std::size_t n = 0;
    for (std::uint32_t c = 0; c < s.rows(); ++c)
      if (events()[4].inside(s.xyz[3 * c], s.xyz[3 * c + 1]))
        rows.insert(rows.end(), s.d.begin() + c * kEpochs, s.d.begin() + (c + 1) * kEpochs), ++n;
    const std::vector<Seed> seeds = find_seeds(rows.data(), n, kEpochs, ObjectsParams{});
    ASSERT_EQ(seeds.size(), n) << "seed " << seed;
    for (const Seed& x : seeds) {
      EXPECT_EQ(x.start, 49u);
      EXPECT_EQ(x.end, kEpochs - 1);
      EXPECT_EQ(x.base, 50u - 12u);  // [b - width / 2, b): the half window before the change point
    }
    ObjectsParams py4dgeo;
    py4dgeo.dtw = ObjectsDtw::kPy4dgeo;
    EXPECT_LT(find_seeds(rows.data(), n, kEpochs, py4dgeo).size(), n / 4) << "seed " << seed;
  }
}

TEST(ObjectsTruth, GapsAreReadInterpolated) {
  // 5 % of the cells NaN: every rule reads the series the seeds were found on (np.interp's
  // arithmetic), so the objects equal those of the series filled beforehand, bit for bit; the
  // default still finds every event.
  Scene gaps = scene(1, true);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double& v : gaps.d)
    if (u(rng) < 0.05) v = std::numeric_limits<double>::quiet_NaN();
  Scene filled = gaps;
  for (std::size_t c = 0; c < filled.rows(); ++c) {
    double* v = filled.d.data() + c * kEpochs;
    std::vector<std::size_t> good;
    for (std::size_t t = 0; t < kEpochs; ++t)
      if (!std::isnan(v[t])) good.push_back(t);
    for (std::size_t t = 0, g = 0; t < kEpochs; ++t) {
      if (!std::isnan(v[t])) continue;
      while (g + 1 < good.size() && good[g + 1] < t) ++g;
      if (t < good.front() || t > good.back()) {
        v[t] = v[t < good.front() ? good.front() : good.back()];
        continue;
      }
      const double slope = (v[good[g + 1]] - v[good[g]]) / (double(good[g + 1]) - double(good[g]));
      v[t] = slope * (double(t) - double(good[g])) + v[good[g]];  // np.interp's
    }
  }
  for (const ObjectsDtw rule : {ObjectsDtw::kBaseline, ObjectsDtw::kPy4dgeo}) {
    const ObjectsResult a = run(gaps, false, rule), b = run(filled, false, rule);
    ASSERT_EQ(a.objects.size(), b.objects.size());
    for (std::size_t k = 0; k < a.objects.size(); ++k) {
      EXPECT_EQ(a.objects[k].cores, b.objects[k].cores);
      EXPECT_EQ(a.objects[k].dtw, b.objects[k].dtw);
    }
  }
  for (const double best : best_iou(gaps, run(gaps, false))) EXPECT_GE(best, 0.5);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t h = v.size() / 2;
  return v.size() % 2 ? v[h] : (v[h - 1] + v[h]) / 2.0;
}

/// The rule's normalised DTW of core c to the seed, written out: the seed's epochs, each series
/// minus its offset, D_max = sum |seed - origin|, capped at 1.
double expected_dtw(const Scene& s, const Seed& seed, std::uint32_t c, ObjectsDtw rule, bool score = false) {
  const auto offset = [&](std::uint32_t r) {
    const double* row = s.d.data() + r * kEpochs;
    if (score && rule == ObjectsDtw::kPy4dgeo) return 0.0;  // py4dgeo's seed score: no offsets
    if (rule == ObjectsDtw::kPy4dgeo) return row[0];
    if (rule == ObjectsDtw::kSeedStart) return row[seed.start];
    return median(std::vector<double>(row + seed.base, row + seed.start + 1));
  };
  const double oa = offset(seed.core), ob = offset(c);
  const double origin = rule == ObjectsDtw::kPy4dgeo ? 0.0 : oa;
  std::vector<double> x, y;
  double dmax = 0.0;
  for (std::size_t t = seed.start; t <= seed.end; ++t) {
    const double a = s.d[seed.core * kEpochs + t];
    x.push_back(a - oa), y.push_back(s.d[c * kEpochs + t] - ob), dmax += std::abs(a - origin);
  }
  return std::fmin(1.0, full_dtw_cost(x, y) / dmax);
}

TEST(ObjectsTruth, EachRulesDtwIsTheBruteForceOne) {
  Scene s = scene(3, true);
  s.d = temporal_median(s.d.data(), s.rows(), kEpochs, 5);  // smoothed: seed-start finds nothing raw
  for (const ObjectsDtw rule : {ObjectsDtw::kBaseline, ObjectsDtw::kSeedStart, ObjectsDtw::kPy4dgeo}) {
    const ObjectsResult r = run(s, false, rule);
    ASSERT_FALSE(r.objects.empty());
    std::size_t checked = 0;
    for (const ChangeObject& o : r.objects) {
      if (rule != ObjectsDtw::kBaseline) {
        EXPECT_EQ(o.seed.base, o.seed.start);
      }
      for (std::size_t k = 0; k < o.cores.size(); ++k, ++checked)
        EXPECT_NEAR(o.dtw[k], expected_dtw(s, o.seed, o.cores[k], rule), 1e-12) << int(rule);
    }
    EXPECT_GT(checked, 100u);
    // The seed score: the mean over the neighbours within the radius (the seed itself among them)
    // divided by their count less one (py4dgeo's neighborhood_similarity).
    for (std::size_t k = 0; k < std::min<std::size_t>(r.seeds.size(), 20); ++k) {
      const Seed& seed = r.seeds[k];
      double sum = 0.0;
      std::size_t count = 0;
      for (std::uint32_t c = 0; c < s.rows(); ++c) {
        const double dx = s.xyz[3 * c] - s.xyz[3 * seed.core], dy = s.xyz[3 * c + 1] - s.xyz[3 * seed.core + 1];
        const double d2 = dx * dx + dy * dy;  // py4dgeo's neighbours are closer than the radius
        if (rule == ObjectsDtw::kPy4dgeo ? d2 < 1.0 : d2 <= 1.0) sum += expected_dtw(s, seed, c, rule, true), ++count;
      }
      EXPECT_NEAR(seed.score, sum / double(count - 1), 1e-12) << int(rule);
    }
  }
}

}  // namespace
}  // namespace m3c2::test
