#include <m3c2/m3c2.hpp>

#include "pipeline/statistics.hpp"
#include "pipeline/validation.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace m3c2 {
namespace {

std::uint64_t cell_index(double v, double origin, double cell, std::uint64_t count) {
  const double k = std::floor((v - origin) / cell);
  return k <= 0.0 ? 0 : std::min(count - 1, std::uint64_t(k));
}

}  // namespace

Grid grid_core_points(PointsView points, double cell) {
  detail::require_positive("cell", cell);
  detail::require_finite_points("points", points);
  detail::require_cell_count("cell", cell, points);
  Grid grid;
  grid.cell = cell;
  if (points.empty()) return grid;
  double xmin = points.coord(0, 0), ymin = points.coord(0, 1), xmax = xmin, ymax = ymin;
  for (std::size_t i = 1; i < points.size(); ++i) {
    xmin = std::min(xmin, points.coord(i, 0)), xmax = std::max(xmax, points.coord(i, 0));
    ymin = std::min(ymin, points.coord(i, 1)), ymax = std::max(ymax, points.coord(i, 1));
  }
  // floor(x / cell) * cell can round above x: step back a cell so that no point has index -1.
  grid.x0 = std::floor(xmin / cell) * cell;
  if (grid.x0 > xmin) grid.x0 -= cell;
  grid.y0 = std::floor(ymin / cell) * cell;
  if (grid.y0 > ymin) grid.y0 -= cell;
  grid.cols = std::uint64_t(std::floor((xmax - grid.x0) / cell)) + 1;
  grid.rows = std::uint64_t(std::floor((ymax - grid.y0) / cell)) + 1;

  // Ordered map: cells come out row by row, column by column, the same every run.
  std::map<std::pair<std::uint64_t, std::uint64_t>, std::vector<double>> z_by_cell;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto c = cell_index(points.coord(i, 0), grid.x0, cell, grid.cols);
    const auto r = cell_index(points.coord(i, 1), grid.y0, cell, grid.rows);
    z_by_cell[{r, c}].push_back(points.coord(i, 2));
  }
  for (auto& [rc, zs] : z_by_cell) {
    std::sort(zs.begin(), zs.end());
    grid.row.push_back(rc.first);
    grid.col.push_back(rc.second);
    grid.core_points.push_back(grid.x0 + (double(rc.second) + 0.5) * cell);
    grid.core_points.push_back(grid.y0 + (double(rc.first) + 0.5) * cell);
    grid.core_points.push_back(detail::sorted_quantile(zs, 0.5));
  }
  return grid;
}

}  // namespace m3c2
