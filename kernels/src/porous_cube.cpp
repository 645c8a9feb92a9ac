#include <vfe/kernels/porous_cube.hpp>

#include <algorithm>

namespace vfe::kernels {

double box_box_overlap(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
                       const Eigen::Vector3d& hi2) {
  double v = 1.0;
  for (int d = 0; d < 3; ++d) {
    const double len = std::min(hi1[d], hi2[d]) - std::max(lo1[d], lo2[d]);
    if (!(len > 0)) return 0.0;
    v *= len;
  }
  return v;
}

void interval_axis_weights(double a, double b, const double* nodes, int m, double* w) {
  int holder = 0;
  for (int i = 0; i < m; ++i) {
    const double len = std::min(nodes[i + 1], b) - std::max(nodes[i], a);
    w[i] = len > 0 ? len : 0.0;
    if (nodes[i] <= a) holder = i;
  }
  normalise_weights(w, m, holder);
}

}  // namespace vfe::kernels
