// The methods and the meshes they run on: one row per method. A new method is its kernel
// (kernels/), its driver functions (methods/<method>.cpp) and one row here (plus its name
// in options.cpp's table).
#pragma once

#include "methods/driver.hpp"
#include "methods/polymesh.hpp"
#include "methods/rectilinear.hpp"

namespace vfe::detail {

template <class MeshContext>
using DriverFn = void (*)(const MeshContext&, Scratch&, const Particle&);

struct MethodDrivers {
  Method method;
  DriverFn<Context> cartesian;              ///< null: not on Cartesian grids
  DriverFn<RectilinearContext> rectilinear; ///< null: not on rectilinear grids
  DriverFn<PolyContext> polyhedral;         ///< null: not on polyhedral meshes
  bool shapes;                              ///< takes non-spherical particles
  const char* instead;                      ///< what to use where a driver is missing
};

/// The row of a method.
const MethodDrivers& method_drivers(Method m);

}  // namespace vfe::detail
