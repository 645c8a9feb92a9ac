// The engine facade: validation, the per-method drivers (methods/), scheduling over particle
// blocks in the engine's own TBB arena, and accumulation into the field.
#include <vfe/engine.hpp>

#include "cartesian_grid.hpp"
#include "methods/driver.hpp"
#include "options.hpp"
#include "shape_spec.hpp"
#include "methods/polymesh.hpp"
#include "methods/rectilinear.hpp"
#include "polymesh/rectilinear_grid.hpp"

#include <vfe/kernels/divided.hpp>
#include <vfe/kernels/particle_template.hpp>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <sstream>

namespace vfe {

namespace {

using detail::Deposit;
using detail::Scratch;
using kernels::ParticleTemplate;

/// Particles per block of the deterministic (sorted) accumulation: fixed, so the
/// summation order never depends on the thread count.
constexpr std::int64_t kSortedBlock = 512;

double sphere_volume(double r) { return 4.0 / 3.0 * std::numbers::pi * r * r * r; }

struct Validation {
  std::int64_t first_bad = std::numeric_limits<std::int64_t>::max();
  double volume = 0;
  double d_min = std::numeric_limits<double>::infinity(), d_max = 0;
};

}  // namespace

struct Engine::Impl {
  CartesianGrid grid;
  Options opts;
  std::unique_ptr<tbb::task_arena> arena;
  std::shared_ptr<spdlog::logger> log;

  std::vector<double> solid;     // last successful field
  std::vector<double> work;      // field being computed (+1 slot: dropped volume)
  Report report{};
  bool have_field = false;

  tbb::enumerable_thread_specific<Scratch> scratch;
  /// Per-thread field (cell_count + 1 values, zero between computes) and, for
  /// touched_only=1, the cells it holds volume in.
  struct PrivateField {
    std::vector<double> field;
    std::vector<std::int64_t> touched;
  };
  tbb::enumerable_thread_specific<PrivateField> private_fields;
  std::vector<std::int64_t> touched;  ///< touched_only: the cells of `solid` that may be non-zero
  bool touched_valid = false;         ///< false: any cell of `solid` may be non-zero

  /// incremental=1: what each particle looked like at its last deposit and its deposits,
  /// by blocks of kSortedBlock particles (deposits of particle i of a block:
  /// deposits[offsets[i] .. offsets[i + 1])).
  struct DepositBlock {
    std::vector<Deposit> deposits;
    std::vector<std::uint32_t> offsets;
    std::vector<std::uint32_t> moved;  ///< particles of the block redone by this compute
  };
  struct IncrementalState {
    bool valid = false;  ///< false after configure, add_shape or a change of layout
    std::int64_t n = 0;
    bool with_shapes = false, with_orientations = false;
    std::vector<double> particles;  ///< x, y, z, r (then w, x, y, z with orientations)
    std::vector<std::int32_t> shape_ids;
    std::vector<DepositBlock> blocks, next;
    double dropped = 0;
  } inc;
  std::int64_t moved_particles = 0;  ///< of the last compute (all of them unless incremental)
  std::vector<std::vector<Deposit>> blocks;       // sorted accumulation
  std::vector<std::pair<std::int64_t, std::int64_t>> sort_keys;  // (cell, sequence)
  std::vector<double> sort_values;
  std::vector<std::int64_t> sort_offsets;  // start of each block's deposits

  std::map<std::pair<int, std::int64_t>, std::unique_ptr<ParticleTemplate>> template_cache;
  const ParticleTemplate divided = kernels::make_divided_template();
  std::vector<const ParticleTemplate*> bank;  // by (auto step - bank_first)
  std::int64_t bank_first = 0;
  detail::AutoRule rule;

  /// A shape registered with add_shape, and its templates for the current compute.
  struct RegisteredShape {
    kernels::Shape shape;
    bool is_sphere = false;
    double eq_diameter = 0;  ///< diameter of the sphere of equal volume, at scale 1
    const ParticleTemplate* tmpl = nullptr;  ///< pmm's template for this compute
    double scale_min = 0, scale_max = 0;
    std::vector<Eigen::Vector3d> samples;  ///< taken once, cut anew for each template size
  };
  std::vector<RegisteredShape> shapes;
  std::map<std::pair<std::int32_t, std::int64_t>, std::unique_ptr<ParticleTemplate>> shape_templates;

  const ParticleTemplate& shape_template(std::int32_t id, std::int64_t n) {
    auto& slot = shape_templates[{id, n}];
    if (!slot) {
      RegisteredShape& sh = shapes[id];
      const bool analytic = sh.shape.kind() == kernels::Shape::Kind::ellipsoid;
      if (!analytic && sh.samples.empty()) sh.samples = kernels::sample_shape(sh.shape, 1000000).points;
      slot = std::make_unique<ParticleTemplate>(analytic ? kernels::make_shape_template(sh.shape, static_cast<int>(n))
                                                         : kernels::make_shape_template(sh.shape, static_cast<int>(n), sh.samples));
      log->info("built template of {} sub-elements for shape {} ({})", slot->size(), id, shapes[id].shape.description());
    }
    return *slot;
  }

