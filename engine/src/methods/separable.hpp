// Drivers of the separable spreading methods (gaussian, porous_cube, trilinear): per-axis
// weights over a window of cells, their product into the window, then the window's
// deposits through the outside policy.
#pragma once

#include "methods/driver.hpp"

#include <vfe/kernels/separable.hpp>

namespace vfe::detail {

/// s.axis[d] holds the weights of the window's cells along axis d (sizes w.m[d]); deposits
/// volume times their product.
inline void deposit_separable(const Context& ctx, Scratch& s, const Particle& p, const Window& w) {
  s.window.assign(w.size(), 0.0);
  const int m0 = static_cast<int>(w.m[0]), m1 = static_cast<int>(w.m[1]), m2 = static_cast<int>(w.m[2]);
  kernels::separable_deposit(s.axis[0].data(), m0, s.axis[1].data(), m1, s.axis[2].data(), m2, p.volume,
                             [&s, m0, m1](int i, int j, int k, double v) {
                               s.window[static_cast<std::size_t>(i + m0 * (j + m1 * k))] = v;
                             });
  emit_window(ctx, s, p, w, ctx.opts.outside);
}

}  // namespace vfe::detail
