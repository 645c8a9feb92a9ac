#include "particle_grid.hpp"

#include <vfe/kernels/octant_split.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>

namespace vfe::detail {

namespace {
constexpr std::int64_t kLadderLinear = 20;
constexpr double kLadderGrowth = 1.05;
}  // namespace

std::int64_t auto_ladder_value(std::int64_t step) {
  if (step <= kLadderLinear) return step;
  return static_cast<std::int64_t>(std::ceil(kLadderLinear * std::pow(kLadderGrowth, double(step - kLadderLinear)) - 1e-9));
}

std::int64_t auto_step(double diameter, double cell_volume, const AutoRule& rule) {
  const double chi = std::cbrt(cell_volume) / diameter;
  const double cap = double(std::max<std::int64_t>(1, std::min(rule.max_grid, kMaxAutoGrid) / 5));
  const double n_min = std::min(n_min_model(chi, rule.model, rule.criterion), cap);
  const auto k = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(n_min * (1.0 - 1e-12))));
  if (k <= kLadderLinear) return k;
  return kLadderLinear +
         static_cast<std::int64_t>(std::ceil(std::log(double(k) / kLadderLinear) / std::log(kLadderGrowth) - 1e-9));
}

void auto_step_thresholds(double d_min, double d_max, double cell_volume, const AutoRule& rule,
                          std::int64_t first_step, std::int64_t last_step, std::vector<double>& thresholds,
                          std::vector<double>& known) {
  thresholds.clear();
  if (known.size() <= static_cast<std::size_t>(last_step)) known.resize(static_cast<std::size_t>(last_step) + 1, 0.0);
  double lo = d_min;  // auto_step(lo) is below the step sought
  for (std::int64_t step = first_step + 1; step <= last_step; ++step) {
    // A step's threshold is the smallest diameter that reaches it, whatever the bounds of
    // the search (auto_step rises with d): one found for an earlier bank holds.
    if (const double t = known[static_cast<std::size_t>(step)]; t > 0) {
      thresholds.push_back(t);
      lo = t;
      continue;
    }
    if (auto_step(lo, cell_volume, rule) >= step) {  // the step rose by more than one at lo
      thresholds.push_back(lo);
      known[static_cast<std::size_t>(step)] = lo;
      continue;
    }
    double hi = d_max;  // auto_step(hi) reaches it
    // Halving the interval until lo and hi are neighbouring doubles: at most about 64 steps
    // for positive doubles (the midpoint of the bit patterns halves the doubles between).
    while (std::nextafter(lo, hi) < hi) {
      std::uint64_t a, b;
      std::memcpy(&a, &lo, sizeof a);
      std::memcpy(&b, &hi, sizeof b);
      const std::uint64_t m = a + (b - a) / 2;
      double mid;
      std::memcpy(&mid, &m, sizeof mid);
      (auto_step(mid, cell_volume, rule) >= step ? hi : lo) = mid;
    }
    thresholds.push_back(hi);
    known[static_cast<std::size_t>(step)] = hi;
    lo = hi;  // the next step's threshold lies beyond
  }
}

AutoRule TemplateCache::auto_rule(const Options& opts, double cell_size) {
  AutoRule rule;
  rule.max_grid = opts.particle_grid_max;
  rule.model = fitted_jump_model(opts.template_family == TemplateFamily::spherical ? "spherical" : "fibonacci");
  if (opts.superficial_velocity > 0 && opts.fluid_dt > 0)
    rule.criterion = flux_jump_criterion(opts.superficial_velocity, opts.fluid_dt, cell_size);
  return rule;
}

const kernels::ParticleTemplate& TemplateCache::get(const Options& opts, std::int64_t n) {
  auto& slot = cache_[{static_cast<int>(opts.template_family), n}];
  if (!slot) {
    const int ni = static_cast<int>(n);
    switch (opts.template_family) {
      case TemplateFamily::spherical: slot = std::make_unique<kernels::ParticleTemplate>(kernels::make_spherical_template(ni)); break;
      case TemplateFamily::fibonacci: slot = std::make_unique<kernels::ParticleTemplate>(kernels::make_fibonacci_template(ni)); break;
      case TemplateFamily::voxel: slot = std::make_unique<kernels::ParticleTemplate>(kernels::make_voxel_template(ni)); break;
    }
    kernels::prepare_octant_split(*slot);
    if (static_cast<std::int64_t>(slot->size()) >= kPointTreeMinPoints)
      slot->tree = kernels::make_point_tree(slot->points, slot->fractions);
  }
  return *slot;
}

TemplateBank TemplateCache::prepare(const Options& opts, double d_min, double d_max, double v_min, double v_max,
                                    std::int64_t spheres) {
  spheres_served_ += std::max<std::int64_t>(spheres, 0);
  bank_.clear();
  TemplateBank bank;
  if (opts.method != Method::pmm && opts.method != Method::automatic) return bank;
  if (opts.particle_grid > 0) {
    bank_.push_back(&get(opts, opts.particle_grid));
    bank.fixed = true;
  } else if (d_max > 0) {
    // From the largest cell for the smallest particle to the smallest cell for the largest
    // (the flux criterion then uses the smallest cell's size).
    bank.rule = auto_rule(opts, std::cbrt(v_min));
    bank.first_step = auto_step(d_min, v_max, bank.rule);
    const std::int64_t last = auto_step(d_max, v_min, bank.rule);
    for (std::int64_t k = bank.first_step; k <= last; ++k) bank_.push_back(&get(opts, auto_particle_count(k, bank.rule)));
    if (v_min == v_max && last > bank.first_step && d_min > 0) {
      if (v_min != threshold_volume_ || !(bank.rule == threshold_rule_)) {
        step_thresholds_.assign(step_thresholds_.size(), 0.0);  // another rule: none known
        threshold_volume_ = v_min;
        threshold_rule_ = bank.rule;
      }
      auto_step_thresholds(d_min, d_max, v_min, bank.rule, bank.first_step, last, thresholds_, step_thresholds_);
      bank.threshold_cell_volume = v_min;
      bank.thresholds = thresholds_;
    }
  }
  bank.templates = bank_;
  // One template counted with the bank's rotations: its points on their rows, once per engine.
  if (bank_.size() == 1 && bank_.front()->split_words == 1 && opts.orientation == Orientation::random &&
      opts.rotation_bank) {
    // One table at a time: sizes that drift over a run do not pile them up.
    if (projected_ != bank_.front() && spheres_served_ >= kSpheresBeforeProjections) {
      projections_ = kernels::project_on_rotation_bank(*bank_.front());
      projected_ = bank_.front();
    }
    if (projected_ == bank_.front()) bank.projections = &projections_;
  }
  static std::atomic<std::uint64_t> banks{0};  // every bank of every engine: its own id
  bank.id = ++banks;
  return bank;
}

}  // namespace vfe::detail
