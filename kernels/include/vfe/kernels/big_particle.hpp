// CFDEMcoupling's `bigParticle` rule: a particle's volume shared equally by the cells
// whose centres lie within the particle (its own cell takes it all when there is none).
#pragma once

#include <Eigen/Core>

#include <cstdint>

namespace vfe::kernels {

/// Cell centres are the lattice (x[i], y[j], z[k]), i < nx, j < ny, k < nz. Counts the
/// centres with |centre_ijk - centre|^2 <= radius^2 and calls sink(i, j, k, volume / count)
/// for each of them, i fastest. Returns the count; at 0 nothing is deposited and the caller
/// gives the volume to the particle's own cell. The deposits sum to volume (to round-off).
template <class Sink>
inline std::int64_t big_particle_deposit(const Eigen::Vector3d& centre, double radius, double volume,
                                         const double* x, int nx, const double* y, int ny, const double* z,
                                         int nz, Sink&& sink) {
  const double r2 = radius * radius;
  auto inside = [&](int i, int j, int k) {
    const double dx = x[i] - centre[0], dy = y[j] - centre[1], dz = z[k] - centre[2];
    return dx * dx + dy * dy + dz * dz <= r2;
  };
  std::int64_t count = 0;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) count += inside(i, j, k);
  if (count == 0) return 0;
  const double share = volume / double(count);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        if (inside(i, j, k)) sink(i, j, k, share);
  return count;
}

}  // namespace vfe::kernels
