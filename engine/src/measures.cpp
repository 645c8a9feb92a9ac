#include <vfe/measures.hpp>

#include <vfe/engine.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace vfe {

AccuracyMeasures compare_fields(std::span<const double> solid, std::span<const double> solid_exact,
                                std::span<const double> cell_volume, double particle_volume) {
  if (solid.size() != solid_exact.size() || solid.size() != cell_volume.size())
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "compare_fields: fields have different sizes (" + std::to_string(solid.size()) +
                    ", " + std::to_string(solid_exact.size()) + ", " +
                    std::to_string(cell_volume.size()) + "); pass fields of one mesh");
  AccuracyMeasures m;
  double sum_abs_eps = 0, sum_abs_vs = 0, sum_vs = 0;
  for (std::size_t c = 0; c < solid.size(); ++c) {
    sum_vs += solid[c];
    if (solid[c] == 0.0 && solid_exact[c] == 0.0) continue;
    const double d = std::abs(solid[c] - solid_exact[c]);
    const double deps = d / cell_volume[c];
    sum_abs_vs += d;
    sum_abs_eps += deps;
    m.max_error = std::max(m.max_error, deps);
    ++m.cells_compared;
  }
  if (m.cells_compared > 0) m.theta = sum_abs_eps / static_cast<double>(m.cells_compared);
  if (particle_volume > 0) {
    m.l1 = sum_abs_vs / particle_volume;
    m.volume_error = std::abs(sum_vs - particle_volume) / particle_volume;
  }
  return m;
}

}  // namespace vfe
