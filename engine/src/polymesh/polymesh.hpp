// Polyhedral mesh in OpenFOAM's conventions, with OpenFOAM's face and cell geometry.
#pragma once

#include "polymesh/polymesh_reader.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace vfe {

/// An immutable polyhedral mesh. Cells keep OpenFOAM's order (cell count = largest owner
/// or neighbour label + 1); faces keep the file's order (internal faces first) and
/// orientation (the area vector points from the owner to the neighbour, or out of the
/// mesh on the boundary). Geometry is computed exactly as OpenFOAM's primitiveMesh does:
///  - face: triangle fan around the mean of its points; area vector = sum of the fan's
///    area vectors; centre = area-weighted mean of the triangle centroids (triangles
///    directly: mean of the points, half the cross product);
///  - cell: estimated centre = mean of its face centres; pyramids (face, estimated
///    centre); volume = sum of the pyramids' signed volumes (positive when the face
///    points away from the cell); centre = volume-weighted mean of the pyramid
///    centroids 3/4 face centre + 1/4 estimated centre.
/// Units are those of the points (metres for OpenFOAM). All functions are const and safe
/// to call from many threads at once.
class PolyMesh {
 public:
  /// Validates the topology (labels in range, one owner per face, at most one neighbour,
  /// cells with >= 4 faces, patches in order) and computes the geometry; rejects cells
  /// that are open or have volume <= 0. Throws Error (VFE_ERROR_INVALID_ARGUMENT) with a
  /// message that names the face or cell and the fix.
  explicit PolyMesh(PolyMeshData data);
  /// read_polymesh(dir) then the constructor: dir is an OpenFOAM case folder or its
  /// constant/polyMesh folder. Throws Error as both do.
  static PolyMesh read(const std::filesystem::path& dir);

  std::int64_t cell_count() const { return n_cells_; }
  std::int64_t face_count() const { return static_cast<std::int64_t>(d_.owner.size()); }
  std::int64_t internal_face_count() const { return static_cast<std::int64_t>(d_.neighbour.size()); }
  std::int64_t point_count() const { return static_cast<std::int64_t>(d_.points.size()); }

  const std::vector<Eigen::Vector3d>& points() const { return d_.points; }
  /// Point labels of face f, in order (right-hand normal from owner to neighbour).
  std::span<const std::int64_t> face(std::int64_t f) const {
    const auto b = d_.face_offsets[static_cast<std::size_t>(f)];
    const auto e = d_.face_offsets[static_cast<std::size_t>(f) + 1];
    return {d_.face_points.data() + b, static_cast<std::size_t>(e - b)};
  }
  std::int64_t owner(std::int64_t f) const { return d_.owner[static_cast<std::size_t>(f)]; }
  /// Neighbour cell of face f, or -1 for a boundary face.
  std::int64_t neighbour(std::int64_t f) const {
    return f < internal_face_count() ? d_.neighbour[static_cast<std::size_t>(f)] : -1;
  }
  /// The cell across face f from cell c (-1 on the boundary); c must be f's owner or neighbour.
  std::int64_t across(std::int64_t f, std::int64_t c) const {
    return owner(f) == c ? neighbour(f) : owner(f);
  }
  /// Faces of cell c: those it owns in increasing order, then those it neighbours in
  /// increasing order (OpenFOAM's cells() order).
  std::span<const std::int64_t> cell_faces(std::int64_t c) const {
    const auto b = cell_offsets_[static_cast<std::size_t>(c)];
    const auto e = cell_offsets_[static_cast<std::size_t>(c) + 1];
    return {cell_faces_.data() + b, static_cast<std::size_t>(e - b)};
  }

  /// Position of cell c's first face in the concatenation of all cells' face lists (for
  /// per cell-face data: entry k of cell c is at cell_face_offset(c) + k).
  std::int64_t cell_face_offset(std::int64_t c) const { return cell_offsets_[static_cast<std::size_t>(c)]; }

