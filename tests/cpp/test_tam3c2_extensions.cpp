// TAM3C2's two extensions of ours (include/m3c2/tam3c2.hpp, Tam3c2Fallback and Tam3c2Breaks;
// docs/series.md, "TAM3C2"), on scenes whose answer is known by hand: a short cell takes the
// epoch's own M3C2 (and only a short one), and a window stops at a step of the per-epoch series
// instead of averaging across it. tests/python/series/test_tam3c2.py checks both against a
// brute-force numpy TAM3C2.
#include <m3c2/errors.hpp>
#include <m3c2/tam3c2.hpp>

#include "series/tam3c2_breaks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A square grid of side `n` points, spacing `step`, centred on the origin, at height z.
std::vector<double> grid(int n, double step, double z) {
  std::vector<double> xyz;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) xyz.insert(xyz.end(), {step * (i - (n - 1) / 2.0), step * (j - (n - 1) / 2.0), z});
  return xyz;
}

m3c2::Tam3c2Params params() {
  m3c2::Tam3c2Params p;
  p.normal_radii = {0.5};
  p.window_ratios = {1.0};
  p.cylinder_radius = 0.25;
  p.max_distance = 2.0;
  p.min_points = 5;
  return p;
}

/// The epochs' own M3C2 of one core point, a column per pool epoch.
struct Epochwise {
  std::vector<double> distance, lod, significant, n1, n2;
  m3c2::Tam3c2Epochwise view() const { return {distance.data(), lod.data(), significant.data(), n1.data(), n2.data()}; }
};

m3c2::Tam3c2Pool pool_of(std::vector<std::vector<double>>& clouds, std::vector<double> times) {
  std::vector<m3c2::PointsView> views;
  for (auto& c : clouds) views.emplace_back(c.data(), c.size() / 3);
  return m3c2::Tam3c2Pool(views, std::move(times));
}

TEST(Tam3c2Fallback, AShortCellTakesTheEpochsOwnM3c2AndOnlyAShortOne) {
  // Window ratio 0.5. Reference: a dense plane at 0 (t 0); epoch 1 (t 1): 4 points at 0.1, its
  // window (0.5) holds no other epoch, so its side stays short of 5 points; epoch 2 (t 10): a
  // dense plane at 0.2; epoch 3 (t 10.5): no point near the core point (its window takes epoch
  // 2: complete).
  std::vector<std::vector<double>> clouds{grid(21, 0.1, 0.0), grid(2, 0.1, 0.1), grid(21, 0.1, 0.2), {5.0, 5.0, 0.3}};
  const auto pool = pool_of(clouds, {0.0, 1.0, 10.0, 10.5});
  const std::vector<double> core{0.0, 0.0, 0.0};
  Epochwise m{{0.0, 0.123, 0.2, kNaN},
              {kNaN, 0.05, 0.01, kNaN},
              {kNaN, 1.0, 1.0, kNaN},
              {kNaN, 30.0, 30.0, kNaN},
              {kNaN, 4.0, 30.0, kNaN}};
  auto p = params();
  p.window_ratios = {0.5};
  const auto authors = m3c2::tam3c2(p, pool, 0, {1, 2, 3}, {core.data(), 1}, {}, m.view());
  p.fallback = m3c2::Tam3c2Fallback::kM3c2;
  const auto ours = m3c2::tam3c2(p, pool, 0, {1, 2, 3}, {core.data(), 1}, {}, m.view());
  // epoch 1: TAM3C2 has a distance from 4 points, but the window fell short: the epoch's own
  EXPECT_NEAR(authors.distance[0], 0.1, 1e-12);
  EXPECT_EQ(authors.source[0], std::uint8_t(m3c2::Tam3c2Source::kWindows));
  EXPECT_EQ(ours.source[0], std::uint8_t(m3c2::Tam3c2Source::kEpoch));
  EXPECT_EQ(ours.distance[0], 0.123);
  EXPECT_EQ(ours.lod[0], 0.05);
  EXPECT_EQ(ours.n2[0], 4.0);
  EXPECT_EQ(ours.significant[0], 1);
  EXPECT_EQ(ours.points2[0], 4u);  // what the window held, still said
  // epoch 2: both sides reached 5 points: TAM3C2's own, the same bits with or without
  EXPECT_EQ(ours.source[1], std::uint8_t(m3c2::Tam3c2Source::kWindows));
  EXPECT_EQ(ours.distance[1], authors.distance[1]);
  EXPECT_NEAR(ours.distance[1], 0.2, 1e-12);
  // epoch 3: borrowed epoch 2 and reached 5 points; no M3C2 there: TAM3C2's own either way
  EXPECT_EQ(ours.source[2], std::uint8_t(m3c2::Tam3c2Source::kWindows));
  EXPECT_EQ(ours.distance[2], authors.distance[2]);
  // no epochs' M3C2 given: the fallback is refused, not silently off
  EXPECT_THROW(m3c2::tam3c2(p, pool, 0, {1}, {core.data(), 1}), m3c2::InvalidArgument);
}

