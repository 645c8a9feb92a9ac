#include <vfe/kernels/gaussian.hpp>

#include <algorithm>
#include <cmath>

namespace vfe::kernels {

void gaussian_axis_weights(double centre, double sigma, const double* nodes, int m, double* w) {
  const double a = centre - kGaussianCut * sigma, b = centre + kGaussianCut * sigma;
  const double scale = 1.0 / (std::sqrt(2.0) * sigma);
  // The mass of [lo, hi] is (erf(hi') - erf(lo')) / 2 with x' = (x - centre) / (sqrt 2 sigma);
  // the factor 1/2 goes with the normalisation. One erf per node, clipped to the cut.
  int holder = 0;
  double below = std::erf((std::clamp(nodes[0], a, b) - centre) * scale);
  for (int i = 0; i < m; ++i) {
    const double above = std::erf((std::clamp(nodes[i + 1], a, b) - centre) * scale);
    w[i] = std::max(above - below, 0.0);
    below = above;
    if (nodes[i] <= centre) holder = i;
  }
  normalise_weights(w, m, holder);
}

}  // namespace vfe::kernels
