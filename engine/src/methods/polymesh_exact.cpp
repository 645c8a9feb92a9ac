// exact on an OpenFOAM polyMesh.
#include "methods/polymesh.hpp"

#include <vfe/engine.hpp>

namespace vfe::detail {

void polymesh_exact_particle(const PolyContext&, Scratch&, const Particle&) {
  throw Error(VFE_ERROR_UNSUPPORTED, "method=exact is not available on a polyMesh yet; use pmm or direct");
}

}  // namespace vfe::detail
