#include <vfe/engine.hpp>
#include <vfe/stability.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

namespace vfe {

namespace {

std::uint64_t splitmix(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double uniform01(std::uint64_t& state) { return double(splitmix(state) >> 11) * 0x1.0p-53; }

[[noreturn]] void bad(const std::string& what) { throw Error(VFE_ERROR_INVALID_ARGUMENT, what); }

std::string g6(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

/// One trajectory's straight path and the grid around it.
struct Trajectory {
  double start[3];
  double dir[3];
  double quat[4];  ///< orientation of a shaped particle (w, x, y, z)
  CartesianGridSpec grid;
};

/// Room around a shaped particle's path, in volume-equivalent diameters: the shape must lie
/// within this distance of its origin (checked: the reference then has no outside particle).
constexpr double kShapeMargin = 2.0;

Trajectory make_trajectory(const StabilityOptions& o, std::uint64_t tseed, std::int64_t steps) {
  Trajectory t;
  const double h = o.chi * o.diameter;
  std::uint64_t state = tseed ^ 0xA0761D6478BD642Full;
  for (double& x : t.start) x = h * uniform01(state);
  const double z = 2.0 * uniform01(state) - 1.0;
  const double phi = 2.0 * std::numbers::pi * uniform01(state);
  const double s = std::sqrt(std::max(0.0, 1.0 - z * z));
  t.dir[0] = s * std::cos(phi);
  t.dir[1] = s * std::sin(phi);
  t.dir[2] = z;
  const double length = double(steps) * o.step * o.diameter;
  // A shape's orientation: uniform over the rotations (Shoemake), fixed per trajectory.
  const double u1 = uniform01(state), u2 = uniform01(state), u3 = uniform01(state);
  const double qa = std::sqrt(1.0 - u1), qb = std::sqrt(u1);
  t.quat[0] = qb * std::cos(2.0 * std::numbers::pi * u3);
  t.quat[1] = qa * std::sin(2.0 * std::numbers::pi * u2);
  t.quat[2] = qa * std::cos(2.0 * std::numbers::pi * u2);
  t.quat[3] = qb * std::sin(2.0 * std::numbers::pi * u3);
  const double r = o.shape.empty() ? 0.5 * o.diameter : kShapeMargin * o.diameter;
  for (int d = 0; d < 3; ++d) {
    const double end = t.start[d] + length * t.dir[d];
    const double lo = std::min(t.start[d], end) - r, hi = std::max(t.start[d], end) + r;
    const std::int64_t i0 = static_cast<std::int64_t>(std::floor(lo / h));
    const std::int64_t i1 = static_cast<std::int64_t>(std::floor(hi / h));
    t.grid.origin[d] = double(i0) * h;
    t.grid.spacing[d] = h;
    t.grid.cells[d] = i1 - i0 + 1;
  }
  return t;
}

/// Per trajectory and particle grid.
struct TrajectoryResult {
  std::int64_t grid_min = std::numeric_limits<std::int64_t>::max();
  std::int64_t grid_max = 0;
  double max_jump = 0, max_jump_exact = 0, excess = -std::numeric_limits<double>::infinity();
};

// Constants of the fitted jump model (docs/stability.md: n_min of 3 seeds x 64 trajectories
// at 11 chi from 0.5 to 4, step d/200, re-measured on the current engine). fibonacci:
// a = 0.376 +- 0.017, b = 1.07 +- 0.12 (log rms 0.21); spherical: a = 0.523 +- 0.032,
// b = 0.99 +- 0.20 (log rms 0.42: its rings make n_min erratic). tests/engine/test_fit.cpp
// checks that they still describe the stress test.
constexpr double kSphericalA = 0.523, kSphericalB = 0.99;
constexpr double kFibonacciA = 0.376, kFibonacciB = 1.07;

}  // namespace

std::uint64_t trajectory_seed(std::uint64_t seed, int trajectory) {
  std::uint64_t state = seed * 0xD1B54A32D192ED03ull + std::uint64_t(trajectory);
  splitmix(state);
  return splitmix(state) >> 1;  // the engine's seed option takes values up to 2^63 - 1
}

std::string stability_reference(const StabilityOptions& o) {
  if (o.shape.empty()) return "method=exact";
  // Ask the engine: exact refuses (unsupported) the shapes it has no exact overlap for.
  Engine probe(CartesianGridSpec{});
  std::int32_t id = 0;
  try {
    id = probe.add_shape(o.shape);
  } catch (const Error& e) {
    throw Error(e.status(), std::string("stability: --shape: ") + e.what());
  }
  probe.configure("method=exact orientation=none");
  const double centre[3] = {0.5, 0.5, 0.5}, scale = 1;
  ParticleView one;
  one.n = 1;
  one.centres = centre;
  one.radii = &scale;
  one.shape_ids = &id;
  std::vector<double> field(static_cast<std::size_t>(probe.cell_count()));
  try {
    probe.compute(one, field);
  } catch (const Error& e) {
    if (e.status() != VFE_ERROR_UNSUPPORTED) throw;
    return "method=pmm particle_grid=" + std::to_string(o.reference_grid);
  }
  return "method=exact";
}

StabilityReport stability_test(const StabilityOptions& in) {
  StabilityOptions o = in;
  if (!(o.chi > 0) || !std::isfinite(o.chi)) bad("stability: chi must be > 0 (got " + g6(o.chi) + ")");
  if (!(o.step > 0) || o.step > 1) bad("stability: step must be in (0, 1] diameters (got " + g6(o.step) + ")");
  if (!(o.cells > 0) || o.cells > 1000) bad("stability: cells must be in (0, 1000] (got " + g6(o.cells) + ")");
  if (o.trajectories < 1) bad("stability: trajectories must be >= 1 (got " + std::to_string(o.trajectories) + ")");
  if (!(o.diameter > 0) || !std::isfinite(o.diameter))
    bad("stability: diameter must be > 0 (got " + g6(o.diameter) + ")");
  if (!(o.jump_criterion > 0)) bad("stability: jump criterion must be > 0 (got " + g6(o.jump_criterion) + ")");
  if (o.superficial_velocity < 0 || o.fluid_dt < 0 || ((o.superficial_velocity > 0) != (o.fluid_dt > 0)))
    bad("stability: the flux form needs both a superficial velocity > 0 and a fluid time step > 0");
  if (o.threads < 0) bad("stability: threads must be 0 (all) or a count");
  const bool has_grid = o.method == "pmm";
  if (!has_grid)
    o.particle_grids = {"-"};
  else if (o.particle_grids.empty())
    o.particle_grids = {"auto"};

  const bool shaped = !o.shape.empty();
  if (shaped && o.reference_grid < 1)
    bad("stability: the reference grid must be >= 1 (got " + std::to_string(o.reference_grid) + ")");
  // A shape turns with its trajectory's quaternion, whatever the other options say.
  const std::string base =
      "threads=1 method=" + o.method + " " + o.engine_options + (shaped ? " orientation=given" : "");
  const std::string reference_options =
      "threads=1 " + (shaped ? stability_reference(o) + " orientation=given" : std::string("method=exact"));
  auto grid_option = [&](const std::string& g) { return has_grid ? " particle_grid=" + g : std::string(); };
  double shape_scale = 0;  // scale that gives the shape the volume-equivalent diameter o.diameter
  {
    // Check every option string (and the shape) once, so a typo fails before any work.
    Engine probe(CartesianGridSpec{});
    if (shaped) {
      std::int32_t id = 0;
      try {
        id = probe.add_shape(o.shape);
      } catch (const Error& e) {
        throw Error(e.status(), std::string("stability: --shape: ") + e.what());
      }
      const double eq_unit = std::cbrt(6.0 * probe.shape_volume(id) / std::numbers::pi);
      shape_scale = o.diameter / eq_unit;
      probe.configure(reference_options);
    }
    for (const auto& g : o.particle_grids) {
      try {
        probe.configure(base + " seed=1" + grid_option(g));
      } catch (const Error& e) {
        throw Error(e.status(), std::string("stability: ") + e.what());
      }
    }
  }

  StabilityReport rep;
  const double h = o.chi * o.diameter;
  rep.steps = static_cast<std::int64_t>(std::ceil(o.cells * o.chi / o.step - 1e-9));
  rep.flux_criterion = o.superficial_velocity > 0 ? o.superficial_velocity * o.fluid_dt / h : 0.0;
  const std::size_t ngrids = o.particle_grids.size();
  const std::int64_t steps = rep.steps;

  std::vector<TrajectoryResult> per(std::size_t(o.trajectories) * ngrids);
  auto run_trajectory = [&](int ti) {
    const std::uint64_t tseed = trajectory_seed(o.seed, ti);
    const Trajectory t = make_trajectory(o, tseed, steps);
    Engine reference(t.grid), method(t.grid);
    reference.configure(reference_options);
    const std::size_t ncell = static_cast<std::size_t>(reference.cell_count());
    const double vc = h * h * h;
    const double radius = shaped ? shape_scale : 0.5 * o.diameter;
    const std::int32_t shape_id = 0;
    ParticleView pv;
    pv.n = 1;
    pv.radii = &radius;
    if (shaped) {
      reference.add_shape(o.shape);
      method.add_shape(o.shape);
      pv.shape_ids = &shape_id;
      pv.orientations = t.quat;
    }
    double centre[3];
    pv.centres = centre;
    auto place = [&](std::int64_t k) {
      const double a = double(k) * o.step * o.diameter;
      for (int d = 0; d < 3; ++d) centre[d] = t.start[d] + a * t.dir[d];
    };
    // Reference field (exact, or the shape's fine pmm) of every step (solid volume / cell volume).
    std::vector<double> exact_fields((steps + 1) * ncell);
    for (std::int64_t k = 0; k <= steps; ++k) {
      place(k);
      std::span<double> f(exact_fields.data() + k * ncell, ncell);
      reference.compute(pv, f);
      if (shaped && reference.last_report().outside_particles > 0)
        bad("stability: shape '" + o.shape + "' reaches farther than " + g6(kShapeMargin) +
            " volume-equivalent diameters from its origin; centre it or use a more compact shape");
      for (double& x : f) x /= vc;
    }
    std::vector<double> prev(ncell), cur(ncell);
    const std::string tbase = base + " seed=" + std::to_string(tseed);
    for (std::size_t g = 0; g < ngrids; ++g) {
      method.configure(tbase + grid_option(o.particle_grids[g]));
      TrajectoryResult& r = per[std::size_t(ti) * ngrids + g];
      for (std::int64_t k = 0; k <= steps; ++k) {
        place(k);
        method.compute(pv, cur);
        if (has_grid) {
          r.grid_min = std::min(r.grid_min, method.last_report().particle_grid_min);
          r.grid_max = std::max(r.grid_max, method.last_report().particle_grid_max);
        }
        if (k > 0) {
          const double* e0 = exact_fields.data() + (k - 1) * ncell;
          const double* e1 = e0 + ncell;
          for (std::size_t c = 0; c < ncell; ++c) {
            // deps = -d(Vs)/Vc; only magnitudes matter.
            const double dm = std::abs(cur[c] - prev[c]) / vc;
            const double de = std::abs(e1[c] - e0[c]);
            r.max_jump = std::max(r.max_jump, dm);
            r.max_jump_exact = std::max(r.max_jump_exact, de);
            r.excess = std::max(r.excess, dm - de);
          }
        }
        std::swap(prev, cur);
      }
      if (!has_grid) r.grid_min = r.grid_max = o.method == "direct" ? 1 : 0;  // direct: one point
    }
  };

  tbb::task_arena arena(o.threads > 0 ? o.threads : int(tbb::task_arena::automatic));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, o.trajectories, 1), [&](const tbb::blocked_range<int>& r) {
      for (int ti = r.begin(); ti < r.end(); ++ti) run_trajectory(ti);
    });
  });

  // Reduce in trajectory order (deterministic).
  const double to_psi = rep.flux_criterion > 0 ? 1.0 / rep.flux_criterion : 0.0;
  for (std::size_t g = 0; g < ngrids; ++g) {
    StabilityResult s;
    s.particle_grid = o.particle_grids[g];
    s.grid_min = std::numeric_limits<std::int64_t>::max();
    s.excess_jump = -std::numeric_limits<double>::infinity();
    double sum = 0;
    for (int ti = 0; ti < o.trajectories; ++ti) {
      const TrajectoryResult& r = per[std::size_t(ti) * ngrids + g];
      s.grid_min = std::min(s.grid_min, r.grid_min);
      s.grid_max = std::max(s.grid_max, r.grid_max);
      s.max_jump = std::max(s.max_jump, r.max_jump);
      s.max_jump_exact = std::max(s.max_jump_exact, r.max_jump_exact);
      if (r.excess > s.excess_jump) {
        s.excess_jump = r.excess;
        s.worst_trajectory = ti;
      }
      sum += r.excess;
      if (r.excess > o.jump_criterion) ++s.unstable_trajectories;
    }
    s.mean_excess_jump = sum / o.trajectories;
    s.stable = s.unstable_trajectories == 0;
    if (s.grid_max > 0) s.excess_in_sub_elements = s.excess_jump / sub_element_jump(double(s.grid_max), o.chi);
    if (rep.flux_criterion > 0) {
      s.psi_max = s.max_jump * to_psi;
      s.psi_excess = s.excess_jump * to_psi;
      s.flux_stable = s.excess_jump <= rep.flux_criterion;
    }
    rep.results.push_back(std::move(s));
  }
  rep.options = o;
  rep.reference = shaped ? stability_reference(o) : "method=exact";
  return rep;
}

JumpModel fitted_jump_model(std::string_view family) {
  // Fits of docs/stability.md (3 seeds x 64 trajectories, chi 0.5 to 4).
  if (family == "spherical") return {kSphericalA, kSphericalB};
  if (family == "fibonacci") return {kFibonacciA, kFibonacciB};
  throw Error(VFE_ERROR_INVALID_ARGUMENT,
              "no fitted stability model for template '" + std::string(family) + "'; known: spherical, fibonacci");
}

double n_min_model(double chi, const JumpModel& m, double crit) {
  if (!(chi > 0) || !(crit > 0)) bad("n_min_model: chi and the criterion must be > 0");
  const double c = std::numbers::pi / (6.0 * crit);
  const double c3 = chi * chi * chi;
  const double x = (c * m.a + std::sqrt(c * c * m.a * m.a + 4.0 * c * m.b * c3)) / (2.0 * c3);
  return std::max(1.0, x * x);
}

std::int64_t auto_particle_grid(double chi, std::string_view family, double crit) {
  const double n = std::ceil(n_min_model(chi, fitted_jump_model(family), crit) * (1.0 - 1e-12));
  return 5 * static_cast<std::int64_t>(std::min(n, 1e9));
}

}  // namespace vfe