  /// Templates of the non-spherical shapes this compute uses; rejects methods that
  /// cannot represent a shape.
  void prepare_shapes(const ParticleView& pv, std::int64_t rs) {
    if (!pv.shape_ids) return;
    for (auto& sh : shapes) sh.scale_min = sh.scale_max = 0;
    for (std::int64_t p = 0; p < pv.n; ++p) {
      RegisteredShape& sh = shapes[pv.shape_ids[p]];
      const double scale = pv.radii[p * rs];
      sh.scale_min = sh.scale_max == 0 ? scale : std::min(sh.scale_min, scale);
      sh.scale_max = std::max(sh.scale_max, scale);
    }
    const detail::AutoRule shape_rule = auto_rule(std::cbrt(smallest_cell_volume()));
    for (std::int32_t id = 0; id < static_cast<std::int32_t>(shapes.size()); ++id) {
      RegisteredShape& sh = shapes[id];
      sh.tmpl = nullptr;
      if (sh.is_sphere || sh.scale_max == 0) continue;
      if (opts.method != Method::pmm && opts.method != Method::direct)
        throw Error(VFE_ERROR_UNSUPPORTED,
                    "method=" + std::string(to_string(opts.method)) + " handles spheres only, but shape " +
                        std::to_string(id) + " is a " + sh.shape.description() +
                        "; use method=pmm (a large particle_grid serves as the reference) or direct");
      if (opts.method == Method::direct) continue;
      if (opts.particle_grid > 0) {
        sh.tmpl = &shape_template(id, opts.particle_grid);
        continue;
      }
      // One template per shape, sized for its largest particles (the smallest chi, the
      // most sub-elements): shape templates are costly to cut, so none per size step.
      const std::int64_t k = detail::auto_step(sh.eq_diameter * sh.scale_max, smallest_cell_volume(), shape_rule);
      sh.tmpl = &shape_template(id, detail::auto_particle_count(k, shape_rule));
    }
  }


  // --- the mesh: a Cartesian grid, or a polyMesh with its locator -------------------
  std::unique_ptr<PolyMesh> poly;
  std::unique_ptr<CellLocator> locator;
  /// A rectilinear grid (then `poly` holds the same cells for topology, volumes and
  /// writers, while the rectilinear drivers compute): its axes may be periodic.
  std::unique_ptr<RectilinearGrid> rect;
  double poly_vmin = 0, poly_vmax = 0;  // smallest and largest cell volume

  explicit Impl(const CartesianGridSpec& spec) : grid(spec) { init(); }

  /// polyMesh engine; `grid` is then only the bounding box (never used to locate).
  explicit Impl(std::unique_ptr<PolyMesh> mesh) : grid(bounding_grid(*mesh)), poly(std::move(mesh)) {
    locator = std::make_unique<CellLocator>(*poly);
    const auto v = poly->cell_volumes();
    poly_vmin = *std::min_element(v.begin(), v.end());
    poly_vmax = *std::max_element(v.begin(), v.end());
    init();
  }

  static CartesianGridSpec bounding_grid(const PolyMesh& mesh) {
    CartesianGridSpec g;
    for (int d = 0; d < 3; ++d) {
      g.origin[d] = mesh.bounds().min()[d];
      g.spacing[d] = std::max(mesh.bounds().sizes()[d], 1e-300);
    }
    return g;
  }

