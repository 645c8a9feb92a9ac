// A polyMesh whose cells are exactly the cells of a rectilinear lattice of axis-aligned
// boxes (blockMesh's boxes, uniform or graded), found once when the engine is created: the
// compute then runs the grid drivers on the equivalent grid and renumbers their cells.
#pragma once

#include "cartesian_grid.hpp"
#include "polymesh/polymesh.hpp"
#include "polymesh/rectilinear_grid.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace vfe::detail {

struct BoxLattice {
  /// The grid of the same cells: Cartesian when the nodes are evenly spaced, else rectilinear.
  std::optional<CartesianGrid> cartesian;
  std::optional<RectilinearGrid> rectilinear;
  std::array<std::int64_t, 3> cells{};
  /// Lattice index (x fastest, as the grids) -> polyMesh cell; one more entry maps the
  /// dropped-volume slot to itself.
  std::vector<std::int64_t> cell_map;
  /// cell_map is the identity: the polyMesh numbers its cells as the grid does (x fastest,
  /// as blockMesh numbers one block's cells).
  bool grid_numbering = false;
  Eigen::AlignedBox3d bounds;
  /// How far two coordinates may differ and still be one lattice node (1e-9 of the
  /// smallest cell side).
  double tolerance = 0;
};

/// The lattice of the mesh's cells, or nothing when some cell is not an axis-aligned box,
/// a box's corners do not lie on the lattice of the distinct node coordinates (to within
/// the tolerance) or a lattice slot is empty or taken twice.
std::optional<BoxLattice> find_box_lattice(const PolyMesh& mesh);

}  // namespace vfe::detail
