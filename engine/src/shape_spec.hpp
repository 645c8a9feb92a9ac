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
/// by position are merged so the mesh's closedness can be checked. Throws vfe::Error.
kernels::TriangleMesh read_triangle_mesh(const std::string& path);

}  // namespace vfe
