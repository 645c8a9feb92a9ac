// Trilinear (cloud-in-cell) deposit: a particle's volume shared between the 8 cells whose
// centres surround its centre, by the trilinear interpolation weights.
#pragma once

#include <cmath>
#include <cstdint>

namespace vfe::kernels {

/// One axis of the cloud-in-cell weights. u is the centre in cell units (cell i spans
/// [i, i+1], its centre is i + 1/2); the volume goes to cells `first` (weight 1 - f) and
/// first + 1 (weight f), f = u - 1/2 - first in [0, 1).
struct TrilinearAxis {
  std::int64_t first;
  double w0, w1;
};

inline TrilinearAxis trilinear_axis(double u) {
  const double t = u - 0.5;
  const double f0 = std::floor(t);
  const double f = t - f0;
  return {static_cast<std::int64_t>(f0), 1.0 - f, f};
}

}  // namespace vfe::kernels
