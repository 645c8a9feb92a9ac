// Accuracy measures of docs/design.md section 8, shared by tests, apps and reports.
#pragma once

#include <vfe/vfe.h>

#include <cstdint>
#include <span>

namespace vfe {

struct AccuracyMeasures {
  double theta = 0;         ///< mean |eps - eps_exact| over cells either field touches
  double max_error = 0;     ///< max |eps - eps_exact| over those cells
  double l1 = 0;            ///< sum |Vs - Vs_exact| / sum of particle volumes
  double volume_error = 0;  ///< |sum Vs - particle volume| / particle volume
  std::int64_t cells_compared = 0;
};

/// Compares a solid-volume field with the exact one. cell_volume gives V_c per cell;
/// particle_volume is the sum of the particles' volumes (the conservation target).
VFE_API AccuracyMeasures compare_fields(std::span<const double> solid, std::span<const double> solid_exact,
                                        std::span<const double> cell_volume, double particle_volume);

}  // namespace vfe
