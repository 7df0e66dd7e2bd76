#include "cylinder.hpp"

#include <algorithm>

namespace m3c2::detail {

void cylinder_offsets(const KdTree& tree, const Cylinder& cyl, CylinderScratch& scratch,
                      std::vector<double>& t_out) {
  scratch.hits.clear();
  tree.cylinder(cyl, scratch.hits);
  std::sort(scratch.hits.begin(), scratch.hits.end());
  t_out.clear();
  t_out.reserve(scratch.hits.size());
  for (const auto& [index, t] : scratch.hits) t_out.push_back(t);
}

}  // namespace m3c2::detail