TEST(Tam3c2Fallback, ACellWithoutADistanceTakesTheEpochsOwnWhereItHasOne) {
  // Epoch 1 holds one point in the cylinder and is alone in its window (0.5): no TAM3C2 distance.
  std::vector<std::vector<double>> clouds{grid(21, 0.1, 0.0), {0.0, 0.0, 0.1}};
  const auto pool = pool_of(clouds, {0.0, 1.0});
  const std::vector<double> core{0.0, 0.0, 0.0};
  Epochwise m{{0.0, 0.1}, {kNaN, 0.02}, {kNaN, 1.0}, {kNaN, 30.0}, {kNaN, 1.0}};
  auto p = params();
  p.window_ratios = {0.5};
  EXPECT_TRUE(std::isnan(m3c2::tam3c2(p, pool, 0, {1}, {core.data(), 1}, {}, m.view()).distance[0]));
  p.fallback = m3c2::Tam3c2Fallback::kM3c2;
  const auto r = m3c2::tam3c2(p, pool, 0, {1}, {core.data(), 1}, {}, m.view());
  EXPECT_EQ(r.distance[0], 0.1);
  EXPECT_EQ(r.source[0], std::uint8_t(m3c2::Tam3c2Source::kEpoch));
  m.distance[1] = kNaN;  // neither has one
  const auto none = m3c2::tam3c2(p, pool, 0, {1}, {core.data(), 1}, {}, m.view());
  EXPECT_TRUE(std::isnan(none.distance[0]));
  EXPECT_EQ(none.source[0], std::uint8_t(m3c2::Tam3c2Source::kNone));
  EXPECT_EQ(none.significant[0], -1);
}

TEST(Tam3c2Breaks, AWindowStopsAtAStepInsteadOfAveragingAcrossIt) {
  // A dense reference at 0 (t 0) and 11 epochs (t 1..11) of 4 points each near the core point,
  // at 0 before pool epoch 6 and 0.1 from it: a side needs 3 epochs for 10 points. Epoch 5's
  // window takes 5, 4 and then 6 (a tie: the earlier first, then 6): across the step.
  std::vector<std::vector<double>> clouds{grid(21, 0.1, 0.0)};
  std::vector<double> times{0.0};
  Epochwise m;
  for (int e = 1; e <= 11; ++e) {
    const double z = e >= 6 ? 0.1 : 0.0;
    clouds.push_back(grid(2, 0.1, z)), times.push_back(double(e));
  }
  for (int e = 0; e <= 11; ++e) {
    m.distance.push_back(e >= 6 ? 0.1 : 0.0);  // the epochs' own M3C2: the step, noise-free
    for (auto* v : {&m.lod, &m.significant, &m.n1, &m.n2}) v->push_back(kNaN);
  }
  const auto pool = pool_of(clouds, times);
  const std::vector<double> core{0.0, 0.0, 0.0};
  auto p = params();
  p.min_points = 10;
  const auto smeared = m3c2::tam3c2(p, pool, 0, {5, 6}, {core.data(), 1}, {}, m.view());
  EXPECT_NEAR(smeared.distance[0], 0.4 / 12.0, 1e-12);  // 4 of its 12 points after the step
  p.breaks = m3c2::Tam3c2Breaks::kChangePoints;
  const auto stopped = m3c2::tam3c2(p, pool, 0, {5, 6}, {core.data(), 1}, {}, m.view());
  EXPECT_NEAR(stopped.distance[0], 0.0, 1e-12);  // epochs 5, 4, 3: all before the step
  EXPECT_EQ(stopped.epochs2[0], 3u);
  EXPECT_NEAR(stopped.distance[1], 0.1, 1e-12);               // epochs 6, 7, 8: all after it
  EXPECT_NEAR(smeared.distance[1], 0.1 * 8.0 / 12.0, 1e-12);  // 6, 5, 7: a third before it
}

TEST(Tam3c2Breaks, SegmentsLeaveNanEpochsOutAndGiveThemTheSegmentBefore) {
  // Pool order is not time order: by_time lists it. The step is between time ranks 6 and 7 (of
  // finite values, rank 6 is the 7th); the NaN at time rank 7 belongs to the segment before.
  const std::vector<double> row{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1};
  std::vector<double> with_gap(row.begin(), row.begin() + 6);
  with_gap.push_back(kNaN);
  with_gap.insert(with_gap.end(), row.begin() + 6, row.end());
  std::vector<std::size_t> by_time(with_gap.size());
  for (std::size_t k = 0; k < by_time.size(); ++k) by_time[k] = k;
  std::vector<std::uint32_t> segment;
  std::vector<double> scratch;
  m3c2::detail::break_segments(with_gap.data(), by_time, m3c2::Tam3c2Params().change_points, segment, scratch);
  const std::vector<std::uint32_t> want{0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1};
  EXPECT_EQ(segment, want);
  // too few finite epochs for the window (6): one segment
  const std::vector<double> short_row{0.0, 0.0, 0.0, 0.1, 0.1, 0.1};
  m3c2::detail::break_segments(short_row.data(), std::vector<std::size_t>{0, 1, 2, 3, 4, 5},
                               m3c2::Tam3c2Params().change_points, segment, scratch);
  EXPECT_EQ(segment, std::vector<std::uint32_t>(6, 0));
}

}  // namespace