  void init() {
    log = std::make_shared<spdlog::logger>("vfe", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    log->set_level(spdlog::level::warn);
    make_arena();
    solid.reserve(ncells() + 1);
    work.reserve(ncells() + 1);
    solid.assign(ncells(), 0.0);
  }

  std::int64_t ncells() const { return poly ? poly->cell_count() : grid.cell_count(); }
  double cell_volume(std::int64_t c) const { return poly ? poly->cell_volume(c) : grid.cell_volume(); }
  /// The smallest cell volume: the most sub-elements auto may need.
  double smallest_cell_volume() const { return poly ? poly_vmin : grid.cell_volume(); }

  void make_arena() {
    arena = std::make_unique<tbb::task_arena>(opts.threads > 0 ? opts.threads : +tbb::task_arena::automatic);
  }

  // --- particle grid ------------------------------------------------------------------

  /// The auto rule of the current options: the template family's fitted jump model, under
  /// the flux criterion when the host gave U_s and dt_f, else DESIGN's default criterion.
  detail::AutoRule auto_rule(double cell_size) const {
    detail::AutoRule rule;
    rule.max_grid = opts.particle_grid_max;
    rule.model = fitted_jump_model(opts.template_family == TemplateFamily::spherical ? "spherical" : "fibonacci");
    if (opts.superficial_velocity > 0 && opts.fluid_dt > 0)
      rule.criterion = flux_jump_criterion(opts.superficial_velocity, opts.fluid_dt, cell_size);
    return rule;
  }

  const ParticleTemplate& get_template(std::int64_t n) {
    const int family = static_cast<int>(opts.template_family);
    auto& slot = template_cache[{family, n}];
    if (!slot) {
      const int ni = static_cast<int>(n);
      ParticleTemplate t;
      switch (opts.template_family) {
        case TemplateFamily::spherical: t = kernels::make_spherical_template(ni); break;
        case TemplateFamily::fibonacci: t = kernels::make_fibonacci_template(ni); break;
        case TemplateFamily::voxel: t = kernels::make_voxel_template(ni); break;
      }
      slot = std::make_unique<ParticleTemplate>(std::move(t));
      log->debug("built {} template for particle_grid={}: {} sub-elements", slot->family, n, slot->size());
    }
    return *slot;
  }

  void prepare_templates(const Validation& v) {
    bank.clear();
    bank_first = 0;
    if (opts.method != Method::pmm) return;
    if (opts.particle_grid > 0) {
      bank.push_back(&get_template(opts.particle_grid));
      return;
    }
    if (!(v.d_max > 0)) return;  // no particles
    // On a polyMesh: from the largest cell for the smallest particle to the smallest cell
    // for the largest (the flux criterion then uses the smallest cell's size).
    rule = auto_rule(std::cbrt(smallest_cell_volume()));
    bank_first = detail::auto_step(v.d_min, poly ? poly_vmax : grid.cell_volume(), rule);
    const std::int64_t last = detail::auto_step(v.d_max, smallest_cell_volume(), rule);
    for (std::int64_t k = bank_first; k <= last; ++k) bank.push_back(&get_template(detail::auto_particle_count(k, rule)));
    log->info("particle_grid=auto: chi {:.3g} to {:.3g}, {} to {} sub-elements per particle",
              std::cbrt(smallest_cell_volume()) / v.d_max, std::cbrt(poly ? poly_vmax : grid.cell_volume()) / v.d_min,
              bank.back()->size(), bank.front()->size());
  }

  // --- validation ---------------------------------------------------------------------

  Validation validate(const ParticleView& pv, std::int64_t cs, std::int64_t rs, std::int64_t qs) {
    const bool need_q = opts.orientation == Orientation::given;
    const std::int32_t nshapes = static_cast<std::int32_t>(shapes.size());
    auto bad_particle = [&](std::int64_t p) {
      const double* c = pv.centres + p * cs;
      const double r = pv.radii[p * rs];
      if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) return true;
      if (!(r > 0) || !std::isfinite(r)) return true;
      if (pv.shape_ids && (pv.shape_ids[p] < 0 || pv.shape_ids[p] >= nshapes)) return true;
      if (need_q) {
        const double* q = pv.orientations + p * qs;
        const double nn = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
        if (!std::isfinite(nn) || !(nn > 0)) return true;
      }
      return false;
    };
    const Validation v = arena->execute([&] {
      return tbb::parallel_deterministic_reduce(
          tbb::blocked_range<std::int64_t>(0, pv.n, 4096), Validation{},
          [&](const tbb::blocked_range<std::int64_t>& r, Validation acc) {
            for (std::int64_t p = r.begin(); p < r.end(); ++p) {
              if (bad_particle(p)) {
                acc.first_bad = std::min(acc.first_bad, p);
                continue;
              }
              const double rad = pv.radii[p * rs];
              if (pv.shape_ids && !shapes[pv.shape_ids[p]].is_sphere) {
                acc.volume += shapes[pv.shape_ids[p]].shape.volume() * rad * rad * rad;
                continue;  // shaped particles' templates are chosen per shape
              }
              acc.volume += sphere_volume(rad);
              acc.d_min = std::min(acc.d_min, 2 * rad);
              acc.d_max = std::max(acc.d_max, 2 * rad);
            }
            return acc;
          },
          [](Validation a, const Validation& b) {
            a.first_bad = std::min(a.first_bad, b.first_bad);
            a.volume += b.volume;
            a.d_min = std::min(a.d_min, b.d_min);
            a.d_max = std::max(a.d_max, b.d_max);
            return a;
          },
          tbb::simple_partitioner());
    });
    if (v.first_bad != std::numeric_limits<std::int64_t>::max()) {
      const std::int64_t p = v.first_bad;
      const double* c = pv.centres + p * cs;
      std::ostringstream msg;
      msg.precision(17);
      msg << "particle " << p << ": ";
      if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2]))
        msg << "centre (" << c[0] << ", " << c[1] << ", " << c[2]
            << ") is not finite; pass finite positions (check the host's particle data)";
      else if (!(pv.radii[p * rs] > 0) || !std::isfinite(pv.radii[p * rs]))
        msg << (pv.shape_ids ? "scale " : "radius ") << pv.radii[p * rs]
            << " is not a finite number > 0; pass positive " << (pv.shape_ids ? "scales" : "radii");
      else if (pv.shape_ids && (pv.shape_ids[p] < 0 || pv.shape_ids[p] >= static_cast<std::int32_t>(shapes.size())))
        msg << "shape id " << pv.shape_ids[p] << " is not registered (" << shapes.size()
            << " shapes); register shapes with vfe_add_shape first";
      else
        msg << "orientation quaternion is zero or not finite; pass unit quaternions (w, x, y, z) "
               "or use orientation=random";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    return v;
  }

  // --- accumulation ---------------------------------------------------------------------

  Accumulation strategy(std::int64_t n) const {
    if (opts.deterministic) return Accumulation::sorted;
    if (opts.accumulation != Accumulation::automatic) return opts.accumulation;
    // Private fields cost threads x cells to clear and merge; atomics cost a
    // compare-and-swap per merged deposit (about 2 per particle). Prefer private fields
    // unless the mesh is much larger than the particle set.
    const double threads = arena->max_concurrency();
    if (threads <= 1) return Accumulation::privatised;
    return double(ncells()) * threads <= 8.0 * double(n) ? Accumulation::privatised
                                                                   : Accumulation::atomic;
  }

  template <class Body>
  void for_particles(std::int64_t n, Body&& body) {
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, n, 256),
                        [&](const tbb::blocked_range<std::int64_t>& r) { body(r.begin(), r.end()); });
    });
  }

  void compute(const ParticleView& pv, std::span<double> out) {
    const std::int64_t ncell = ncells();
    if (static_cast<std::int64_t>(out.size()) != ncell)
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "output has " + std::to_string(out.size()) +
                                                  " values but the mesh has " + std::to_string(ncell) +
                                                  " cells; pass a buffer of cell_count values");
    if (pv.n < 0) throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle count is negative; pass n >= 0");
    if (pv.n > 0 && (!pv.centres || !pv.radii))
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "centres or radii is NULL; pass arrays of 3n and n doubles");
    if (pv.n > 0 && opts.orientation == Orientation::given && !pv.orientations)
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "orientation=given needs orientations (4n quaternions w, x, y, z); pass them or "
                  "set orientation=random");
    const std::int64_t cs = pv.centre_stride ? pv.centre_stride : 3;
    const std::int64_t rs = pv.radius_stride ? pv.radius_stride : 1;
    const std::int64_t qs = pv.orientation_stride ? pv.orientation_stride : 4;

    const Validation v = validate(pv, cs, rs, qs);
    prepare_templates(v);
    prepare_shapes(pv, rs);
    const Accumulation acc = strategy(pv.n);
    log->debug("compute: {} particles, method={}, accumulation={}", pv.n, to_string(opts.method), int(acc));

    for (Scratch& s : scratch) s.reset_counters();
    const detail::Context ctx{grid, opts, detail::TemplateBank{bank, bank_first, opts.particle_grid > 0, rule}, divided};
    void (*driver)(const detail::Context&, Scratch&, const detail::Particle&) = nullptr;
    switch (opts.method) {
      case Method::direct: driver = detail::direct_particle; break;
      case Method::pmm: driver = detail::pmm_particle; break;
      case Method::exact: driver = detail::exact_particle; break;
      case Method::divided: driver = detail::divided_particle; break;
      case Method::gaussian: driver = detail::gaussian_particle; break;
      case Method::porous_cube: driver = detail::porous_cube_particle; break;
      case Method::big_particle: driver = detail::big_particle_particle; break;
      case Method::trilinear: driver = detail::trilinear_particle; break;
    }
    const bool shape_direct = opts.method == Method::direct;
    if (poly && opts.method != Method::direct && opts.method != Method::pmm && opts.method != Method::exact)
      throw Error(VFE_ERROR_UNSUPPORTED, "method=" + std::string(to_string(opts.method)) +
                                             " is not available on a polyMesh or rectilinear grid; use exact, pmm or direct");
    const detail::PolyContext poly_ctx{locator.get(), opts};
    const std::optional<detail::RectilinearContext> rect_ctx =
        rect ? std::optional<detail::RectilinearContext>(detail::RectilinearContext{*rect, opts}) : std::nullopt;
    auto particle = [&](Scratch& s, std::int64_t p) {
      s.deposits.clear();
      const double* cp = pv.centres + p * cs;
      const double r = pv.radii[p * rs];
      if (rect) {
        const Eigen::Vector3d c = wrapped(Eigen::Vector3d(cp[0], cp[1], cp[2]));
        const double* q = pv.orientations ? pv.orientations + p * qs : nullptr;
        if (pv.shape_ids && !shapes[pv.shape_ids[p]].is_sphere) {
          const RegisteredShape& sh = shapes[pv.shape_ids[p]];
          detail::rectilinear_particle(*rect_ctx, s, detail::Particle{p, c, r, sh.shape.volume() * r * r * r, q},
                                       shape_direct ? nullptr : sh.tmpl, sh.shape.centroid());
        } else {
          detail::rectilinear_particle(*rect_ctx, s, detail::Particle{p, c, r, 4.0 / 3.0 * std::numbers::pi * r * r * r, q},
                                       opts.method == Method::pmm ? &poly_template(c, 2 * r) : nullptr,
                                       Eigen::Vector3d::Zero());
        }
        return;
      }
      if (poly) {
        const Eigen::Vector3d c(cp[0], cp[1], cp[2]);
        const double* q = pv.orientations ? pv.orientations + p * qs : nullptr;
        if (pv.shape_ids && !shapes[pv.shape_ids[p]].is_sphere) {
          const RegisteredShape& sh = shapes[pv.shape_ids[p]];
          detail::polymesh_particle(poly_ctx, s, detail::Particle{p, c, r, sh.shape.volume() * r * r * r, q},
                                    shape_direct ? nullptr : sh.tmpl, sh.shape.centroid());
        } else if (opts.method == Method::exact) {
          detail::polymesh_exact_particle(poly_ctx, s,
                                          detail::Particle{p, c, r, 4.0 / 3.0 * std::numbers::pi * r * r * r, q});
        } else {
          detail::polymesh_particle(poly_ctx, s,
                                    detail::Particle{p, c, r, 4.0 / 3.0 * std::numbers::pi * r * r * r, q},
                                    shape_direct ? nullptr : &poly_template(c, 2 * r), Eigen::Vector3d::Zero());
        }
        return;
      }
      if (pv.shape_ids && !shapes[pv.shape_ids[p]].is_sphere) {
        const RegisteredShape& sh = shapes[pv.shape_ids[p]];
        const detail::Particle shaped{p, wrapped(Eigen::Vector3d(cp[0], cp[1], cp[2])), r, sh.shape.volume() * r * r * r,
                                      pv.orientations ? pv.orientations + p * qs : nullptr};
        detail::shape_particle(ctx, s, shaped, shape_direct ? nullptr : sh.tmpl,
                               sh.shape.centroid());
        return;
      }
      const detail::Particle particle{p, wrapped(Eigen::Vector3d(cp[0], cp[1], cp[2])), r,
                                      4.0 / 3.0 * std::numbers::pi * r * r * r,
                                      pv.orientations ? pv.orientations + p * qs : nullptr};
      driver(ctx, s, particle);
    };

    moved_particles = pv.n;
    Report rep;
    if (opts.incremental) {
      rep = accumulate_incremental(pv, cs, rs, qs, v.volume, particle);
    } else if (opts.touched_only && !opts.deterministic) {
      rep = accumulate_touched(pv, cs, rs, v.volume, particle);
    } else {
      work.assign(ncell + 1, 0.0);
      switch (acc) {
        case Accumulation::privatised:
        case Accumulation::automatic: accumulate_private(pv.n, particle); break;
        case Accumulation::atomic: {
          for_particles(pv.n, [&](std::int64_t b, std::int64_t e) {
            Scratch& s = scratch.local();
            for (std::int64_t p = b; p < e; ++p) {
              particle(s, p);
              for (const Deposit& d : s.deposits)
                std::atomic_ref<double>(work[d.cell]).fetch_add(d.volume, std::memory_order_relaxed);
            }
          });
          break;
        }
        case Accumulation::sorted: accumulate_sorted(pv.n, particle); break;
      }
      rep = gather_report(pv, cs, rs, v.volume);
      rep.dropped_volume = work[ncell];
      work.resize(ncell);
      solid.swap(work);
      touched_valid = false;
      rep.deposited_volume = sum_cells(solid, nullptr);
      rep.clipped_volume = clipped_volume(solid, nullptr);
    }
    have_field = true;
    report = rep;
    std::copy(solid.begin(), solid.end(), out.begin());
    log->info("computed {} particles with {}: {} moved, {} sub-elements, {} on the fast path, {} outside", pv.n,
              to_string(opts.method), moved_particles, rep.sub_elements, rep.fast_path_particles,
              rep.outside_particles);
  }

  /// The counters of this compute from the threads' scratch. Throws the outside=error
  /// failure: callers call it before they change the field.
  Report gather_report(const ParticleView& pv, std::int64_t cs, std::int64_t rs, double particle_volume) {
    Report rep{};
    rep.particles = pv.n;
    rep.particle_volume = particle_volume;
    rep.particle_grid_min = std::numeric_limits<std::int64_t>::max();
    std::int64_t first_error = std::numeric_limits<std::int64_t>::max();
    for (const Scratch& s : scratch) {
      rep.fast_path_particles += s.fast_path;
      rep.sub_elements += s.sub_elements;
      rep.outside_particles += s.outside_particles;
      rep.particle_grid_min = std::min(rep.particle_grid_min, s.grid_min);
      rep.particle_grid_max = std::max(rep.particle_grid_max, s.grid_max);
      first_error = std::min(first_error, s.first_error);
    }
    // Methods without sub-elements report 1 (a pmm compute of no particle reports 0).
    if (rep.particle_grid_max == 0) rep.particle_grid_min = rep.particle_grid_max = opts.method == Method::pmm ? 0 : 1;
    if (first_error != std::numeric_limits<std::int64_t>::max()) {
      const double* cp = pv.centres + first_error * cs;
      std::ostringstream msg;
      msg.precision(9);
      msg << "particle " << first_error << " at (" << cp[0] << ", " << cp[1] << ", " << cp[2]
          << ") with radius " << pv.radii[first_error * rs] << " reaches outside the mesh ["
          << grid.origin().transpose() << "] - [" << grid.upper().transpose() << "] (bounding box; "
          << rep.outside_particles
          << " particles do); enlarge the mesh or choose outside=nearest, centre or drop";
      throw Error(VFE_ERROR_OUT_OF_DOMAIN, msg.str());
    }
    return rep;
  }

  /// Sum of the field over the given cells (all cells when null).
  double sum_cells(const std::vector<double>& field, const std::vector<std::int64_t>* cells) const {
    double sum = 0;
    if (cells)
      for (const std::int64_t c : *cells) sum += field[c];
    else
      for (const double x : field) sum += x;
    return sum;
  }

  std::vector<double>& private_field() {
    std::vector<double>& f = private_fields.local().field;
    if (f.size() != static_cast<std::size_t>(ncells() + 1)) f.assign(ncells() + 1, 0.0);
    return f;
  }

  /// Per-thread fields, then a merge over all cells in parallel, copies innermost; leaves
  /// the copies zeroed for reuse.
  template <class ParticleFn>
  void accumulate_private(std::int64_t n, ParticleFn& particle) {
    const std::int64_t ncell = ncells();
    for_particles(n, [&](std::int64_t b, std::int64_t e) {
      Scratch& s = scratch.local();
      std::vector<double>& f = private_field();
      for (std::int64_t p = b; p < e; ++p) {
        particle(s, p);
        for (const Deposit& d : s.deposits) f[d.cell] += d.volume;
      }
    });
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, ncell + 1, 4096),
                        [&](const tbb::blocked_range<std::int64_t>& r) {
                          for (auto& pf : private_fields) {
                            std::vector<double>& f = pf.field;
                            if (f.size() != static_cast<std::size_t>(ncell + 1)) continue;
                            for (std::int64_t c = r.begin(); c < r.end(); ++c) {
                              work[c] += f[c];
                              f[c] = 0.0;
                            }
                          }
                        });
    });
  }

  /// touched_only=1: per-thread fields that list the cells they touch; only those cells
  /// (and the ones the last compute touched) are cleared, merged and summed.
  template <class ParticleFn>
  Report accumulate_touched(const ParticleView& pv, std::int64_t cs, std::int64_t rs, double volume,
                            ParticleFn& particle) {
    const std::int64_t ncell = ncells();
    for_particles(pv.n, [&](std::int64_t b, std::int64_t e) {
      Scratch& s = scratch.local();
      std::vector<double>& f = private_field();
      std::vector<std::int64_t>& t = private_fields.local().touched;
      for (std::int64_t p = b; p < e; ++p) {
        particle(s, p);
        for (const Deposit& d : s.deposits) {
          double& x = f[d.cell];
          if (x == 0.0) t.push_back(d.cell);
          x += d.volume;
        }
      }
    });
    Report rep;
    try {
      rep = gather_report(pv, cs, rs, volume);
    } catch (...) {
      for (auto& pf : private_fields) {
        for (const std::int64_t c : pf.touched) pf.field[c] = 0.0;
        pf.touched.clear();
      }
      throw;
    }
    if (touched_valid)
      for (const std::int64_t c : touched) solid[c] = 0.0;
    else
      solid.assign(ncell, 0.0);
    touched.clear();
    double dropped = 0;
    for (auto& pf : private_fields) {
      for (const std::int64_t c : pf.touched) {
        double& x = pf.field[c];
        if (c == ncell) {
          dropped += x;
        } else {
          if (solid[c] == 0.0) touched.push_back(c);
          solid[c] += x;
        }
        x = 0.0;
      }
      pf.touched.clear();
    }
    touched_valid = true;
    rep.dropped_volume = dropped;
    rep.deposited_volume = sum_cells(solid, &touched);
    rep.clipped_volume = clipped_volume(solid, &touched);
    return rep;
  }

  /// incremental=1: particles that did not move keep their deposits and cost one
  /// comparison; a moved particle's old deposits are subtracted and its new ones added.
  /// Particles appended since the last compute (a growing bed) are new; a smaller
  /// count, a change of shapes or orientations being given, or a configure or add_shape
  /// call starts afresh.
  template <class ParticleFn>
  Report accumulate_incremental(const ParticleView& pv, std::int64_t cs, std::int64_t rs, std::int64_t qs,
                                double volume, ParticleFn& particle) {
    const std::int64_t n = pv.n, ncell = ncells();
    const bool with_orientations = opts.orientation == Orientation::given;
    const bool with_shapes = pv.shape_ids != nullptr;
    const bool fresh = !inc.valid || n < inc.n || inc.with_shapes != with_shapes ||
                       inc.with_orientations != with_orientations;
    const std::int64_t old_n = fresh ? 0 : inc.n;  // particles with kept deposits
    const std::int64_t stride = with_orientations ? 8 : 4;
    const std::int64_t nblocks = (n + kSortedBlock - 1) / kSortedBlock;
    if (fresh) {
      inc.valid = false;
      inc.blocks.assign(nblocks, {});
    }
    inc.blocks.resize(nblocks);
    inc.particles.resize(n * stride);
    inc.shape_ids.resize(with_shapes ? n : 0);
    inc.next.resize(nblocks);
    const double tol = opts.move_tolerance;
    auto moved = [&](std::int64_t p) {
      if (p >= old_n) return true;
      const double* old = &inc.particles[p * stride];
      const double* c = pv.centres + p * cs;
      if (std::abs(c[0] - old[0]) > tol || std::abs(c[1] - old[1]) > tol || std::abs(c[2] - old[2]) > tol ||
          pv.radii[p * rs] != old[3])
        return true;
      if (with_orientations)
        for (int k = 0; k < 4; ++k)
          if (pv.orientations[p * qs + k] != old[4 + k]) return true;
      return with_shapes && pv.shape_ids[p] != inc.shape_ids[p];
    };
    // Phase 1: the new deposits of every block with a moved particle, beside the old ones.
    arena->execute([&] {
      tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
        const std::int64_t first = b * kSortedBlock, count = std::min(n, first + kSortedBlock) - first;
        DepositBlock& next = inc.next[b];
        next.moved.clear();
        for (std::int64_t i = 0; i < count; ++i)
          if (moved(first + i)) next.moved.push_back(static_cast<std::uint32_t>(i));
        if (next.moved.empty()) return;
        const DepositBlock& old = inc.blocks[b];
        Scratch& s = scratch.local();
        next.deposits.clear();
        next.offsets.resize(count + 1);
        next.offsets[0] = 0;
        std::size_t m = 0;
        for (std::int64_t i = 0; i < count; ++i) {
          if (m < next.moved.size() && next.moved[m] == i) {
            particle(s, first + i);
            next.deposits.insert(next.deposits.end(), s.deposits.begin(), s.deposits.end());
            ++m;
          } else {  // kept particles are below old_n, so their old deposits exist
            next.deposits.insert(next.deposits.end(), old.deposits.begin() + old.offsets[i],
                                 old.deposits.begin() + old.offsets[i + 1]);
          }
          next.offsets[i + 1] = static_cast<std::uint32_t>(next.deposits.size());
        }
      });
    });
    Report rep = gather_report(pv, cs, rs, volume);  // throws before the field changes
    // Phase 2: subtract the moved particles' old deposits, add their new ones.
    if (fresh) {
      solid.assign(ncell, 0.0);
      inc.dropped = 0;
    }
    auto apply_block = [&](std::int64_t b, auto&& add) {
      const DepositBlock& next = inc.next[b];
      const DepositBlock& old = inc.blocks[b];
      double dropped = 0;
      for (const std::uint32_t i : next.moved) {
        if (b * kSortedBlock + i < old_n)
          for (std::uint32_t k = old.offsets[i]; k < old.offsets[i + 1]; ++k) {
            const Deposit& d = old.deposits[k];
            if (d.cell == ncell) dropped -= d.volume; else add(d.cell, -d.volume);
          }
        for (std::uint32_t k = next.offsets[i]; k < next.offsets[i + 1]; ++k) {
          const Deposit& d = next.deposits[k];
          if (d.cell == ncell) dropped += d.volume; else add(d.cell, d.volume);
        }
      }
      return dropped;
    };
    double dropped = 0;
    if (opts.deterministic) {  // one thread, block order: the same sums for any thread count
      for (std::int64_t b = 0; b < nblocks; ++b)
        dropped += apply_block(b, [&](std::int64_t c, double x) { solid[c] += x; });
    } else {
      dropped = arena->execute([&] {
        return tbb::parallel_reduce(
            tbb::blocked_range<std::int64_t>(0, nblocks), 0.0,
            [&](const tbb::blocked_range<std::int64_t>& r, double acc) {
              for (std::int64_t b = r.begin(); b < r.end(); ++b)
                acc += apply_block(b, [&](std::int64_t c, double x) {
                  std::atomic_ref<double>(solid[c]).fetch_add(x, std::memory_order_relaxed);
                });
              return acc;
            },
            std::plus<double>());
      });
    }
    inc.dropped += dropped;
    std::int64_t count = 0;
    for (std::int64_t b = 0; b < nblocks; ++b) {
      DepositBlock& next = inc.next[b];
      if (next.moved.empty()) continue;
      count += static_cast<std::int64_t>(next.moved.size());
      for (const std::uint32_t i : next.moved) {
        const std::int64_t p = b * kSortedBlock + i;
        double* st = &inc.particles[p * stride];
        for (int d = 0; d < 3; ++d) st[d] = pv.centres[p * cs + d];
        st[3] = pv.radii[p * rs];
        if (with_orientations)
          for (int k = 0; k < 4; ++k) st[4 + k] = pv.orientations[p * qs + k];
        if (with_shapes) inc.shape_ids[p] = pv.shape_ids[p];
      }
      std::swap(next, inc.blocks[b]);
    }
    inc.valid = true;
    inc.n = n;
    inc.with_shapes = with_shapes;
    inc.with_orientations = with_orientations;
    moved_particles = count;
    touched_valid = false;
    rep.dropped_volume = inc.dropped;
    rep.deposited_volume = sum_cells(solid, nullptr);
    rep.clipped_volume = clipped_volume(solid, nullptr);
    return rep;
  }

  /// A position moved into the grid along its periodic axes (others unchanged).
  Eigen::Vector3d wrapped(Eigen::Vector3d c) const {
    for (int d = 0; d < 3; ++d) {
      if (!grid.periodic(d)) continue;
      const double length = grid.spacing()[d] * double(grid.cells()[d]);
      double u = std::fmod(c[d] - grid.origin()[d], length);
      if (u < 0) u += length;
      if (!(u < length)) u = 0;  // fmod of a value just below a multiple of the length
      c[d] = grid.origin()[d] + u;
    }
    return c;
  }

  /// pmm's sphere template on a polyMesh: auto sizes it by the cell holding the centre.
  const ParticleTemplate& poly_template(const Eigen::Vector3d& c, double diameter) const {
    if (bank.size() == 1) return *bank.front();
    std::int64_t cell = rect ? rect->nearest(c) : locator->locate(c);
    if (cell < 0) cell = locator->nearest_cell(c);
    const std::int64_t k = detail::auto_step(diameter, poly->cell_volume(cell), rule);
    return *bank[static_cast<std::size_t>(std::clamp<std::int64_t>(k - bank_first, 0, std::int64_t(bank.size()) - 1))];
  }

  /// Solid volume that clipping eps at alpha_min removes (0 when alpha_min is 0: no clip).
  /// Over the given cells (all cells when null; others hold no solid).
  double clipped_volume(const std::vector<double>& field, const std::vector<std::int64_t>* cells) const {
    if (opts.alpha_min <= 0) return 0.0;
    auto clip = [&](std::int64_t c) { return std::max(0.0, field[c] - (1.0 - opts.alpha_min) * cell_volume(c)); };
    double clipped = 0;
    if (cells)
      for (const std::int64_t c : *cells) clipped += clip(c);
    else
      for (std::int64_t c = 0; c < static_cast<std::int64_t>(field.size()); ++c) clipped += clip(c);
    return clipped;
  }

  /// Deterministic accumulation: deposits of fixed particle blocks, concatenated in
  /// particle order, sorted by (cell, position), summed per cell in that order. The
  /// result is bitwise the same for any thread count.
  template <class Particle>
  void accumulate_sorted(std::int64_t n, Particle& particle) {
    const std::int64_t nblocks = (n + kSortedBlock - 1) / kSortedBlock;
    blocks.resize(nblocks);
    arena->execute([&] {
      tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
        Scratch& s = scratch.local();
        auto& out = blocks[b];
        out.clear();
        const std::int64_t e = std::min(n, (b + 1) * kSortedBlock);
        for (std::int64_t p = b * kSortedBlock; p < e; ++p) {
          particle(s, p);
          out.insert(out.end(), s.deposits.begin(), s.deposits.end());
        }
      });
    });
    std::vector<std::int64_t>& offset = sort_offsets;
    offset.assign(nblocks + 1, 0);
    for (std::int64_t b = 0; b < nblocks; ++b) offset[b + 1] = offset[b] + std::int64_t(blocks[b].size());
    const std::int64_t total = offset[nblocks];
    sort_keys.resize(total);
    sort_values.resize(total);
    arena->execute([&] {
      tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
        for (std::size_t i = 0; i < blocks[b].size(); ++i) {
          const std::int64_t at = offset[b] + std::int64_t(i);
          sort_keys[at] = {blocks[b][i].cell, at};
          sort_values[at] = blocks[b][i].volume;
        }
      });
      tbb::parallel_sort(sort_keys.begin(), sort_keys.end());  // keys are unique
      // Each task sums the runs of equal cells that start in its range, in order.
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, total, 8192),
                        [&](const tbb::blocked_range<std::int64_t>& r) {
                          std::int64_t i = r.begin();
                          while (i > 0 && i < total && sort_keys[i].first == sort_keys[i - 1].first) ++i;
                          while (i < r.end() && i < total) {
                            const std::int64_t cell = sort_keys[i].first;
                            double sum = 0;
                            for (; i < total && sort_keys[i].first == cell; ++i) sum += sort_values[sort_keys[i].second];
                            work[cell] = sum;
                          }
                        });
    });
  }
};

