// Reader of an OpenFOAM constant/polyMesh: points, faces, owner, neighbour, boundary.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace vfe {

/// One boundary patch of a polyMesh (an entry of its `boundary` file).
struct PolyPatch {
  std::string name;
  std::string type;             ///< e.g. patch, wall, symmetryPlane, empty, cyclic
  std::int64_t start_face = 0;  ///< first face of the patch
  std::int64_t n_faces = 0;     ///< faces start_face .. start_face + n_faces - 1
  std::string neighbour_patch;  ///< partner patch of a cyclic patch, empty otherwise
  /// True for cyclic types (cyclic, cyclicAMI, cyclicACMI, cyclicSlip): its faces are
  /// coupled to the partner patch, but are still mesh boundary faces here.
  bool cyclic = false;
};

/// A polyhedral mesh as OpenFOAM stores it: points, faces as lists of point labels (in
/// order; the right-hand normal points from the owner to the neighbour), one owner per
/// face, one neighbour per internal face (internal faces come first), and the boundary
/// patches that cover the remaining faces in order.
struct PolyMeshData {
  std::vector<Eigen::Vector3d> points;
  /// Face f has the point labels face_points[face_offsets[f] .. face_offsets[f + 1]).
  std::vector<std::int64_t> face_offsets{0};
  std::vector<std::int64_t> face_points;
  std::vector<std::int64_t> owner;      ///< one per face
  std::vector<std::int64_t> neighbour;  ///< one per internal face
  std::vector<PolyPatch> patches;
  std::string source;  ///< folder the mesh was read from (for messages); may be empty

  std::int64_t face_count() const { return static_cast<std::int64_t>(owner.size()); }
};

/// Reads an OpenFOAM polyMesh from `dir`, which is either a case folder (its
/// constant/polyMesh is read) or the polyMesh folder itself. Each of points, faces, owner,
/// neighbour and boundary may be plain or gzip-compressed (name.gz). Reads the ASCII
/// format as blockMesh and snappyHexMesh write it (FoamFile header, C/C++ comments,
/// counted or uncounted lists split over any lines, uniform lists N{value}, faceList and
/// faceCompactList) and the binary format (little-endian, label 32 or 64 bits, scalar 32
/// or 64 bits as the header's arch entry says).
/// Throws Error: VFE_ERROR_IO when a file is missing or unreadable, VFE_ERROR_INVALID_ARGUMENT
/// for bad content (the message names the file, the line and the problem),
/// VFE_ERROR_UNSUPPORTED for big-endian binary files or unknown label/scalar sizes.
/// Checks what can be checked without geometry: counts, labels in range, owner/neighbour
/// sizes, patch ranges, the header's nCells note. Geometry is PolyMesh's job.
/// Limits (README "Limits"): list sizes at most 2^40 and what the file's bytes can hold;
/// point labels in 0..points-1; cell labels in 0..faces-1 (a cell has at least 4 faces,
/// so a larger label is corrupt and label + 1 cannot overflow); patch nFaces and startFace
/// at most the face count; face offsets non-decreasing from 0; a uniform point list at
/// most 65536 points. Past a limit: VFE_ERROR_INVALID_ARGUMENT naming file, entry, limit.
PolyMeshData read_polymesh(const std::filesystem::path& dir);

/// The polyMesh folder that `dir` names: a case folder's constant/polyMesh, a constant
/// folder's polyMesh, or `dir` itself. Throws Error (VFE_ERROR_IO) when dir is no folder.
std::filesystem::path polymesh_folder(const std::filesystem::path& dir);

/// A labelList file of the polyMesh folder `dir` names (as polymesh_folder), plain or
/// name.gz, ASCII or binary: e.g. decomposePar's cellProcAddressing. Labels may be
/// negative (faceProcAddressing's sign marks a flipped face). Throws Error as read_polymesh.
std::vector<std::int64_t> read_label_list_file(const std::filesystem::path& dir, const std::string& name);

}  // namespace vfe
