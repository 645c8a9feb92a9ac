// Conservative smoothing of the solid volume over the mesh's face graph (implicit diffusion,
// as CFDEM's constDiffSmoothing and MFiX's diffusion filter): for cells smaller than about
// three particle diameters, where any deposit is spiky.
#pragma once

#include "engine_mesh.hpp"

#include <cstdint>
#include <vector>

namespace vfe::detail {

/// The faces between neighbouring cells with their conductance A_f / d_f (face area over
/// the distance between the two cell centres), built once per mesh.
struct FaceGraph {
  std::vector<std::int64_t> a, b;
  std::vector<double> k;
};
FaceGraph face_graph(const EngineMesh& mesh);

/// Smoothing of solid (per cell) with length L: the solid fraction x solves
/// (V + L^2 K) x = solid, K the face graph's Laplacian (one implicit diffusion step of
/// time L^2), by Jacobi-preconditioned conjugate gradients to a relative residual of 1e-12;
/// out = solid - L^2 K x, which conserves the sum to round-off whatever the solver's
/// residual, and is V x to that residual. Returns the iterations taken.
int smooth_solid(const FaceGraph& graph, const EngineMesh& mesh, double length, const std::vector<double>& solid,
                 std::vector<double>& out);

}  // namespace vfe::detail