Engine::Engine(const CartesianGridSpec& grid) : impl_(std::make_unique<Impl>(grid)) {}
Engine::Engine(const PolyMeshSpec& mesh) {
  auto poly = std::make_unique<PolyMesh>(PolyMesh::read(mesh.dir));
  // Sub-elements leaving through a cyclic patch would need the coupled patch's transform;
  // without it they would be counted outside the mesh, so refuse rather than lose volume.
  for (const PolyPatch& patch : poly->patches())
    if (patch.cyclic)
      throw Error(VFE_ERROR_UNSUPPORTED,
                  "polyMesh " + poly->source() + ": patch '" + patch.name + "' is of type " + patch.type +
                      "; cyclic patches are not supported. Use a mesh without cyclic patches (e.g. change them "
                      "to walls or patches) or, for a box, a rectilinear or Cartesian grid with periodic axes");
  impl_ = std::make_unique<Impl>(std::move(poly));
}
Engine::Engine(const RectilinearGridSpec& grid) {
  auto rect = std::make_unique<RectilinearGrid>(grid.nodes);
  impl_ = std::make_unique<Impl>(std::make_unique<PolyMesh>(rect->polymesh_data()));
  impl_->rect = std::move(rect);
}
Engine::~Engine() = default;

void Engine::configure(std::string_view options) {
  Options next = parse_options(options, impl_->opts);
  const bool new_arena = next.threads != impl_->opts.threads;
  if (next.periodic && impl_->poly && !impl_->rect)
    throw Error(VFE_ERROR_UNSUPPORTED,
                "periodic axes are available on Cartesian and rectilinear grids only; an OpenFOAM polyMesh's "
                "cyclic patches are not supported (use periodic=none)");
  impl_->opts = next;
  impl_->inc.valid = false;  // deposits kept by incremental=1 may no longer hold
  impl_->grid.set_periodic(next.periodic);
  if (new_arena) impl_->make_arena();
  impl_->log->set_level(spdlog::level::from_str(next.log_level));
}

