#include "box_lattice.hpp"

#include "methods/polymesh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vfe::detail {

namespace {

/// The distinct values of xs (sorted in place): a value within tol of the first value of
/// the current run joins that run.
std::vector<double> distinct_nodes(std::vector<double>& xs, double tol) {
  std::sort(xs.begin(), xs.end());
  std::vector<double> nodes;
  for (const double x : xs)
    if (nodes.empty() || x > nodes.back() + tol) nodes.push_back(x);
  return nodes;
}

/// Index of the node within tol of x, or -1.
std::int64_t node_index(const std::vector<double>& nodes, double x, double tol) {
  const auto it = std::lower_bound(nodes.begin(), nodes.end(), x - tol);
  if (it == nodes.end() || std::abs(*it - x) > tol) return -1;
  return it - nodes.begin();
}

}  // namespace

std::optional<BoxLattice> find_box_lattice(const PolyMesh& mesh) {
  const std::int64_t n = mesh.cell_count();
  if (n == 0) return std::nullopt;
  std::vector<Eigen::AlignedBox3d> boxes(static_cast<std::size_t>(n));
  double smallest = std::numeric_limits<double>::infinity();
  for (std::int64_t c = 0; c < n; ++c) {
    if (!cell_is_box(mesh, c, boxes[static_cast<std::size_t>(c)])) return std::nullopt;
    smallest = std::min(smallest, boxes[static_cast<std::size_t>(c)].sizes().minCoeff());
  }
  if (!(smallest > 0)) return std::nullopt;
  BoxLattice lattice;
  lattice.tolerance = 1e-9 * smallest;
  const double tol = lattice.tolerance;
  std::array<std::vector<double>, 3> nodes;
  std::int64_t slots = 1;
  for (int d = 0; d < 3; ++d) {
    std::vector<double> xs;
    xs.reserve(2 * static_cast<std::size_t>(n));
    for (const auto& b : boxes) xs.insert(xs.end(), {b.min()[d], b.max()[d]});
    nodes[d] = distinct_nodes(xs, tol);
    lattice.cells[d] = static_cast<std::int64_t>(nodes[d].size()) - 1;
    // Checked one axis at a time: the product of three axes may not fit.
    if (lattice.cells[d] < 1 || lattice.cells[d] > n / slots) return std::nullopt;
    slots *= lattice.cells[d];
  }
  if (slots != n) return std::nullopt;
  lattice.cell_map.assign(static_cast<std::size_t>(n + 1), -1);
  for (std::int64_t c = 0; c < n; ++c) {
    const auto& b = boxes[static_cast<std::size_t>(c)];
    std::int64_t at[3];
    for (int d = 0; d < 3; ++d) {
      at[d] = node_index(nodes[d], b.min()[d], tol);
      // The box spans one slot: its upper corner is the next node.
      if (at[d] < 0 || node_index(nodes[d], b.max()[d], tol) != at[d] + 1) return std::nullopt;
    }
    std::int64_t& slot =
        lattice.cell_map[static_cast<std::size_t>(at[0] + lattice.cells[0] * (at[1] + lattice.cells[1] * at[2]))];
    if (slot >= 0) return std::nullopt;
    slot = c;
  }
  lattice.cell_map[static_cast<std::size_t>(n)] = n;  // n distinct cells filled n slots: all filled
  lattice.grid_numbering = true;
  for (std::int64_t i = 0; i < n; ++i)
    lattice.grid_numbering = lattice.grid_numbering && lattice.cell_map[static_cast<std::size_t>(i)] == i;
  lattice.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(nodes[0].front(), nodes[1].front(), nodes[2].front()),
                                       Eigen::Vector3d(nodes[0].back(), nodes[1].back(), nodes[2].back()));
  // Evenly spaced nodes (to within the tolerance) make a Cartesian grid: O(1) location.
  bool uniform = true;
  CartesianGridSpec spec;
  for (int d = 0; d < 3; ++d) {
    const double h = (nodes[d].back() - nodes[d].front()) / double(lattice.cells[d]);
    for (std::size_t i = 0; i < nodes[d].size(); ++i)
      uniform = uniform && std::abs(nodes[d][i] - (nodes[d].front() + double(i) * h)) <= tol;
    spec.origin[static_cast<std::size_t>(d)] = nodes[d].front();
    spec.spacing[static_cast<std::size_t>(d)] = h;
    spec.cells[static_cast<std::size_t>(d)] = lattice.cells[d];
  }
  if (uniform)
    lattice.cartesian.emplace(spec);
  else
    lattice.rectilinear.emplace(std::move(nodes));
  return lattice;
}

}  // namespace vfe::detail
