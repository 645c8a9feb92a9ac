// PMM's templates for a compute: the particle_grid=auto rule (sub-elements from the
// stability stress test's fitted jump model), the cache of built templates, and the bank
// of sizes one compute uses.
#pragma once

#include "options.hpp"

#include <vfe/kernels/octant_split.hpp>
#include <vfe/kernels/particle_template.hpp>
#include <vfe/stability.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <vector>

namespace vfe::detail {

/// particle_grid=auto: n = 5 * n_min(chi) with n_min from the stress test's fitted jump
/// model (docs/stability.md) under a jump criterion (the default of docs/design.md section 8, or the flux form).
struct AutoRule {
  JumpModel model;
  double criterion = kDefaultJumpCriterion;
  std::int64_t max_grid = 20000;  ///< particle_grid_max
  bool operator==(const AutoRule& o) const {
    return model.a == o.model.a && model.b == o.model.b && criterion == o.criterion && max_grid == o.max_grid;
  }
};

/// Largest particle grid `auto` may choose.
inline constexpr std::int64_t kMaxAutoGrid = 5 * 27 * 1000;

/// Auto step of a particle: the template ladder's index of ceil(n_min(chi)), where the
/// ladder is 1, 2, ..., 20 and then grows by 5 % a rung (so a polydisperse bed needs few
/// templates). particle_grid = 5 * auto_ladder_value(step).
std::int64_t auto_step(double diameter, double cell_volume, const AutoRule& rule);
std::int64_t auto_ladder_value(std::int64_t step);
/// Sub-elements auto uses at a step: 5 * auto_ladder_value(step), at most rule.max_grid.
inline std::int64_t auto_particle_count(std::int64_t step, const AutoRule& rule) {
  return std::min(5 * auto_ladder_value(step), std::max<std::int64_t>(rule.max_grid, 1));
}

/// The last two templates one thread's bank gave, with their spheres' diameters and cells'
/// volumes (TemplateBank::template_for): polydisperse particles come in few sizes, and the
/// auto rule costs a cube root and a square root per sphere.
struct TemplateMemo {
  std::uint64_t bank = 0;  ///< TemplateBank::id of the entries (0: none)
  double diameter[2] = {0, 0}, cell_volume[2] = {0, 0};
  const kernels::ParticleTemplate* templates[2] = {nullptr, nullptr};
  unsigned next = 0;  ///< the entry to replace
};

/// PMM's templates for this compute: one fixed size, or one per auto step.
struct TemplateBank {
  std::span<const kernels::ParticleTemplate* const> templates;
  std::int64_t first_step = 0;  ///< auto step of templates[0]
  bool fixed = false;           ///< particle_grid given: templates[0] for every particle
  AutoRule rule;
  std::uint64_t id = 0;         ///< unique per bank prepared (TemplateMemo's key)
  /// The one template's projections on the rotation bank, where pmm counts with them
  /// (orientation=random from the bank, at most 64 points); else null.
  const kernels::BankProjections* projections = nullptr;
  /// Where every cell has one volume (a Cartesian grid) and the bank several templates:
  /// that volume, and the diameters at which the auto step rises, templates[k] taking the
  /// diameters from thresholds[k - 1] on. A sphere then finds its template by comparisons
  /// instead of a cube root and a square root (polydisperse spheres rarely repeat a size).
  double threshold_cell_volume = 0;
  std::span<const double> thresholds;

  /// With thresholds: the index in templates of a sphere of this diameter (in a cell of
  /// threshold_cell_volume), the thresholds it reaches. Compared with each, independently: a
  /// binary search's chain of loads cost method=auto more (docs/performance.md).
  std::size_t threshold_index(double diameter) const {
    std::size_t k = 0;
    for (const double t : thresholds) k += diameter >= t;
    return k;
  }

