#include "engine_mesh.hpp"

#include "methods/rectilinear.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace vfe::detail {

EngineMesh::EngineMesh(const CartesianGridSpec& spec) : kind_(MeshKind::cartesian), cartesian_(spec) {
  cells_ = cartesian_->cell_count();
  v_min_ = v_max_ = cartesian_->cell_volume();
}

EngineMesh::EngineMesh(RectilinearGrid grid) : kind_(MeshKind::rectilinear), rectilinear_(std::move(grid)) {
  cells_ = rectilinear_->cell_count();
  // The extreme cell volumes are products of the extreme spacings per axis.
  double lo = 1, hi = 1;
  for (int d = 0; d < 3; ++d) {
    const auto& x = rectilinear_->nodes(d);
    double a = std::numeric_limits<double>::infinity(), b = 0;
    for (std::size_t i = 1; i < x.size(); ++i) {
      a = std::min(a, x[i] - x[i - 1]);
      b = std::max(b, x[i] - x[i - 1]);
    }
    lo *= a;
    hi *= b;
  }
  v_min_ = lo;
  v_max_ = hi;
}

EngineMesh::EngineMesh(std::unique_ptr<PolyMesh> mesh) : kind_(MeshKind::polyhedral), poly_(std::move(mesh)) {
  // Sub-elements leaving through a cyclic patch would need the coupled patch's transform;
  // without it they would be counted outside the mesh, so refuse rather than lose volume.
  for (const PolyPatch& patch : poly_->patches())
    if (patch.cyclic)
      throw Error(VFE_ERROR_UNSUPPORTED,
                  "polyMesh " + poly_->source() + ": patch '" + patch.name + "' is of type " + patch.type +
                      "; cyclic patches are not supported. Use a mesh without cyclic patches (e.g. change them "
                      "to walls or patches) or, for a box, a rectilinear or Cartesian grid with periodic axes");
  locator_ = std::make_unique<CellLocator>(*poly_);
  lattice_ = find_box_lattice(*poly_);
  cells_ = poly_->cell_count();
  const auto v = poly_->cell_volumes();
  v_min_ = *std::min_element(v.begin(), v.end());
  v_max_ = *std::max_element(v.begin(), v.end());
}

const char* EngineMesh::kind_name() const {
  switch (kind_) {
    case MeshKind::cartesian: return "Cartesian grid";
    case MeshKind::rectilinear: return "rectilinear grid";
    case MeshKind::polyhedral: return "polyMesh";
  }
  return "mesh";
}

double EngineMesh::cell_volume(std::int64_t c) const {
  switch (kind_) {
    case MeshKind::cartesian: return cartesian_->cell_volume();
    case MeshKind::rectilinear: return rectilinear_->cell_volume(c);
    case MeshKind::polyhedral: return poly_->cell_volume(c);
  }
  return 0;
}

Eigen::Vector3d EngineMesh::cell_centre(std::int64_t c) const {
  switch (kind_) {
    case MeshKind::cartesian: {
      const CartesianGrid& g = *cartesian_;
      const auto& n = g.cells();
      const std::int64_t i = c % n[0], j = (c / n[0]) % n[1], k = c / (n[0] * n[1]);
      return {g.centre(0, i), g.centre(1, j), g.centre(2, k)};
    }
    case MeshKind::rectilinear: return rectilinear_->cell_centre(c);
    case MeshKind::polyhedral: return poly_->cell_centre(c);
  }
  return Eigen::Vector3d::Zero();
}

Eigen::AlignedBox3d EngineMesh::bounds() const {
  switch (kind_) {
    case MeshKind::cartesian: return {cartesian_->lower(), cartesian_->upper()};
    case MeshKind::rectilinear: return {rectilinear_->lower(), rectilinear_->upper()};
    case MeshKind::polyhedral: return poly_->bounds();
  }
  return {};
}

void EngineMesh::set_periodic(unsigned mask) {
  if (mask && kind_ == MeshKind::polyhedral)
    throw Error(VFE_ERROR_UNSUPPORTED,
                "periodic axes are available on Cartesian and rectilinear grids only; an OpenFOAM polyMesh's "
                "cyclic patches are not supported (use periodic=none)");
  periodic_ = mask;
  if (cartesian_) cartesian_->set_periodic(mask);
}

Eigen::Vector3d EngineMesh::wrap_periodic(const Eigen::Vector3d& x) const {
  if (rectilinear_) return rectilinear_wrap(*rectilinear_, periodic_, x);
  Eigen::Vector3d c = x;
  const CartesianGrid& g = *cartesian_;
  for (int d = 0; d < 3; ++d) {
    if (!g.periodic(d)) continue;
    const double length = g.spacing()[d] * double(g.cells()[d]);
    const double lo = g.node(d, 0);
    double u = std::fmod(c[d] - lo, length);
    if (u < 0) u += length;
    if (!(u < length)) u = 0;  // fmod of a value just below a multiple of the length
    c[d] = lo + u;
  }
  return c;
}

std::unique_ptr<PolyMesh> EngineMesh::polyhedra() const {
  if (rectilinear_) return std::make_unique<PolyMesh>(rectilinear_->polymesh_data());
  return nullptr;
}

}  // namespace vfe::detail
