// Core-point helpers (section 3.1.1): minimum-spacing subsampling and the regular 2D grid.

#include "test_support.hpp"

#include <algorithm>
#include <map>

namespace m3c2::test {
namespace {

constexpr double kSpacing = 0.3;

Cloud subsample_cloud() { return random_box(777, 5000, Vec3(0, 0, 0), Vec3(10, 10, 1)); }

TEST(Subsample, NoTwoKeptPointsCloserThanSpacing) {
  const Cloud c = subsample_cloud();
  const auto kept = subsample_min_spacing(c.view(), kSpacing);
  ASSERT_GT(kept.size(), 100u);
  ASSERT_LT(kept.size(), c.size());
  for (std::size_t a = 0; a < kept.size(); ++a)
    for (std::size_t b = a + 1; b < kept.size(); ++b)
      ASSERT_GE((c[kept[a]] - c[kept[b]]).norm(), kSpacing) << kept[a] << " " << kept[b];
}

TEST(Subsample, EveryDroppedPointIsWithinSpacingOfAKeptPoint) {
  const Cloud c = subsample_cloud();
  const auto kept = subsample_min_spacing(c.view(), kSpacing);
  std::vector<bool> is_kept(c.size(), false);
  for (auto k : kept) is_kept[k] = true;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (is_kept[i]) continue;
    double best = std::numeric_limits<double>::infinity();
    for (auto k : kept) best = std::min(best, (c[i] - c[k]).norm());
    ASSERT_LE(best, kSpacing) << "dropped point " << i << " is " << best << " from every kept point";
  }
}

TEST(Subsample, SortedDeterministicAndFirstPointKept) {
  const Cloud c = subsample_cloud();
  const auto a = subsample_min_spacing(c.view(), kSpacing);
  const auto b = subsample_min_spacing(c.view(), kSpacing);
  EXPECT_EQ(a, b);
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.front(), 0u);
  EXPECT_TRUE(std::is_sorted(a.begin(), a.end()));
  EXPECT_TRUE(std::adjacent_find(a.begin(), a.end()) == a.end()) << "duplicate index";
}

TEST(Subsample, EqualsSequentialGreedyInInputOrder) {
  // The contract: "chosen greedily in input order (the first point of a cluster is kept)".
  const Cloud c = subsample_cloud();
  std::vector<std::uint64_t> expected;
  for (std::size_t i = 0; i < c.size(); ++i) {
    bool close = false;
    for (auto k : expected)
      if ((c[i] - c[k]).norm() < kSpacing) {
        close = true;
        break;
      }
    if (!close) expected.push_back(i);
  }
  EXPECT_EQ(subsample_min_spacing(c.view(), kSpacing), expected);
}

TEST(Subsample, DuplicatesCollapseToTheFirst) {
  Cloud c;
  c.add(1, 1, 1);
  c.add(5, 5, 5);
  c.add(1, 1, 1);
  c.add(5, 5, 5);
  c.add(1.01, 1, 1);
  const auto kept = subsample_min_spacing(c.view(), 0.1);
  EXPECT_EQ(kept, (std::vector<std::uint64_t>{0, 1}));
}

// Cloud with x, y in [0, 2.6] (min exactly 0) and cell 1: a 3 x 3 grid with x0 = y0 = 0.
// Non-empty cells (row, col): (0,0) z {5, 1, 3} -> 3; (0,2) z {-1}; (1,1) z {50, 10, 40, 20, 30}
// -> 30; (2,0) z {7, 9, 8} -> 8. Every other cell is empty and must be omitted.
Cloud grid_cloud() {
  Cloud c;
  c.add(0.0, 0.0, 5);
  c.add(0.5, 0.5, 1);
  c.add(0.9, 0.2, 3);
  c.add(2.1, 0.3, -1);
  c.add(1.2, 1.7, 50);
  c.add(1.8, 1.1, 10);
  c.add(1.5, 1.5, 40);
  c.add(1.1, 1.9, 20);
  c.add(1.3, 1.3, 30);
  c.add(0.4, 2.6, 7);
  c.add(0.6, 2.4, 9);
  c.add(0.2, 2.2, 8);
  return c;
}