  const Eigen::Vector3d& face_centre(std::int64_t f) const { return face_centres_[static_cast<std::size_t>(f)]; }
  /// Apex of face f's triangle fan for point location: the face centre, except that a
  /// coordinate shared exactly by all the face's points is set to that value, so that the
  /// triangles of a plane axis-aligned face lie exactly in its plane (differs from the face
  /// centre by rounding only).
  const Eigen::Vector3d& face_apex(std::int64_t f) const { return face_apexes_[static_cast<std::size_t>(f)]; }
  /// Area vector of face f: |A| is the area, A points from the owner to the neighbour.
  const Eigen::Vector3d& face_area(std::int64_t f) const { return face_areas_[static_cast<std::size_t>(f)]; }
  const Eigen::Vector3d& cell_centre(std::int64_t c) const { return cell_centres_[static_cast<std::size_t>(c)]; }
  double cell_volume(std::int64_t c) const { return cell_volumes_[static_cast<std::size_t>(c)]; }
  /// All cell volumes in cell order (> 0).
  std::span<const double> cell_volumes() const { return cell_volumes_; }
  const std::vector<Eigen::Vector3d>& cell_centres() const { return cell_centres_; }
  const std::vector<Eigen::Vector3d>& face_centres() const { return face_centres_; }
  const std::vector<Eigen::Vector3d>& face_areas() const { return face_areas_; }
  /// Sum of the cell volumes.
  double total_volume() const { return total_volume_; }

  /// Bounding box of the mesh points.
  const Eigen::AlignedBox3d& bounds() const { return bounds_; }
  /// Bounding box of cell c's tetrahedra (its points, face centres and centre): a point
  /// outside it is not in the cell.
  const Eigen::AlignedBox3d& cell_bounds(std::int64_t c) const { return cell_bounds_[static_cast<std::size_t>(c)]; }

  const std::vector<PolyPatch>& patches() const { return d_.patches; }
  /// Folder the mesh was read from (empty for meshes built in memory).
  const std::string& source() const { return d_.source; }

  /// Tetrahedra (cell centre, face apex, two consecutive face points) whose orientation
  /// is inverted or flat: 0 on a mesh whose cells are star-shaped from their centres. Where
  /// it is not 0, point location may miss points near the offending faces.
  std::int64_t inverted_tet_count() const { return inverted_tets_; }

  /// Point-location data (see cell_contains in locators.hpp).
  /// Unit normal of face f (owner -> neighbour; zero for a face of zero area).
  const Eigen::Vector3d& face_normal(std::int64_t f) const { return face_normals_[static_cast<std::size_t>(f)]; }
  /// Warp of face f: how far its points and apex lie from the plane (face centre, normal).
  double face_warp(std::int64_t f) const { return face_warps_[static_cast<std::size_t>(f)]; }
  /// How far cell c's tetrahedra reach beyond the plane of its k-th face (outwards from c;
  /// about 0 for a convex cell with plane faces): entry cell_face_offset(c) + k.
  double cell_face_reach(std::int64_t entry) const { return reach_[static_cast<std::size_t>(entry)]; }
  /// Rounding bound of the plane distances above (a few ulps of the mesh's coordinates).
  double location_tolerance() const { return tolerance_; }
  /// The fan triangle (face_apex, P_k, P_k+1) that stands for the whole face f when all
  /// its points and its apex lie exactly in one plane, or -1.
  std::int32_t face_plane_triangle(std::int64_t f) const { return face_plane_[static_cast<std::size_t>(f)]; }
  /// True when cell c (the union of its tetrahedra) is exactly convex with every fan
  /// triangle facing away from its centre: the intersection of their inner half-spaces.
  bool cell_is_convex(std::int64_t c) const { return (cell_flags_[static_cast<std::size_t>(c)] & kConvex) != 0; }
  /// True when cell c's tetrahedra are all positive and its centre lies deeper than the
  /// warp of each face: then a point deeper than every face's warp is inside.
  bool cell_accepts_deep_points(std::int64_t c) const {
    return (cell_flags_[static_cast<std::size_t>(c)] & kDeepAccept) != 0;
  }

 private:
  void validate_topology();
  void compute_geometry();
  void compute_location_data();

  PolyMeshData d_;
  std::int64_t n_cells_ = 0;
  std::vector<std::int64_t> cell_offsets_, cell_faces_;
  std::vector<Eigen::Vector3d> face_centres_, face_apexes_, face_areas_, cell_centres_;
  std::vector<double> cell_volumes_;
  std::vector<Eigen::AlignedBox3d> cell_bounds_;
  Eigen::AlignedBox3d bounds_;
  double total_volume_ = 0;
  std::int64_t inverted_tets_ = 0;
  static constexpr std::uint8_t kConvex = 1, kDeepAccept = 2;
  std::vector<Eigen::Vector3d> face_normals_;
  std::vector<double> face_warps_, reach_;
  double tolerance_ = 0;
  std::vector<std::int32_t> face_plane_;
  std::vector<std::int8_t> face_axis_;
  std::vector<std::uint8_t> cell_flags_;
};

}  // namespace vfe
