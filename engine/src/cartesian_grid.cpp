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
