#include "methods/registry.hpp"

#include "methods/hybrid.hpp"
#include "methods/shape_exact.hpp"

namespace vfe::detail {

namespace {

const MethodDrivers kMethods[] = {
    {Method::direct, direct_particle, rectilinear_direct, polymesh_direct, true, ""},
    {Method::pmm, pmm_particle, rectilinear_pmm, polymesh_pmm, true, ""},
    // Spheres by their closed forms; ellipsoids and triangle meshes by their exact overlaps
    // (methods/shape_exact.cpp); prepare_shapes refuses the other shapes (exact_shape_refusal).
    {Method::exact, exact_any_particle, rectilinear_exact_any, polymesh_exact_any, true, ""},
    {Method::divided, divided_particle, rectilinear_divided, polymesh_divided, false, ""},
    {Method::gaussian, gaussian_particle, rectilinear_gaussian, polymesh_gaussian, false, ""},
    {Method::porous_cube, porous_cube_particle, rectilinear_porous_cube, polymesh_porous_cube, false, ""},
    {Method::big_particle, big_particle_particle, rectilinear_big_particle, polymesh_big_particle, false, ""},
    // Cloud-in-cell needs the 8 cells whose centres surround a point: a structured stencil
    // an unstructured mesh does not have.
    {Method::trilinear, trilinear_particle, rectilinear_trilinear, nullptr, false,
     "trilinear (cloud-in-cell) needs a structured grid's stencil of 8 cell centres; on a polyhedral mesh use "
     "pmm, exact, divided or big_particle"},
    // Per sphere the cheaper of pmm and exact; shapes take pmm.
    {Method::automatic, auto_particle, rectilinear_auto, polymesh_auto, true, ""},
};

}  // namespace

const MethodDrivers& method_drivers(Method m) {
  for (const MethodDrivers& row : kMethods)
    if (row.method == m) return row;
  return kMethods[0];
}

}  // namespace vfe::detail
