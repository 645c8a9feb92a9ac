// A template's points in a tree of balls, for locating many of them at once: where one
// cell holds a whole ball, every point in it goes to that cell without being located.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace vfe::kernels {

struct PointTree {
  struct Node {
    Eigen::Vector3d centre;  ///< in template units, as the points
    double radius;           ///< every point of the node lies within this distance of centre
    double fraction;         ///< the node's points' fractions, summed in tree order
    std::uint32_t first;     ///< the node's points are points[first, first + count)
    std::uint32_t count;
    std::uint32_t skip;  ///< the index of the node after this one's subtree (its children follow it)
    bool leaf() const { return count <= kLeafPoints; }
  };
  /// A node of more points has two children, halves of its points by the widest axis.
  static constexpr std::uint32_t kLeafPoints = 64;

  std::vector<Node> nodes;  ///< depth first, the root (all points) first; empty: no tree
  std::vector<Eigen::Vector3d> points;  ///< the template's points in tree order
  std::vector<double> fractions;        ///< their fractions

  bool empty() const { return nodes.empty(); }
};

/// The bounding box of points[order[i]] for i in [first, last) (first < last).
Eigen::AlignedBox3d bounds_of(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& order,
                              std::size_t first, std::size_t last);

/// Reorders order[first, last) so that order[first, mid) holds the points lowest along the
/// widest axis of `bounds` (theirs, from bounds_of): the split both point groupings use.
void split_along_widest_axis(const std::vector<Eigen::Vector3d>& points, std::vector<std::size_t>& order,
                             std::size_t first, std::size_t mid, std::size_t last, const Eigen::AlignedBox3d& bounds);

/// The tree of points (and their fractions): each node's points split in halves along the
/// widest axis of their bounds, down to kLeafPoints; a node's ball is centred at its points'
/// bounding box centre, with the largest distance of a point from it as its radius (rounded
/// up).
PointTree make_point_tree(const std::vector<Eigen::Vector3d>& points, const std::vector<double>& fractions);

}  // namespace vfe::kernels