std::string Engine::option(std::string_view key) const { return option_value(impl_->opts, key); }
std::string Engine::options() const { return format_options(impl_->opts); }
std::int64_t Engine::cell_count() const { return impl_->ncells(); }
bool Engine::is_polymesh() const { return impl_->poly != nullptr; }

namespace {
void check_size(std::span<const double> out, std::int64_t expected, const char* what) {
  if (static_cast<std::int64_t>(out.size()) != expected)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, std::string(what) + " has " + std::to_string(out.size()) +
                                                " values but needs " + std::to_string(expected) +
                                                " (per cell); pass a buffer of that size");
}
}  // namespace

void Engine::cell_volumes(std::span<double> out) const {
  check_size(out, cell_count(), "output");
  for (std::int64_t c = 0; c < cell_count(); ++c) out[c] = impl_->cell_volume(c);
}

void Engine::cell_centres(std::span<double> out) const {
  check_size(out, 3 * cell_count(), "output");
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    Eigen::Vector3d x;
    if (impl_->poly) {
      x = impl_->poly->cell_centre(c);
    } else {
      const auto& n = impl_->grid.cells();
      const std::int64_t i = c % n[0], j = (c / n[0]) % n[1], k = c / (n[0] * n[1]);
      x = impl_->grid.origin() +
          impl_->grid.spacing().cwiseProduct(Eigen::Vector3d(double(i) + 0.5, double(j) + 0.5, double(k) + 0.5));
    }
    for (int d = 0; d < 3; ++d) out[3 * c + d] = x[d];
  }
}

