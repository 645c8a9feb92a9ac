#include <vfe/kernels/divided.hpp>

#include <cmath>

namespace vfe::kernels {

const std::array<Eigen::Vector3d, 14>& divided_directions() {
  static const std::array<Eigen::Vector3d, 14> dirs = [] {
    std::array<Eigen::Vector3d, 14> d;
    int n = 0;
    for (int axis = 0; axis < 3; ++axis)
      for (double sign : {1.0, -1.0}) {
        Eigen::Vector3d v = Eigen::Vector3d::Zero();
        v[axis] = sign;
        d[n++] = v;
      }
    // Polar angle 45 or 135 degrees: z = +-cos 45; horizontal radius sin 45, split by the
    // azimuth 45 + 90 k degrees into x, y = +-sin 45 cos 45 = +-1/2.
    const double h = 0.5, z = std::sqrt(0.5);
    for (double sz : {1.0, -1.0})
      for (int k = 0; k < 4; ++k) {
        const double sx = (k == 0 || k == 3) ? 1.0 : -1.0;  // azimuth 45, 135, 225, 315
        const double sy = k < 2 ? 1.0 : -1.0;
        d[n++] = Eigen::Vector3d(sx * h, sy * h, sz * z);
      }
    return d;
  }();
  return dirs;
}

ParticleTemplate make_divided_template() {
  ParticleTemplate t;
  t.family = "divided";
  t.points.reserve(kDividedPoints);
  t.points.emplace_back(0, 0, 0);
  for (double shell : {kDividedInnerShell, kDividedOuterShell})
    for (const Eigen::Vector3d& d : divided_directions()) t.points.push_back(shell * d);
  t.fractions.assign(t.points.size(), 1.0 / kDividedPoints);
  t.reach = kDividedOuterShell;
  return t;
}

}  // namespace vfe::kernels