  /// The template of a sphere of this diameter in a cell of this volume.
  const kernels::ParticleTemplate& template_for(double diameter, double cell_volume) const {
    if (templates.size() == 1) return *templates.front();
    if (cell_volume == threshold_cell_volume && !thresholds.empty()) return *templates[threshold_index(diameter)];
    const std::int64_t k = auto_step(diameter, cell_volume, rule) - first_step;
    const auto last = static_cast<std::int64_t>(templates.size()) - 1;
    return *templates[static_cast<std::size_t>(k < 0 ? 0 : (k > last ? last : k))];
  }
  /// The same, remembered in the calling thread's memo for the next sphere of the same
  /// size in a cell of the same volume.
  const kernels::ParticleTemplate& template_for(double diameter, double cell_volume, TemplateMemo& memo) const {
    if (templates.size() == 1) return *templates.front();
    if (memo.bank != id) {
      memo = TemplateMemo{};
      memo.bank = id;
    }
    for (int i = 0; i < 2; ++i)
      if (memo.templates[i] && memo.diameter[i] == diameter && memo.cell_volume[i] == cell_volume)
        return *memo.templates[i];
    const kernels::ParticleTemplate& t = template_for(diameter, cell_volume);
    const unsigned i = memo.next;
    memo.next ^= 1;
    memo.diameter[i] = diameter;
    memo.cell_volume[i] = cell_volume;
    memo.templates[i] = &t;
    return t;
  }
};

/// The sphere templates an engine has built (each built once, kept for later computes) and
/// the bank of the current compute.
class TemplateCache {
 public:
  /// The auto rule of the options: the template family's fitted jump model, under the flux
  /// criterion when the host gave U_s and dt_f (for cells of size cell_size), else the default.
  static AutoRule auto_rule(const Options& opts, double cell_size);

  /// The template of n sub-elements of the options' family (built on first use).
  const kernels::ParticleTemplate& get(const Options& opts, std::int64_t n);

  /// Prepares the bank for spheres of diameters [d_min, d_max] in cells of volumes
  /// [v_min, v_max] (nothing unless method=pmm or auto), for a compute of `spheres` spheres.
  /// Returns the bank; valid until the next call.
  TemplateBank prepare(const Options& opts, double d_min, double d_max, double v_min, double v_max,
                       std::int64_t spheres = 0);

  /// A bank's one template gets its projections once the cache has served this many spheres
  /// (counting the compute's own): building them takes about 0.5 ms, and saves about 1 ns per
  /// counted sphere (docs/performance.md), so a small one-off compute does not pay for them.
  static constexpr std::int64_t kSpheresBeforeProjections = 1000000;

  /// Templates of at least this many points get their tree of balls (kernels::PointTree):
  /// a polyMesh then locates a ball that one cell holds at once instead of point by point.
  static constexpr std::int64_t kPointTreeMinPoints = 64;

 private:
  std::map<std::pair<int, std::int64_t>, std::unique_ptr<kernels::ParticleTemplate>> cache_;
  const kernels::ParticleTemplate* projected_ = nullptr;  ///< the template projections_ holds
  kernels::BankProjections projections_;                  ///< its projections (2 to 3 MB)
  std::int64_t spheres_served_ = 0;  ///< spheres of every compute prepared so far
  std::vector<const kernels::ParticleTemplate*> bank_;
  std::vector<double> thresholds_;  ///< the bank's TemplateBank::thresholds
  /// Each auto step's threshold diameter (index: step) for cells of threshold_volume_ under
  /// threshold_rule_, found once: a bisection costs about 60 auto steps, which a compute of a
  /// few thousand spheres would feel every time.
  double threshold_volume_ = 0;
  AutoRule threshold_rule_;
  std::vector<double> step_thresholds_;
};

/// The diameters in (d_min, d_max] at which auto_step(d, cell_volume, rule) rises from
/// first_step to first_step + 1, + 2, ..., last_step: each the smallest double at which the
/// step reaches its value, found by bisection on auto_step itself (which rises with d).
/// Into thresholds, whose memory is kept: a steady run of computes allocates nothing.
/// Entries of known (index: step, from first_step + 1; 0: not known yet) are taken as found.
void auto_step_thresholds(double d_min, double d_max, double cell_volume, const AutoRule& rule,
                          std::int64_t first_step, std::int64_t last_step, std::vector<double>& thresholds,
                          std::vector<double>& known);

}  // namespace vfe::detail
