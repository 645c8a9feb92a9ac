// A C++ host of an installed vfe: find_package(vfe CONFIG) and target vfe::vfe, through the
// C++ facade. This project asks for no C++ standard: vfe::vfe brings C++20 (std::span).
#include <vfe/engine.hpp>

#include <cmath>
#include <cstdio>
#include <vector>

int main() {
  vfe::CartesianGridSpec grid;
  grid.spacing = {1, 1, 1};
  grid.cells = {2, 2, 2};
  const double centre[3] = {1, 1, 1}, radius = 0.5;
  const double eighth = 4.0 / 3.0 * std::acos(-1.0) * radius * radius * radius / 8;
  try {
    vfe::Engine e(grid);
    e.configure("method=exact");
    vfe::ParticleView particles;
    particles.n = 1;
    particles.centres = centre;
    particles.radii = &radius;
    std::vector<double> solid(static_cast<std::size_t>(e.cell_count()));
    e.compute(particles, solid);
    // The sphere at the common corner of the 8 cells puts an eighth of itself in each.
    for (double v : solid)
      if (std::abs(v - eighth) > 1e-12) {
        std::fprintf(stderr, "host_cpp: cell volume %.15g, expected %.15g\n", v, eighth);
        return 1;
      }
    // vfe::Error thrown inside libvfe is caught here as vfe::Error (its type is exported).
    try {
      e.configure("method=no_such_method");
      std::fprintf(stderr, "host_cpp: an unknown method was accepted\n");
      return 1;
    } catch (const vfe::Error& err) {
      if (err.status() != VFE_ERROR_INVALID_ARGUMENT) {
        std::fprintf(stderr, "host_cpp: unknown method gave %s\n", vfe_status_name(err.status()));
        return 1;
      }
    }
  } catch (const std::exception& err) {
    std::fprintf(stderr, "host_cpp: %s\n", err.what());
    return 1;
  }
  std::printf("vfe %s (C++ facade): an eighth of the sphere in each of 8 cells\n", vfe_version());
  return 0;
}
