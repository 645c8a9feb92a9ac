#include "cartesian_grid.hpp"

#include <limits>
#include <sstream>

namespace vfe {

CartesianGrid::CartesianGrid(const CartesianGridSpec& spec) {
  const char* axis = "xyz";
  for (int d = 0; d < 3; ++d) {
    std::ostringstream msg;
    if (!std::isfinite(spec.origin[d])) {
      msg << "origin[" << d << "] (" << axis[d] << ") is " << spec.origin[d] << "; give a finite coordinate";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    if (!(spec.spacing[d] > 0) || !std::isfinite(spec.spacing[d])) {
      msg << "spacing[" << d << "] (" << axis[d] << ") is " << spec.spacing[d] << "; give a finite cell size > 0";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    if (spec.cells[d] < 1) {
      msg << "cells[" << d << "] (" << axis[d] << ") is " << spec.cells[d] << "; give at least 1 cell per axis";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    o_[d] = spec.origin[d];
    h_[d] = spec.spacing[d];
    inv_h_[d] = 1.0 / spec.spacing[d];
    n_[d] = spec.cells[d];
    if (std::abs(spec.first_cell[d]) > (std::int64_t(1) << 40)) {
      msg << "first_cell[" << d << "] (" << axis[d] << ") is " << spec.first_cell[d]
          << "; give a global cell index within +-2^40";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    first_[d] = spec.first_cell[d];
  }
  // The cell volume, its inverse and the grid's far corner must be ordinary doubles: a
  // spacing such as 1e-200 gives a volume of 0 (void fraction NaN), 5e-324 an inverse of inf.
  const double volume = cell_volume();
  const Eigen::Vector3d far_corner = upper();
  if (!std::isnormal(volume) || !std::isnormal(1.0 / volume) || !inv_h_.allFinite() || !far_corner.allFinite()) {
    std::ostringstream msg;
    msg << "spacing " << h_[0] << " x " << h_[1] << " x " << h_[2] << " gives a cell volume of " << volume
        << " and a far corner of (" << far_corner.transpose() << "), which cannot be computed in doubles (cell volume "
        << "and its inverse must lie within " << std::numeric_limits<double>::min() << " .. "
        << std::numeric_limits<double>::max() << "); give the grid in units where cells are nearer to 1 (e.g. mm or m)";
    throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
  }
  // Cell indices must fit int64 and the field must be allocatable: 2^40 cells is far
  // beyond any machine this runs on and keeps i + nx*(j + ny*k) from overflowing.
  const double total = double(n_[0]) * double(n_[1]) * double(n_[2]);
  if (total > double(std::int64_t(1) << 40)) {
    std::ostringstream msg;
    msg << "grid of " << n_[0] << " x " << n_[1] << " x " << n_[2] << " cells is too large (" << total
        << " cells, limit 2^40); use a coarser grid";
    throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
  }
}

}  // namespace vfe