Engine::PolyTopology Engine::poly_topology() const {
  if (!impl_->poly) throw Error(VFE_ERROR_INVALID_ARGUMENT, "poly_topology: this engine is on a Cartesian grid");
  const PolyMesh& m = *impl_->poly;
  PolyTopology t;
  for (const auto& p : m.points()) t.points.insert(t.points.end(), {p[0], p[1], p[2]});
  t.face_offsets.push_back(0);
  for (std::int64_t f = 0; f < m.face_count(); ++f) {
    for (const std::int64_t q : m.face(f)) t.face_points.push_back(q);
    t.face_offsets.push_back(static_cast<std::int64_t>(t.face_points.size()));
  }
  t.cell_face_offsets.push_back(0);
  for (std::int64_t c = 0; c < m.cell_count(); ++c) {
    for (const std::int64_t f : m.cell_faces(c)) t.cell_faces.push_back(f);
    t.cell_face_offsets.push_back(static_cast<std::int64_t>(t.cell_faces.size()));
  }
  return t;
}

void Engine::compute(const ParticleView& particles, std::span<double> out) { impl_->compute(particles, out); }

void Engine::void_fraction(std::span<double> out) const {
  check_size(out, cell_count(), "output");
  const double alpha_min = impl_->opts.alpha_min;
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    const double eps = 1.0 - impl_->solid[c] / impl_->cell_volume(c);
    out[c] = alpha_min > 0 && eps < alpha_min ? alpha_min : eps;
  }
}

