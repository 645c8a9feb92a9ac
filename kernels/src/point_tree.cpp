#include <vfe/kernels/point_tree.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vfe::kernels {

namespace {

/// Appends the subtree of points [first, last) of tree order `order`.
void build(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& order, std::size_t first,
           std::size_t last, std::vector<PointTree::Node>& nodes) {
  const Eigen::AlignedBox3d bounds = bounds_of(points, order, first, last);
  const Eigen::Vector3d centre = 0.5 * (bounds.min() + bounds.max());
  double radius = 0;
  for (std::size_t i = first; i < last; ++i) radius = std::max(radius, (points[order[i]] - centre).norm());
  const std::size_t at = nodes.size();
  nodes.push_back({centre, std::nextafter(radius, std::numeric_limits<double>::infinity()), 0.0,
                   static_cast<std::uint32_t>(first), static_cast<std::uint32_t>(last - first), 0});
  if (!nodes[at].leaf()) {
    const std::size_t mid = first + (last - first) / 2;
    split_along_widest_axis(points, order, first, mid, last, bounds);
    build(points, order, first, mid, nodes);
    build(points, order, mid, last, nodes);
  }
  nodes[at].skip = static_cast<std::uint32_t>(nodes.size());
}

}  // namespace

Eigen::AlignedBox3d bounds_of(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& order,
                              std::size_t first, std::size_t last) {
  Eigen::Vector3d lo = points[order[first]], hi = lo;
  for (std::size_t i = first; i < last; ++i) {
    lo = lo.cwiseMin(points[order[i]]);
    hi = hi.cwiseMax(points[order[i]]);
  }
  return {lo, hi};
}

void split_along_widest_axis(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& order,
                             std::size_t first, std::size_t mid, std::size_t last, const Eigen::AlignedBox3d& bounds) {
  int axis = 0;
  bounds.sizes().maxCoeff(&axis);
  std::nth_element(order.begin() + static_cast<std::ptrdiff_t>(first), order.begin() + static_cast<std::ptrdiff_t>(mid),
                   order.begin() + static_cast<std::ptrdiff_t>(last),
                   [&](std::size_t a, std::size_t b) { return points[a][axis] < points[b][axis]; });
}

PointTree make_point_tree(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& fractions) {
  PointTree tree;
  const std::size_t n = points.size();
  if (n == 0 || n != fractions.size() || n > std::numeric_limits<std::uint32_t>::max()) return tree;
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  build(points, order, 0, n, tree.nodes);
  tree.points.resize(n);
  tree.fractions.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    tree.points[i] = points[order[i]];
    tree.fractions[i] = fractions[order[i]];
  }
  for (PointTree::Node& node : tree.nodes)
    for (std::uint32_t i = node.first; i < node.first + node.count; ++i) node.fraction += tree.fractions[i];
  return tree;
}

}  // namespace vfe::kernels
