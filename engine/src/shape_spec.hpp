// Shape specs of vfe_add_shape ("sphere", "ellipsoid A B C", ...) and triangle-mesh files.
#pragma once

#include <vfe/kernels/shape.hpp>

#include <string>
#include <string_view>

namespace vfe {

/// Parses a shape spec: "sphere" | "ellipsoid A B C" | "superquadric A B C E1 E2" |
/// "clump x y z r; x y z r; ..." | "mesh FILE" (STL, ASCII or binary, or OBJ). Throws
/// vfe::Error (invalid argument for a bad spec or mesh, I/O error for an unreadable file).
kernels::Shape parse_shape_spec(std::string_view spec);

/// Reads a closed triangle mesh from an STL (ASCII or binary) or OBJ file; vertices shared
/// by position are merged so the mesh's closedness can be checked. Throws vfe::Error:
/// VFE_ERROR_IO for a missing or unreadable file or a folder, VFE_ERROR_INVALID_ARGUMENT
/// (file:line) for bad content. Every number is parsed whole (an OBJ index "1x", "2.9" or
/// "4294967300" is an error, and must name one of the vertices read so far); at most
/// kernels::kMaxMeshTriangles (2^22) triangles and 3x that many OBJ vertices; an ASCII STL
/// that ends inside a facet is truncated.
kernels::TriangleMesh read_triangle_mesh(const std::string& path);

}  // namespace vfe
