// Point location on a PolyMesh: an exact point-in-cell test, and three ways to find the
// candidate cells (a cell-binned spatial hash, a KD-tree over cell centres, a walk across
// face neighbours). Candidates, then the exact test, then an explicit fallback.
//
// Tie rule. Cell c is the union of the tetrahedra (cell centre, face centre, two
// consecutive points of a face) over its faces. A point p belongs to c when it lies in
// one of them, decided with exact orientation signs (predicates.hpp) for p displaced by
// an infinitesimal (e, e^2, e^3). So:
//  - a point exactly on a face goes to the cell on the +x side of the face (the +y side if
//    the face is parallel to x, the +z side if parallel to x and y): on an axis-aligned
//    mesh, the cell above it, as CartesianGrid does. In owner/neighbour terms, with
//    s = orient3d(face centre, a, b, p) for the face triangle (a, b in face order), the
//    same signed expression for both cells: owner when s < 0, neighbour when s > 0, and
//    for s = 0 the displacement decides;
//  - points on edges and vertices follow from the same displacement: every point of the
//    mesh belongs to exactly one cell, whatever the mesh, as long as the tetrahedra are
//    positively oriented (PolyMesh::inverted_tet_count() == 0);
//  - on the boundary: a point on a lower boundary face (outward normal towards -x) is
//    inside, on an upper one (towards +x) it is outside (-1), as for CartesianGrid.
// All locators give the same cell as locate_brute_force for every point.
//
// Lifetime: every locator keeps a reference to the mesh (and the KD-tree and the walk to
// the spatial hash); those must outlive it and stay where they are. All query functions
// are const and safe to call from many threads at once.
#pragma once

#include "polymesh/polymesh.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace vfe {

/// True when p lies in cell c by the tie rule above (exact, consistent between cells).
/// Cost: the cell's bounding box, then one plane distance per face, which settles points
/// that are clearly outside or deep inside; exact orientation signs only for points near a
/// face (one per planar face of a convex cell, about five per face otherwise).
bool cell_contains(const PolyMesh& mesh, std::int64_t c, const Eigen::Vector3d& p);

/// The cell holding p, or -1: tests every cell (O(cells)); the reference for the others.
std::int64_t locate_brute_force(const PolyMesh& mesh, const Eigen::Vector3d& p);

/// Uniform bins over the box of the cells' tetrahedra; each cell is registered in every bin
/// its bounding box overlaps. locate = the bin's candidates, then the exact test.
class SpatialHash {
 public:
  /// bins_per_cell: bins per cell on average (> 0); 1 is a good default.
  explicit SpatialHash(const PolyMesh& mesh, double bins_per_cell = 1.0);

  /// The cell holding p, or -1 when p is outside the mesh (or not finite).
  std::int64_t locate(const Eigen::Vector3d& p) const;
  /// Cells whose bounds overlap the bin of p, those covering more of the bin first (empty
  /// outside the box).
  std::span<const std::uint32_t> candidates(const Eigen::Vector3d& p) const;
  /// The cells whose bounding boxes overlap `box` (closed), each once: replaces the
  /// contents of out (no allocation once out has the capacity).
  void cells_in_box(const Eigen::AlignedBox3d& box, std::vector<std::int64_t>& out) const;
  /// The same cells as cells_in_box, in increasing order (cheaper for a box that spans few
  /// bins: the duplicates are sorted out instead of each cell's first bin computed).
  void sorted_cells_in_box(const Eigen::AlignedBox3d& box, std::vector<std::int64_t>& out) const;
  /// True when p is in the hashed box (closed); points outside it are outside the mesh.
  bool in_box(const Eigen::Vector3d& p) const {
    return p.x() >= lo_.x() && p.x() <= hi_.x() && p.y() >= lo_.y() && p.y() <= hi_.y() && p.z() >= lo_.z() &&
           p.z() <= hi_.z();
  }
  const std::array<std::int64_t, 3>& bins() const { return nb_; }
  /// Stored (bin, cell) pairs: memory is about 4 bytes each.
  std::int64_t entry_count() const { return static_cast<std::int64_t>(cells_.size()); }
  const PolyMesh& mesh() const { return *mesh_; }

 private:
  std::int64_t bin(int d, double x) const;
  /// The bins a box overlaps, per axis lo..hi; false when it misses the hashed box.
  bool bin_range(const Eigen::AlignedBox3d& box, std::int64_t lo[3], std::int64_t hi[3]) const;

