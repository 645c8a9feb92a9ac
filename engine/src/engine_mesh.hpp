// The engine's mesh: one of the three kinds (Cartesian grid, rectilinear grid, polyhedral
// mesh with its locators), and what the engine asks of any of them (cells, volumes,
// centres, bounds, periodic wrapping). The methods' drivers use the concrete kinds
// (methods/registry.hpp): the engine dispatches on the kind once per compute.
#pragma once

#include "box_lattice.hpp"
#include "cartesian_grid.hpp"
#include "polymesh/locators.hpp"
#include "polymesh/polymesh.hpp"
#include "polymesh/rectilinear_grid.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>

namespace vfe::detail {

enum class MeshKind { cartesian, rectilinear, polyhedral };

class EngineMesh {
 public:
  explicit EngineMesh(const CartesianGridSpec& spec);
  explicit EngineMesh(RectilinearGrid grid);
  /// Takes a polyMesh (refuses cyclic patches: their volume would be lost).
  explicit EngineMesh(std::unique_ptr<PolyMesh> mesh);

  MeshKind kind() const { return kind_; }
  const char* kind_name() const;
  std::int64_t cell_count() const { return cells_; }
  double cell_volume(std::int64_t c) const;
  Eigen::Vector3d cell_centre(std::int64_t c) const;
  double smallest_cell_volume() const { return v_min_; }
  double largest_cell_volume() const { return v_max_; }
  /// Bounding box of the mesh.
  Eigen::AlignedBox3d bounds() const;

  /// Periodic axes (bit d: axis d); throws Error on a polyhedral mesh.
  void set_periodic(unsigned mask);
  unsigned periodic() const { return periodic_; }
  /// A position moved into the mesh along its periodic axes (others unchanged).
  Eigen::Vector3d wrap(const Eigen::Vector3d& x) const { return periodic_ ? wrap_periodic(x) : x; }

  /// The concrete mesh of each kind (null for the other kinds).
  const CartesianGrid* cartesian() const { return cartesian_ ? &*cartesian_ : nullptr; }
  const RectilinearGrid* rectilinear() const { return rectilinear_ ? &*rectilinear_ : nullptr; }
  const PolyMesh* polyhedral() const { return poly_.get(); }
  const CellLocator* locator() const { return locator_.get(); }
  /// A polyMesh whose cells are a lattice of axis-aligned boxes: that lattice (found once,
  /// at creation), else null.
  const BoxLattice* lattice() const { return lattice_ ? &*lattice_ : nullptr; }

  /// The cells as polyhedra (points, faces, owner, neighbour) for writers that draw them;
  /// built on demand for the grids. Null for a Cartesian grid (writers use ImageData).
  std::unique_ptr<PolyMesh> polyhedra() const;

 private:
  Eigen::Vector3d wrap_periodic(const Eigen::Vector3d& x) const;

  MeshKind kind_;
  std::int64_t cells_ = 0;
  double v_min_ = 0, v_max_ = 0;
  unsigned periodic_ = 0;
  std::optional<CartesianGrid> cartesian_;
  std::optional<RectilinearGrid> rectilinear_;
  std::unique_ptr<PolyMesh> poly_;
  std::unique_ptr<CellLocator> locator_;
  std::optional<BoxLattice> lattice_;
};

}  // namespace vfe::detail
