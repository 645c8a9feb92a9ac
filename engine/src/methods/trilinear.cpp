// trilinear: cloud-in-cell; the particle volume shared between the 8 cells whose centres
// surround its centre by the trilinear weights (kernels/trilinear.hpp). Shares that fall
// on cells beyond the mesh follow the outside policy.
#include "methods/separable.hpp"

#include <vfe/kernels/trilinear.hpp>

#include <algorithm>

namespace vfe::detail {

void trilinear_particle(const Context& ctx, Scratch& s, const Particle& p) {
  const CartesianGrid& grid = ctx.grid;
  Window w;
  kernels::TrilinearAxis axis[3];
  for (int d = 0; d < 3; ++d) {
    const double u = grid.axis_coordinate(d, p.centre[d]);
    const double bound = 0x1p60;  // far beyond any mesh: still representable
    axis[d] = kernels::trilinear_axis(std::clamp(u, -bound, bound));
    const std::int64_t n = grid.cells()[d];
    const std::int64_t local = axis[d].first - grid.first(d);  // axis_coordinate is global
    const std::int64_t a = std::clamp<std::int64_t>(local, -1, n);
    const std::int64_t b = std::clamp<std::int64_t>(local + 1, -1, n);
    w.lo[d] = a;
    w.m[d] = b - a + 1;
    s.axis[d].assign(static_cast<std::size_t>(w.m[d]), 0.0);
    s.axis[d][0] += axis[d].w0;
    s.axis[d][static_cast<std::size_t>(b - a)] += axis[d].w1;
  }
  s.sub_elements += 8;
  deposit_separable(ctx, s, p, w);
}

}  // namespace vfe::detail