  const PolyMesh* mesh_;
  Eigen::Vector3d lo_, hi_, inv_h_;
  std::array<std::int64_t, 3> nb_{};
  std::vector<std::int64_t> offsets_;
  std::vector<std::uint32_t> cells_;
};

/// nanoflann KD-tree over the cell centres (built once, single-threaded).
/// locate = the k cells with the nearest centres, then the exact test, then the hash.
class KdTreeLocator {
 public:
  /// k: nearest centres to test before falling back to the hash (>= 1).
  KdTreeLocator(const PolyMesh& mesh, const SpatialHash& fallback, int k = 8, int leaf_max_size = 10);
  ~KdTreeLocator();
  KdTreeLocator(KdTreeLocator&&) noexcept;
  KdTreeLocator& operator=(KdTreeLocator&&) noexcept;

  /// The cell holding p, or -1 when p is outside the mesh.
  std::int64_t locate(const Eigen::Vector3d& p) const;
  /// The cell whose centre is nearest to p (any finite p, inside or outside the mesh; ties
  /// go to one of them, the same one on every call; 0 for a non-finite p).
  std::int64_t nearest_cell(const Eigen::Vector3d& p) const;
  /// The k cells whose centres are nearest to a finite p (1 <= k <= 64), nearest first,
  /// into cells[0, k) with their squared distances into d2[0, k); returns how many (fewer
  /// when the mesh has fewer cells). Allocates nothing.
  std::size_t nearest_cells(const Eigen::Vector3d& p, std::size_t k, std::uint32_t* cells, double* d2) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Walk from a start cell towards p across the faces: in each cell step to the neighbour
/// across the face whose plane p lies furthest beyond, until a cell holds p.
class NeighbourWalk {
 public:
  enum class Stop {
    kInside,     ///< cell holds p
    kBoundary,   ///< the face to cross is a boundary face (p outside, or behind a hole)
    kStepLimit,  ///< max_steps reached (a cycle or a long way)
  };
  struct Result {
    std::int64_t cell = -1;  ///< the cell holding p when stop == kInside, else -1
    std::int64_t steps = 0;  ///< faces crossed
    Stop stop = Stop::kStepLimit;
  };

  /// max_steps <= 0 chooses about 4x the cells across the mesh's bounding box.
  NeighbourWalk(const PolyMesh& mesh, const SpatialHash& fallback, std::int64_t max_steps = 0);

  /// The cell holding p, or -1 outside: walks from start (a valid cell, e.g. the cell of a
  /// nearby point), and asks the hash when the walk stops without a cell (boundary reached,
  /// since the mesh need not be convex, or step limit). An invalid start uses the hash.
  std::int64_t locate(const Eigen::Vector3d& p, std::int64_t start) const;
  /// The walk alone, without fallback.
  Result walk(const Eigen::Vector3d& p, std::int64_t start) const;
  std::int64_t max_steps() const { return max_steps_; }

 private:
  const PolyMesh* mesh_;
  const SpatialHash* hash_;
  std::int64_t max_steps_;
};

/// The three locators over one mesh, for the engine: hash for cold queries, walk from a
/// hint for nearby points, KD-tree for the nearest cell of points outside the mesh.
/// Not movable (the KD-tree and the walk point into it); hold it by unique_ptr.
class CellLocator {
 public:
  explicit CellLocator(const PolyMesh& mesh);
  CellLocator(const CellLocator&) = delete;
  CellLocator& operator=(const CellLocator&) = delete;

  /// The cell holding p, or -1 outside the mesh (spatial hash).
  std::int64_t locate(const Eigen::Vector3d& p) const { return hash_.locate(p); }
  /// Same answer as locate, faster when p is near cell `hint` (neighbour walk); hint < 0
  /// or out of range uses the hash.
  std::int64_t locate_from(const Eigen::Vector3d& p, std::int64_t hint) const { return walk_.locate(p, hint); }
  /// The cell whose centre is nearest to p (the `nearest` outside policy).
  std::int64_t nearest_cell(const Eigen::Vector3d& p) const { return kdtree_.nearest_cell(p); }

  const PolyMesh& mesh() const { return hash_.mesh(); }
  const SpatialHash& hash() const { return hash_; }
  const KdTreeLocator& kdtree() const { return kdtree_; }
  const NeighbourWalk& walk() const { return walk_; }

 private:
  SpatialHash hash_;
  KdTreeLocator kdtree_;
  NeighbourWalk walk_;
};

}  // namespace vfe