TEST(GridCorePoints, CellCentresAndMedianZOnKnownCloud) {
  const Cloud c = grid_cloud();
  const Grid g = grid_core_points(c.view(), 1.0);
  EXPECT_EQ(g.cell, 1.0);
  EXPECT_EQ(g.x0, 0.0);
  EXPECT_EQ(g.y0, 0.0);
  EXPECT_EQ(g.rows, 3u);
  EXPECT_EQ(g.cols, 3u);
  ASSERT_EQ(g.core_points.size(), 3 * g.row.size());
  ASSERT_EQ(g.row.size(), 4u);
  ASSERT_EQ(g.col.size(), 4u);
  const std::map<std::pair<std::uint64_t, std::uint64_t>, double> expected = {
      {{0, 0}, 3.0}, {{0, 2}, -1.0}, {{1, 1}, 30.0}, {{2, 0}, 8.0}};
  std::map<std::pair<std::uint64_t, std::uint64_t>, int> seen;
  for (std::size_t i = 0; i < g.row.size(); ++i) {
    const auto key = std::make_pair(g.row[i], g.col[i]);
    ASSERT_TRUE(expected.count(key)) << "unexpected cell " << g.row[i] << "," << g.col[i];
    ++seen[key];
    EXPECT_DOUBLE_EQ(g.core_points[3 * i], g.x0 + (static_cast<double>(g.col[i]) + 0.5) * g.cell);
    EXPECT_DOUBLE_EQ(g.core_points[3 * i + 1], g.y0 + (static_cast<double>(g.row[i]) + 0.5) * g.cell);
    EXPECT_EQ(g.core_points[3 * i + 2], expected.at(key)) << "median z of cell " << g.row[i] << "," << g.col[i];
  }
  EXPECT_EQ(seen.size(), 4u);
}

TEST(GridCorePoints, EveryPointFallsInTheCellItsCorePointNames) {
  const Cloud c = random_box(31337, 3000, Vec3(-3.3, 12.1, 0), Vec3(4.9, 17.7, 2));
  const double cell = 0.7;
  const Grid g = grid_core_points(c.view(), cell);
  std::map<std::pair<std::uint64_t, std::uint64_t>, std::vector<double>> cells;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const double fc = (c[i].x() - g.x0) / cell, fr = (c[i].y() - g.y0) / cell;
    ASSERT_GE(fc, 0.0);
    ASSERT_GE(fr, 0.0);
    const auto col = std::min<std::uint64_t>(static_cast<std::uint64_t>(fc), g.cols - 1);
    const auto row = std::min<std::uint64_t>(static_cast<std::uint64_t>(fr), g.rows - 1);
    cells[{row, col}].push_back(c[i].z());
  }
  EXPECT_EQ(g.row.size(), cells.size()) << "one core point per non-empty cell";
  EXPECT_LE(g.x0, -3.3 + 1e-12);
  EXPECT_GE(g.x0 + g.cols * cell, 4.9 - 1e-12);
  for (std::size_t i = 0; i < g.row.size(); ++i) {
    auto it = cells.find({g.row[i], g.col[i]});
    ASSERT_NE(it, cells.end());
    std::vector<double> z = it->second;
    std::sort(z.begin(), z.end());
    const std::size_t n = z.size();
    const double median = n % 2 ? z[n / 2] : 0.5 * (z[n / 2 - 1] + z[n / 2]);
    // Points exactly on a cell edge could be binned differently by rounding; with random
    // coordinates that has probability ~1e-13, so the medians must agree exactly.
    EXPECT_DOUBLE_EQ(g.core_points[3 * i + 2], median) << "cell " << g.row[i] << "," << g.col[i];
  }
}

}  // namespace
}  // namespace m3c2::test