const Report& Engine::last_report() const { return impl_->report; }

double Engine::last_report_value(std::string_view key) const {
  const Report& r = impl_->report;
  const std::pair<const char*, double> facts[] = {
      {"particles", double(r.particles)},
      {"fast_path_particles", double(r.fast_path_particles)},
      {"sub_elements", double(r.sub_elements)},
      {"particle_grid_min", double(r.particle_grid_min)},
      {"particle_grid_max", double(r.particle_grid_max)},
      {"particle_volume", r.particle_volume},
      {"deposited_volume", r.deposited_volume},
      {"dropped_volume", r.dropped_volume},
      {"outside_particles", double(r.outside_particles)},
      {"clipped_volume", r.clipped_volume},
      {"moved_particles", double(impl_->have_field ? impl_->moved_particles : 0)},
      {"touched_cells", impl_->touched_valid ? double(impl_->touched.size()) : -1.0},
  };
  std::string known;
  for (const auto& [name, value] : facts) {
    if (key == name) return value;
    known += (known.empty() ? "" : ", ") + std::string(name);
  }
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "unknown report key '" + std::string(key) + "'; known keys: " + known);
}

std::int32_t Engine::add_shape(std::string_view spec) {
  Impl::RegisteredShape sh{parse_shape_spec(spec), false, 0, nullptr, 0, 0, {}};
  sh.is_sphere = sh.shape.kind() == kernels::Shape::Kind::sphere;
  sh.eq_diameter = std::cbrt(6.0 * sh.shape.volume() / std::numbers::pi);
  impl_->shapes.push_back(std::move(sh));
  impl_->inc.valid = false;
  return static_cast<std::int32_t>(impl_->shapes.size() - 1);
}

double Engine::shape_volume(std::int32_t id) const {
  if (id < 0 || id >= static_cast<std::int32_t>(impl_->shapes.size()))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "shape id " + std::to_string(id) + " is not registered");
  return impl_->shapes[id].shape.volume();
}

std::int64_t Engine::particle_grid_for(double diameter, double cell_size) const {
  const std::int64_t n = impl_->opts.particle_grid > 0
                             ? impl_->opts.particle_grid
                             : detail::auto_particle_count(
                                   detail::auto_step(diameter, cell_size * cell_size * cell_size,
                                                     impl_->auto_rule(cell_size)),
                                   impl_->auto_rule(cell_size));
  return static_cast<std::int64_t>(impl_->get_template(n).size());
}

}  // namespace vfe
