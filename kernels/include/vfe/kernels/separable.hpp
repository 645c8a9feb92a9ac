// Separable spreading: a particle's volume shared over a box of cells by a product of
// per-axis weights (the gaussian, porous cube and trilinear kernels).
#pragma once

namespace vfe::kernels {

/// Cell (i, j, k) of an nx x ny x nz patch gets volume * wx[i] * wy[j] * wz[k];
/// sink(i, j, k, v) is called for every positive product, i fastest. When the weights of
/// each axis sum to 1 the deposits sum to volume (to round-off).
template <class Sink>
inline void separable_deposit(const double* wx, int nx, const double* wy, int ny, const double* wz, int nz,
                              double volume, Sink&& sink) {
  for (int k = 0; k < nz; ++k) {
    if (wz[k] <= 0.0) continue;
    const double vk = volume * wz[k];
    for (int j = 0; j < ny; ++j) {
      if (wy[j] <= 0.0) continue;
      const double vjk = vk * wy[j];
      for (int i = 0; i < nx; ++i)
        if (wx[i] > 0.0) sink(i, j, k, vjk * wx[i]);
    }
  }
}

/// Divides w[0..m) by its sum so it sums to 1; a zero sum gives all weight to w[fallback].
inline void normalise_weights(double* w, int m, int fallback) {
  double sum = 0;
  for (int i = 0; i < m; ++i) sum += w[i];
  if (!(sum > 0)) {
    for (int i = 0; i < m; ++i) w[i] = 0.0;
    w[fallback] = 1.0;
    return;
  }
  const double inv = 1.0 / sum;
  for (int i = 0; i < m; ++i) w[i] *= inv;
}

}  // namespace vfe::kernels
