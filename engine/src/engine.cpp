// The engine facade and the dispatch of a compute: validation (particles.cpp), PMM's
// templates (particle_grid.cpp), the method's driver for the engine's mesh kind
// (methods/registry.cpp), chosen once per compute, and the accumulator (accumulator.cpp).
#include <vfe/detail/engine_backend.hpp>
#include <vfe/engine.hpp>

#include "accumulator.hpp"
#include "engine_mesh.hpp"
#include "field_facts.hpp"
#include "methods/exact.hpp"
#include "methods/hybrid.hpp"
#include "methods/lattice.hpp"
#include "methods/registry.hpp"
#include "methods/shape_exact.hpp"
#include "options.hpp"
#include "particle_grid.hpp"
#include "particle_arrays.hpp"
#include "particle_order.hpp"
#include "sphere_pass.hpp"
#include "shape_spec.hpp"
#include "smoothing.hpp"

#include <vfe/kernels/divided.hpp>
#include <vfe/kernels/particle_template.hpp>

#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <sstream>

namespace vfe {

namespace {

using detail::Deposit;
using detail::MeshKind;
using detail::ParticleArrays;
using detail::Scratch;
using detail::Validation;
using kernels::ParticleTemplate;

double sphere_volume(double r) { return 4.0 / 3.0 * std::numbers::pi * r * r * r; }

/// spdlog sink that hands each message to the host's callback.
class CallbackSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  CallbackSink(vfe_log_fn fn, void* user) : fn_(fn), user_(user) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    fn_(static_cast<int>(msg.level), std::string(msg.payload.begin(), msg.payload.end()).c_str(), user_);
  }
  void flush_() override {}

 private:
  vfe_log_fn fn_;
  void* user_;
};

/// One engine must not be used by two threads at once; a second caller is answered with an
/// error instead of corrupting the first one's result.
class UseGuard {
 public:
  explicit UseGuard(std::atomic<bool>& busy) : busy_(busy) {
    if (busy_.exchange(true, std::memory_order_acquire))
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "this engine is being used by another thread; one engine must not be called from two threads at "
                  "once (use one engine per thread)");
  }
  ~UseGuard() { busy_.store(false, std::memory_order_release); }
  UseGuard(const UseGuard&) = delete;
  UseGuard& operator=(const UseGuard&) = delete;

 private:
  std::atomic<bool>& busy_;
};

ParticleArrays arrays_of(const ParticleView& pv) {
  ParticleArrays a;
  a.n = pv.n;
  a.centres = reinterpret_cast<const char*>(pv.centres);
  a.centres_stride = 8 * (pv.centre_stride ? pv.centre_stride : 3);
  a.radii = reinterpret_cast<const char*>(pv.radii);
  a.radii_stride = 8 * (pv.radius_stride ? pv.radius_stride : 1);
  a.orientations = reinterpret_cast<const char*>(pv.orientations);
  a.orientations_stride = 8 * (pv.orientation_stride ? pv.orientation_stride : 4);
  a.shape_ids = reinterpret_cast<const char*>(pv.shape_ids);
  a.shape_ids_stride = 4;
  return a;
}

ParticleArrays arrays_of(const vfe_particles& p) {
  ParticleArrays a;
  a.n = p.n;
  a.centres = reinterpret_cast<const char*>(p.centres);
  a.centres_stride = p.centres_stride ? p.centres_stride : 24;
  a.radii = reinterpret_cast<const char*>(p.radii);
  a.radii_stride = p.radii_stride ? p.radii_stride : 8;
  a.orientations = reinterpret_cast<const char*>(p.orientations);
  a.orientations_stride = p.orientations_stride ? p.orientations_stride : 32;
  a.shape_ids = reinterpret_cast<const char*>(p.shape_ids);
  a.shape_ids_stride = p.shape_ids_stride ? p.shape_ids_stride : 4;
  a.ids = reinterpret_cast<const char*>(p.ids);
  a.ids_stride = p.ids_stride ? p.ids_stride : 8;
  return a;
}

}  // namespace

struct Engine::Impl {
  detail::EngineMesh mesh;
  Options opts;
  std::unique_ptr<tbb::task_arena> arena;
  std::shared_ptr<spdlog::logger> log;
  detail::Accumulator acc;
  tbb::enumerable_thread_specific<Scratch> scratch;
  detail::TemplateCache templates;
  const ParticleTemplate divided = kernels::make_divided_template();
  Report report{};
  bool have_field = false;
  double deterministic_volume_bound = 0;  ///< set_deterministic_volume
  // smoothing_length > 0: the smoothed field (what the host sees) and the mesh's face graph.
  std::vector<double> smoothed;
  std::unique_ptr<detail::FaceGraph> faces;
  std::atomic<bool> busy{false};
  detail::BlockedOrder blocked_order;  ///< particle_order: the copy in cell-block order
  std::int64_t arranged_blocks = 0;    ///< slabs this compute orders the particles by (0: the host's order)
  std::int64_t ordered_blocks = 0;     ///< the same, of the last successful compute

  // --- shapes ---------------------------------------------------------------------------

  /// Partitions per (shape, size) in pmm's bank: each particle takes one by its rotation
  /// key, so neighbours do not share one partition whose layers of sub-element centroids
  /// cross a face together (docs/shapes.md: the aligned cube's error then falls as n^-0.6
  /// instead of n^-0.37).
  static constexpr std::size_t kShapeVariants = 8;

  /// A shape registered with add_shape, and its templates for the current compute.
  struct RegisteredShape {
    kernels::Shape shape;
    bool is_sphere = false;
    double eq_diameter = 0;  ///< diameter of the sphere of equal volume, at scale 1
    const std::vector<std::unique_ptr<ParticleTemplate>>* variants = nullptr;  ///< pmm's bank for this compute
    double scale_min = 0, scale_max = 0;
    std::uint32_t variants_needed = 0;  ///< bit k: a particle of this compute takes variant k
  };
  std::vector<RegisteredShape> shapes;
  std::map<std::pair<std::int32_t, std::int64_t>, std::vector<std::unique_ptr<ParticleTemplate>>> shape_templates;

  // --- incremental=1: what each particle looked like at its last deposit ---------------
  struct Snapshot {
    bool with_shapes = false, with_orientations = false;
    std::vector<double> particles;  ///< x, y, z, r (then w, x, y, z with orientations)
    std::vector<std::int32_t> shape_ids;
  } snapshot;

  // --- weights=1: the transposed weights (cell -> particles), built on demand ----------
  struct CellWeights {
    bool valid = false;
    std::vector<std::int64_t> offsets, particles;
    std::vector<double> fractions;
  };
  mutable CellWeights cell_weights;
  std::vector<double> particle_volumes;  ///< weights=1: V_p of the last compute
  bool weights_kept = false;             ///< the last compute ran with weights=1

  template <class Spec>
  explicit Impl(Spec&& spec) : mesh(std::forward<Spec>(spec)), acc(mesh.cell_count()) {
    log = std::make_shared<spdlog::logger>("vfe", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    log->set_level(spdlog::level::warn);
    make_arena();
  }

  void make_arena() {
    arena = std::make_unique<tbb::task_arena>(opts.threads > 0 ? opts.threads : +tbb::task_arena::automatic);
  }

  /// The bank of kShapeVariants partitions of shape id into n sub-elements (variants 1..K of
  /// make_shape_template_variant: variant 0 is the lattice aligned with the shape's axes),
  /// each built when a particle first needs it (bit k of `needed`) and then cached.
  const std::vector<std::unique_ptr<ParticleTemplate>>& shape_template(std::int32_t id, std::int64_t n,
                                                                       std::uint32_t needed) {
    auto& bank = shape_templates[{id, n}];
    bank.resize(kShapeVariants);
    std::vector<std::size_t> missing;
    for (std::size_t k = 0; k < kShapeVariants; ++k)
      if (((needed >> k) & 1u) && !bank[k]) missing.push_back(k);
    if (missing.empty()) return bank;
    const RegisteredShape& sh = shapes[id];
    const auto start = std::chrono::steady_clock::now();
    // The variants are independent: built in parallel in the engine's arena.
    arena->execute([&] {
      tbb::parallel_for(std::size_t(0), missing.size(), [&](std::size_t i) {
        bank[missing[i]] = std::make_unique<ParticleTemplate>(kernels::make_shape_template_variant(
            sh.shape, static_cast<int>(n), static_cast<std::uint32_t>(missing[i] + 1)));
      });
    });
    log->info("built {} templates of {} sub-elements for shape {} ({}) in {:.3f} s", missing.size(), n, id,
              sh.shape.description(), std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    return bank;
  }

  /// The variant of a shape's bank particle `key` takes (a hash: keys in sequence spread
  /// over the bank independently of the rotation bank's pick).
  static std::size_t shape_variant(std::uint64_t key) {
    key = (key ^ (key >> 30)) * 0xbf58476d1ce4e5b9ull;
    key = (key ^ (key >> 27)) * 0x94d049bb133111ebull;
    return static_cast<std::size_t>((key ^ (key >> 31)) % kShapeVariants);
  }

  /// Templates of the non-spherical shapes this compute uses; rejects methods that
  /// cannot represent a shape.
  void prepare_shapes(const ParticleArrays& pa) {
    if (!pa.shape_ids) return;
    for (auto& sh : shapes) sh.scale_min = sh.scale_max = 0, sh.variants_needed = 0;
    for (std::int64_t p = 0; p < pa.n; ++p) {
      RegisteredShape& sh = shapes[pa.shape_id(p)];
      const double scale = pa.radius(p);
      sh.variants_needed |= 1u << shape_variant(pa.rotation_key(p));
      sh.scale_min = sh.scale_max == 0 ? scale : std::min(sh.scale_min, scale);
      sh.scale_max = std::max(sh.scale_max, scale);
    }
    const detail::AutoRule shape_rule = detail::TemplateCache::auto_rule(opts, std::cbrt(mesh.smallest_cell_volume()));
    for (std::int32_t id = 0; id < static_cast<std::int32_t>(shapes.size()); ++id) {
      RegisteredShape& sh = shapes[id];
      sh.variants = nullptr;
      if (sh.is_sphere || sh.scale_max == 0) continue;
      if (!detail::method_drivers(opts.method).shapes)
        throw Error(VFE_ERROR_UNSUPPORTED,
                    "method=" + std::string(to_string(opts.method)) + " handles spheres only, but shape " +
                        std::to_string(id) + " is a " + sh.shape.description() +
                        "; use method=pmm (a large particle_grid serves as the reference) or direct");
      if (opts.method == Method::exact)
        if (const std::string why = detail::exact_shape_refusal(sh.shape, id); !why.empty())
          throw Error(VFE_ERROR_UNSUPPORTED, why);
      if (opts.method != Method::pmm && opts.method != Method::automatic) continue;  // auto: shapes take pmm
      if (opts.particle_grid > 0) {
        sh.variants = &shape_template(id, opts.particle_grid, sh.variants_needed);
        continue;
      }
      // One template per shape, sized for its largest particles (the smallest chi, the
      // most sub-elements): shape templates are costly to cut, so none per size step.
      const std::int64_t k = detail::auto_step(sh.eq_diameter * sh.scale_max, mesh.smallest_cell_volume(), shape_rule);
      sh.variants = &shape_template(id, detail::auto_particle_count(k, shape_rule), sh.variants_needed);
    }
  }

  // --- validation -------------------------------------------------------------------------

  /// Why particle p cannot be computed, or "" when it can.
  std::string particle_problem(const ParticleArrays& pa, std::int64_t p) const {
    const Eigen::Vector3d c = pa.centre(p);
    const double r = pa.radius(p);
    std::ostringstream msg;
    msg.precision(17);
    const char* size_word = pa.shape_ids ? "scale " : "radius ";
    if (!c.allFinite()) {
      msg << "centre (" << c[0] << ", " << c[1] << ", " << c[2]
          << ") is not finite; pass finite positions (check the host's particle data)";
    } else if (!(r > 0) || !std::isfinite(r)) {
      msg << size_word << r << " is not a finite number > 0; pass positive " << (pa.shape_ids ? "scales" : "radii");
    } else if (pa.shape_ids && (pa.shape_id(p) < 0 || pa.shape_id(p) >= static_cast<std::int32_t>(shapes.size()))) {
      msg << "shape id " << pa.shape_id(p) << " is not registered (" << shapes.size()
          << " shapes); register shapes with vfe_add_shape first";
    } else if (opts.orientation == Orientation::given && [&] {
                 const double* q = pa.orientation(p);
                 const double nn = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
                 return !std::isfinite(nn) || !(nn > 0);
               }()) {
      msg << "orientation quaternion is zero or not finite; pass unit quaternions (w, x, y, z) or use "
             "orientation=random";
    } else {
      const double v = particle_volume(pa, p);
      if (!(v >= std::numeric_limits<double>::min() && v < 1e300))
        msg << size_word << r << " gives a volume of " << v
            << " that doubles cannot hold; pass sizes in units where a particle's volume lies between 1e-300 and "
               "1e300 (e.g. millimetres instead of metres for tiny particles)";
      else if (!(c.cwiseAbs().sum() + r < 1e300))
        msg << "centre and " << size_word << r << " reach beyond 1e300; pass positions and sizes near the mesh";
    }
    return msg.str();
  }

  double particle_volume(const ParticleArrays& pa, std::int64_t p) const {
    const double r = pa.radius(p);
    if (pa.shape_ids && !shapes[pa.shape_id(p)].is_sphere) return shapes[pa.shape_id(p)].shape.volume() * r * r * r;
    return sphere_volume(r);
  }

  /// The box spheres must stay within (validation's geometric outside count).
  detail::SphereBounds sphere_bounds() const {
    detail::SphereBounds b;
    const Eigen::AlignedBox3d box = mesh.bounds();
    for (int d = 0; d < 3; ++d) {
      const bool open = mesh.kind() == MeshKind::polyhedral || ((mesh.periodic() >> d) & 1u);
      b.lo[d] = open ? -std::numeric_limits<double>::infinity() : box.min()[d] - opts.outside_tolerance;
      b.hi[d] = open ? std::numeric_limits<double>::infinity() : box.max()[d] + opts.outside_tolerance;
    }
    return b;
  }

  static constexpr std::int64_t kChunk = detail::kSphereChunk;  ///< spheres checked (and deposited) at a time

  /// The particles' validation: body(range, acc) checks a range of particles into acc. The
  /// reduction tree is fixed (blocks of 4096, halved), so the sums are the same for any
  /// thread count and any body that adds the same particles in order.
  template <class Body>
  Validation reduce_particles(std::int64_t n, Body&& body) {
    return arena->execute([&] {
      return tbb::parallel_deterministic_reduce(
          tbb::blocked_range<std::int64_t>(0, n, 4096), Validation{},
          [&](const tbb::blocked_range<std::int64_t>& r, Validation acc) {
            body(r, acc);
            return acc;
          },
          [](Validation a, const Validation& b) {
            a.first_bad = std::min(a.first_bad, b.first_bad);
            a.volume += b.volume;
            a.d_min = std::min(a.d_min, b.d_min);
            a.d_max = std::max(a.d_max, b.d_max);
            a.shape_volume_max = std::max(a.shape_volume_max, b.shape_volume_max);
            a.beyond += b.beyond;
            return a;
          },
          tbb::simple_partitioner());
    });
  }

  /// Throws for the first bad particle or a total volume doubles cannot hold.
  void check_validation(const ParticleArrays& pa, const Validation& v) const {
    if (v.first_bad != std::numeric_limits<std::int64_t>::max()) {
      // The message computes with the bad values (a NaN compared, a radius cubed).
      const std::string problem = [&] {
        const detail::HeldFloatingPointTraps held;
        return particle_problem(pa, v.first_bad);
      }();
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle " + std::to_string(v.first_bad) + ": " + problem);
    }
    if (!std::isfinite(v.volume))
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "the particles' total volume overflows doubles; pass sizes in smaller units");
  }

  Validation validate(const ParticleArrays& pa) {
    const detail::SphereBounds bounds = sphere_bounds();
    const bool given = opts.orientation == Orientation::given;
    if (!pa.shape_ids && !given) {  // spheres only: the tight loop of the fused passes
      const Validation v = reduce_particles(pa.n, [&](const tbb::blocked_range<std::int64_t>& r, Validation& acc) {
        for (std::int64_t first = r.begin(); first < r.end(); first += kChunk)
          detail::check_sphere_chunk(pa, first, std::min(kChunk, r.end() - first), bounds, acc);
      });
      check_validation(pa, v);
      return v;
    }
    const auto nshapes = static_cast<std::int32_t>(shapes.size());
    const Validation v = reduce_particles(pa.n, [&](const tbb::blocked_range<std::int64_t>& r, Validation& acc) {
      const detail::HeldFloatingPointTraps held;  // the values are not checked yet
      for (std::int64_t p = r.begin(); p < r.end(); ++p) {
        const double* c = reinterpret_cast<const double*>(pa.centres + p * pa.centres_stride);
        const double rad = pa.radius(p);
        bool sphere = true;
        double vol;
        if (pa.shape_ids) {
          const std::int32_t id = pa.shape_id(p);
          if (id < 0 || id >= nshapes) {
            acc.first_bad = std::min(acc.first_bad, p);
            continue;
          }
          sphere = shapes[id].is_sphere;
          vol = sphere ? sphere_volume(rad) : shapes[id].shape.volume() * rad * rad * rad;
        } else {
          vol = sphere_volume(rad);
        }
        bool ok = detail::particle_values_ok(c, rad, vol);
        if (ok && given) {
          const double* q = pa.orientation(p);
          const double nn = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
          ok = std::isfinite(nn) && nn > 0;
        }
        if (!ok) {
          acc.first_bad = std::min(acc.first_bad, p);
          continue;
        }
        acc.volume += vol;
        if (sphere) {
          acc.d_min = std::min(acc.d_min, 2 * rad);
          acc.d_max = std::max(acc.d_max, 2 * rad);
          acc.beyond += bounds.beyond(c, rad);
        } else {
          acc.shape_volume_max = std::max(acc.shape_volume_max, vol);
        }
      }
    });
    check_validation(pa, v);
    return v;
  }

  /// The Cartesian grid the fused passes below compute on: the mesh itself, or the grid of
  /// a polyMesh's box lattice where that grid's drivers serve every sphere as they are
  /// (LatticeBoundary::grid; methods/lattice.hpp), its cells renumbered by cell_map (null
  /// when the numbering is the grid's). grid is null where neither holds.
  struct FusedGrid {
    const CartesianGrid* grid = nullptr;
    const std::int64_t* cell_map = nullptr;
  };
  FusedGrid fused_grid() const {
    if (mesh.kind() == MeshKind::cartesian) return {mesh.cartesian(), nullptr};
    const detail::BoxLattice* lattice = opts.lattice ? mesh.lattice() : nullptr;
    if (!lattice || !lattice->cartesian ||
        detail::lattice_boundary(opts.method, *lattice) != detail::LatticeBoundary::grid)
      return {};
    return {&*lattice->cartesian, lattice->grid_numbering ? nullptr : lattice->cell_map.data()};
  }

  /// direct on a Cartesian grid with spheres and private fields: validation, locate and the
  /// add in one pass over the particles, so direct costs little more than reading them.
  bool fuses_direct(const ParticleArrays& pa, const detail::AccumulationPlan& pl) const {
    const FusedGrid fg = fused_grid();
    return opts.method == Method::direct && fg.grid && !fg.grid->is_block() && !pa.shape_ids &&
           opts.orientation != Orientation::given && pl.strategy == Accumulation::privatised && !pl.uses_blocks() &&
           !pl.touched_only && mesh.cell_count() < detail::kCentreGridCells;
  }

  /// The fused pass: the same Validation as validate() (the same tree, the same particles in
  /// order) and the same cells as direct_particle. A sphere whose centre lies outside the
  /// grid goes through the driver (the outside policy); on a periodic grid every sphere is
  /// wrapped first, as the driver does. Throws validate()'s errors, and the accumulator
  /// drops what the pass deposited. On a box lattice the grid's cells are renumbered.
  Validation fused_direct(const ParticleArrays& pa, const detail::AccumulationPlan& pl) {
    const FusedGrid fg = fused_grid();
    const CartesianGrid& grid = *fg.grid;
    const std::int64_t* const map = fg.cell_map;
    const detail::Context ctx{detail::MethodContext{opts, detail::TemplateBank{}, divided}, grid};
    const detail::SphereBounds bounds = sphere_bounds();
    const bool periodic = mesh.periodic() != 0;
    const bool on_lattice = mesh.kind() == MeshKind::polyhedral;
    // The pass, with add(cell, volume) and add_extra(cell, volume) for this thread's deposits.
    auto pass = [&](const tbb::blocked_range<std::int64_t>& r, Validation& a, detail::CentreGrid g, auto&& add,
                    auto&& add_extra) {
      Scratch& s = scratch.local();
      for (int d = 0; d < 3; ++d) {
        g.origin[d] = grid.origin()[d];
        g.inv_spacing[d] = 1.0 / grid.spacing()[d];
        g.cells[d] = double(grid.cells()[d]);
      }
      g.strides[0] = static_cast<std::int32_t>(grid.cells()[0]);
      g.strides[1] = static_cast<std::int32_t>(grid.cells()[0] * grid.cells()[1]);
      g.cell_map = map;
      if (on_lattice) s.lattice_particles += r.size();
      auto by_driver = [&](std::int64_t p) {
        s.deposits.clear();
        detail::direct_particle(ctx, s, particle(pa, p));
        for (const Deposit& d : s.deposits) add_extra(map ? map[d.cell] : d.cell, d.volume);
      };
      std::int64_t left[kChunk];
      for (std::int64_t first = r.begin(); first < r.end(); first += kChunk) {
        const std::int64_t count = std::min(kChunk, r.end() - first);
        if (!periodic) {
          const std::int64_t nleft = detail::deposit_sphere_chunk(pa, first, count, bounds, g, a, left);
          s.sub_elements += count - nleft;  // the driver counts the others
          for (std::int64_t i = 0; i < nleft; ++i) by_driver(left[i]);
          continue;
        }
        if (!detail::check_sphere_chunk(pa, first, count, bounds, a)) continue;  // the compute fails
        for (std::int64_t p = first; p < first + count; ++p) {
          if (const std::int64_t cell = grid.locate(mesh.wrap(pa.centre(p))); cell >= 0) {
            add(cell, sphere_volume(pa.radius(p)));
            ++s.sub_elements;
          } else {
            by_driver(p);
          }
        }
      }
    };
    if (pl.binned)
      return acc.deposit_binned(*arena, pl, pa.n, [&](auto&& thread_bins) {
        const Validation v = reduce_particles(pa.n, [&](const tbb::blocked_range<std::int64_t>& r, Validation& a) {
          detail::BinWriter bins = thread_bins();
          detail::CentreGrid g{};
          g.bins = &bins;
          pass(
              r, a, g, [&](std::int64_t cell, double v) { bins.add(static_cast<std::int32_t>(cell), v); },
              [&](std::int64_t cell, double v) { bins.extra(cell, v); });
        });
        check_validation(pa, v);
        return v;
      });
    return acc.deposit_private(pl, pa.n, [&](auto&& thread_field) {
      const Validation v = reduce_particles(pa.n, [&](const tbb::blocked_range<std::int64_t>& r, Validation& a) {
        double* const field = thread_field();
        detail::CentreGrid g{};
        g.field = field;
        auto add = [field](std::int64_t cell, double v) { field[cell] += v; };
        pass(r, a, g, add, add);
      });
      check_validation(pa, v);
      return v;
    });
  }

  /// pmm on a Cartesian grid (no periodic axis) with spheres and private fields: each
  /// particle's fast path or octant count (methods/driver.hpp, PmmQuick) adds
  /// straight into the thread's field; a particle that takes neither goes through the
  /// driver. The same cells as the general loop, with less per particle around them.
  /// method=auto takes the same pass with its own quick case (methods/hybrid.hpp).
  bool fuses_pmm(const ParticleArrays& pa, const detail::AccumulationPlan& pl) const {
    return (opts.method == Method::pmm || opts.method == Method::automatic) && fused_grid().grid &&
           !pa.shape_ids && !mesh.periodic() &&
           opts.orientation != Orientation::given && opts.fast_path && pl.strategy == Accumulation::privatised &&
           !pl.uses_blocks() && !pl.touched_only;
  }

  /// bank_d_min, bank_d_max: the diameters the bank was made for (private_field_pass).
  Validation fused_pmm(const ParticleArrays& pa, const detail::AccumulationPlan& pl, const detail::TemplateBank& bank,
                       bool validating, double bank_d_min, double bank_d_max) {
    const detail::Context ctx{detail::MethodContext{opts, bank, divided}, *fused_grid().grid};
    const detail::PmmQuick quick(ctx, true);
    const bool hybrid = opts.method == Method::automatic;
    // method=auto takes the chunks where it leaves every sphere to pmm's quick case.
    const detail::QuickGrid* chunked = quick.window_grid();
    if (chunked && hybrid)
      for (const kernels::ParticleTemplate* t : quick.chunk_templates())
        if (!detail::auto_counts_every_window(*t)) chunked = nullptr;
    projected_counts = chunked && quick.counts_from_projections();
    static_assert(detail::PmmQuick::kChunk == kChunk, "a planned chunk is a checked chunk");
    return private_field_pass(pa, pl, validating, [&](Scratch& s, auto&& add, const tbb::blocked_range<std::int64_t>& r,
                                                      auto&& check) {
      // One particle record for the range, its per-particle fields set in the loop
      // (building a whole record per particle costs as much as a quick case).
      detail::Particle part{0, Eigen::Vector3d::Zero(), 0.0, 0.0, nullptr, 0};
      auto general = [&](std::int64_t p) {
        s.deposits.clear();
        if (hybrid)
          detail::auto_particle(ctx, s, particle(pa, p));
        else
          detail::pmm_particle(ctx, s, particle(pa, p));
        for (const Deposit& d : s.deposits) add(d.cell, d.volume);
      };
      if (const detail::QuickGrid* g = chunked) {
        // Windows and thresholds of a few spheres at once (pmm_plan.hpp), then their counts
        // (sorted by path: PmmQuick::finish_chunk).
        constexpr std::int64_t kChunk = detail::PmmQuick::kChunk;
        detail::QuickWindows planned;
        for (std::int64_t chunk = r.begin(); chunk < r.end(); chunk += kChunk) {
          const std::int64_t n = std::min(kChunk, r.end() - chunk);
          // The planning first, then the check: it asks for the spheres' lines ahead, so the
          // check reads them from the cache (paired rounds: the other order lost the gain of
          // validating in this pass). The planning computes on values not yet checked (it
          // would divide by a radius of 0): with the thread's traps held.
          bool good;
          {
            const detail::HeldFloatingPointTraps held;
            detail::plan_sphere_windows(pa, chunk, n, *g, planned);
            good = check(chunk, n);
          }
          if (!good) continue;  // the compute fails, or the bank is another's
          detail::PmmQuick::Tally tally;
          auto finish = [&](auto&& taken) {
            quick.finish_chunk(
                tally, planned, n, add, [&](std::int64_t k) { return pa.radius(chunk + k); }, taken,
                [&](std::int64_t k) { general(chunk + k); });
          };
          if (hybrid) {  // method=auto counts its paths, in registers, into the Scratch once a chunk
            std::int64_t auto_fast = 0, auto_pmm = 0;
            finish([&](std::int64_t k, bool fast) {
              if (fast) {  // only a fast path asks where the ball lies
                part.centre = pa.centre(chunk + k);
                part.radius = pa.radius(chunk + k);
              }
              detail::auto_count_quick(ctx.grid, part, fast, auto_fast, auto_pmm);
            });
            s.auto_fast += auto_fast;
            s.auto_pmm += auto_pmm;
          } else
            finish([](std::int64_t, bool) {});
          quick.commit(s, tally);
        }
        return;
      }
      for (std::int64_t first = r.begin(); first < r.end(); first += kChunk) {
        const std::int64_t end = std::min(first + kChunk, r.end());
        if (!check(first, end - first)) continue;  // the compute fails
        for (std::int64_t p = first; p < end; ++p) {
          __builtin_prefetch(pa.centres + (p + 16) * pa.centres_stride);
          __builtin_prefetch(pa.radii + (p + 16) * pa.radii_stride);
          const double radius = pa.radius(p);
          part.index = pa.host(p);
          part.centre = pa.centre(p);
          part.radius = radius;
          part.volume = sphere_volume(radius);
          part.rotation_key = pa.rotation_key(p);
          // An octant without sub-elements may add 0.0: a cell of the private field stays as it is.
          if (hybrid ? detail::auto_sphere_quick(quick, s, part, add, detail::PmmQuick::EmptyOctants::add_zero)
                     : quick(s, part, add, detail::PmmQuick::EmptyOctants::add_zero))
            continue;
          general(p);
        }
      }
    }, bank_d_min, bank_d_max);
  }

  /// exact on a Cartesian grid (no periodic axis) with spheres and private fields: a sphere
  /// whose cells lie in the grid, at most two per axis, adds its parts straight into the
  /// thread's field (methods/exact.hpp, exact_sphere_quick); any other goes through the
  /// driver. The same cells and volumes as the general loop.
  bool fuses_exact(const ParticleArrays& pa, const detail::AccumulationPlan& pl) const {
    return opts.method == Method::exact && fused_grid().grid && !pa.shape_ids && !mesh.periodic() &&
           pl.strategy == Accumulation::privatised && !pl.uses_blocks() && !pl.touched_only;
  }

  Validation fused_exact(const ParticleArrays& pa, const detail::AccumulationPlan& pl,
                         const detail::TemplateBank& bank, bool validating) {
    const detail::Context ctx{detail::MethodContext{opts, bank, divided}, *fused_grid().grid};
    return private_field_pass(pa, pl, validating, [&](Scratch& s, auto&& add, const tbb::blocked_range<std::int64_t>& r,
                                                      auto&& check) {
      for (std::int64_t first = r.begin(); first < r.end(); first += kChunk) {
        const std::int64_t end = std::min(first + kChunk, r.end());
        if (!check(first, end - first)) continue;  // the compute fails
        for (std::int64_t p = first; p < end; ++p) {
          const double radius = pa.radius(p);
          // A sphere needs no rotation key; its index is the host's (particle_order may have
          // arranged the arrays).
          const detail::Particle part{pa.host(p), pa.centre(p), radius, sphere_volume(radius), nullptr, 0};
          if (detail::exact_sphere_quick(ctx, s, part, add)) continue;
          s.deposits.clear();
          detail::exact_particle(ctx, s, particle(pa, p));
          for (const Deposit& d : s.deposits) add(d.cell, d.volume);
        }
      }
    });
  }

  /// A fused pass's add into a thread's field: add(cell, volume), and prefetch(cell) of the
  /// line a later add will write (through the lattice's map where kMapped).
  template <bool kMapped>
  struct FieldAdd {
    double* field;
    const std::int64_t* map;
    [[gnu::always_inline]] void operator()(std::int64_t cell, double v) const {
      field[kMapped ? map[cell] : cell] += v;
    }
    [[gnu::always_inline]] void prefetch(std::int64_t cell) const {
      __builtin_prefetch(field + (kMapped ? map[cell] : cell), 1);
    }
  };

  /// Phase 1 by a pass of the caller's own over the particles (validate()'s blocks on the
  /// engine's threads), adding straight into each thread's private field. The frame of the
  /// fused passes of pmm and exact: body(scratch, add, block, check) with add(cell, volume),
  /// cell a cell of fused_grid(), and check(first, count) called for spheres [first,
  /// first + count) before the body computes them, in chunks of kChunk from the block's
  /// start; where it returns false the chunk holds a bad sphere and the body leaves it.
  /// With `validating` the pass validates as it goes, so the particles are read from memory
  /// once: it returns validate()'s Validation (the same tree, the same chunks in order) and
  /// throws its errors, the accumulator dropping what the pass deposited. Without, the
  /// particles were validated before and check returns true. A pass whose template bank was
  /// made for diameters [bank_d_min, bank_d_max] computes nothing from the first chunk that
  /// holds a sphere outside them: its caller runs it again with the right bank, and until
  /// then only the validation is worth its cost (a bank for larger spheres may give small
  /// ones thousands of sub-elements each).
  template <class Body>
  Validation private_field_pass(const ParticleArrays& pa, const detail::AccumulationPlan& pl, bool validating,
                                Body&& body, double bank_d_min = 0,
                                double bank_d_max = std::numeric_limits<double>::infinity()) {
    const std::int64_t* const map = fused_grid().cell_map;
    const bool on_lattice = mesh.kind() == MeshKind::polyhedral;
    const detail::SphereBounds bounds = sphere_bounds();
    std::atomic<bool> beyond_bank{false};
    return acc.deposit_private(pl, pa.n, [&](auto&& thread_field) {
      const Validation v = reduce_particles(pa.n, [&](const tbb::blocked_range<std::int64_t>& r, Validation& a) {
        double* const field = thread_field();
        Scratch& s = scratch.local();
        if (on_lattice) s.lattice_particles += r.size();
        const auto check = [&](std::int64_t first, std::int64_t count) {
          if (!validating) return true;
          const bool good = detail::check_sphere_chunk(pa, first, count, bounds, a);
          if (a.d_min < bank_d_min || a.d_max > bank_d_max) beyond_bank.store(true, std::memory_order_relaxed);
          return good && !beyond_bank.load(std::memory_order_relaxed);
        };
        if (map)
          body(s, FieldAdd<true>{field, map}, r, check);
        else
          body(s, FieldAdd<false>{field, nullptr}, r, check);
      });
      if (validating) check_validation(pa, v);
      return v;
    });
  }

  /// The spheres' smallest and largest diameters into v from their radii alone, for pmm's
  /// bank before a pass that validates as it goes (a fourth of validate()'s bytes where the
  /// radii are packed). False where some radius is bad (validate() then names it); else
  /// v's diameters are the ones validate() gives.
  bool sphere_diameters(const ParticleArrays& pa, Validation& v) {
    struct Range {
      double lo = std::numeric_limits<double>::infinity(), hi = 0;
      bool bad = false;
    };
    const Range range = arena->execute([&] {
      return tbb::parallel_reduce(
          tbb::blocked_range<std::int64_t>(0, pa.n, 16384), Range{},
          [&](const tbb::blocked_range<std::int64_t>& r, Range a) {
            const detail::HeldFloatingPointTraps held;  // the radii are not checked yet
            const auto take = [&](double radius) {
              a.lo = std::min(a.lo, radius);
              a.hi = std::max(a.hi, radius);
              a.bad |= !(radius > 0);  // NaN too
            };
            if (pa.radii_stride == sizeof(double)) {  // packed: a loop the compiler vectorises
              const double* radii = reinterpret_cast<const double*>(pa.radii);
              for (std::int64_t p = r.begin(); p < r.end(); ++p) take(radii[p]);
            } else {
              for (std::int64_t p = r.begin(); p < r.end(); ++p) take(pa.radius(p));
            }
            return a;
          },
          [](Range a, const Range& b) {
            a.lo = std::min(a.lo, b.lo);
            a.hi = std::max(a.hi, b.hi);
            a.bad |= b.bad;
            return a;
          });
    });
    // The volume grows with the radius: particle_values_ok's bounds on the radius hold for
    // every radius when they hold for the extremes (whose cubes may overflow: traps held).
    const detail::HeldFloatingPointTraps held;
    const double origin[3] = {0, 0, 0};
    const bool ok = !range.bad && (pa.n == 0 || (detail::particle_values_ok(origin, range.lo, sphere_volume(range.lo)) &&
                                                 detail::particle_values_ok(origin, range.hi, sphere_volume(range.hi))));
    v.d_min = 2 * range.lo;
    v.d_max = 2 * range.hi;
    return ok;
  }

  // --- accumulation plan ----------------------------------------------------------------

  detail::AccumulationPlan plan(const ParticleArrays& pa) const {
    const std::int64_t n = pa.n;
    detail::AccumulationPlan plan;
    plan.touched_only = opts.touched_only;
    plan.incremental = opts.incremental;
    plan.keep_deposits = opts.weights;
    plan.fixed_point = opts.deterministic;
    if (opts.deterministic) {
      plan.strategy = Accumulation::sorted;
    } else if (opts.accumulation != Accumulation::automatic) {
      plan.strategy = opts.accumulation;
    } else {
      // Private fields cost threads x cells to clear and merge; atomics cost a
      // compare-and-swap per merged deposit (about 2 per particle). Prefer private fields
      // unless the mesh is much larger than the particle set (or touched_only asks for them).
      // direct's fused pass, which needs them, costs a few ns per sphere where the general
      // loop behind atomics costs tens, so it keeps them up to a sparser scene; from
      // kBinnedCells its bins cost the cells once, whatever the thread count
      // (docs/performance.md, "direct's fused pass against atomics").
      // Bins where several threads would each fill and merge a large private field (one
      // thread's field is cheaper than bins: cell_bins.hpp).
      const double threads = arena->max_concurrency();
      detail::AccumulationPlan fused = plan;
      fused.strategy = Accumulation::privatised;
      const bool fused_direct = threads > 1 && fuses_direct(pa, fused);
      const double cells = double(mesh.cell_count());
      const bool bins = fused_direct && cells >= double(detail::kBinnedCells);
      plan.strategy = threads <= 1 || opts.touched_only ||
                              (bins ? cells : cells * threads) <=
                                  (fused_direct ? 64.0 : 8.0) * double(std::max<std::int64_t>(n, 1))
                          ? Accumulation::privatised
                          : Accumulation::atomic;
      plan.binned = bins && plan.strategy == Accumulation::privatised;
    }
    return plan;
  }

  // --- the compute ----------------------------------------------------------------------

  void compute(const ParticleArrays& host, std::span<double> out) {
    const ParticleArrays pa = arranged(host);  // the host's arrays, or a copy in cell-block order
    const std::int64_t ncell = mesh.cell_count();
    if (static_cast<std::int64_t>(out.size()) != ncell)
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "output has " + std::to_string(out.size()) +
                                                  " values but the mesh has " + std::to_string(ncell) +
                                                  " cells; pass a buffer of cell_count values");
    if (pa.n < 0) throw Error(VFE_ERROR_INVALID_ARGUMENT, "particle count is negative; pass n >= 0");
    if (pa.n > 0 && (!pa.centres || !pa.radii))
      throw Error(VFE_ERROR_INVALID_ARGUMENT, "centres or radii is NULL; pass arrays of 3n and n doubles");
    if (pa.n > 0 && opts.orientation == Orientation::given && !pa.orientations)
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "orientation=given needs orientations (4n quaternions w, x, y, z); pass them or "
                  "set orientation=random");

    detail::AccumulationPlan pl = plan(pa);
    for (Scratch& sc : scratch) sc.reset_counters();
    const bool fused = fuses_direct(pa, pl);
    const bool fused_particles = !fused && fuses_pmm(pa, pl);
    const bool fused_exact_pass = !fused && fuses_exact(pa, pl);
    // The fused passes of pmm and exact validate as they go where they can (exact validates
    // given quaternions beforehand). pmm's bank needs the diameters first: the last
    // validated compute's, checked after the pass (a host's spheres keep their sizes from
    // one step to the next), or on a first compute from the radii alone.
    Validation v;
    bool validating = false, assumed_diameters = false;
    if (fused) {
      v = fused_direct(pa, pl);
    } else if (fused_particles) {
      assumed_diameters = last_diameters.has_value();
      if (assumed_diameters) {
        v.d_min = last_diameters->first;
        v.d_max = last_diameters->second;
        validating = true;
      } else {
        validating = sphere_diameters(pa, v);
      }
    } else if (fused_exact_pass) {
      validating = opts.orientation != Orientation::given;
    }
    if (!fused && !validating) v = validate(pa);
    if (pl.fixed_point)  // every rank of a distributed mesh gives the same bound: the same unit
      pl.unit_exponent = fixed_unit_exponent(
          std::max({deterministic_volume_bound, v.shape_volume_max, v.d_max > 0 ? sphere_volume(v.d_max / 2) : 0.0}));
    const auto template_bank = [&] {
      return templates.prepare(opts, v.d_min, v.d_max, mesh.smallest_cell_volume(), mesh.largest_cell_volume(),
                               pa.n);
    };
    detail::TemplateBank bank = template_bank();
    prepare_shapes(pa);

    const detail::MethodDrivers& drivers = detail::method_drivers(opts.method);
    const detail::MethodContext common{opts, bank, divided};
    projected_counts = false;
    if (fused_exact_pass) {
      const Validation checked = fused_exact(pa, pl, bank, validating);
      if (validating) v = checked;
    }
    if (fused_particles) {
      const Validation checked = fused_pmm(pa, pl, bank, validating, v.d_min, v.d_max);
      const bool stale_bank = assumed_diameters && (checked.d_min != v.d_min || checked.d_max != v.d_max);
      if (validating) v = checked;
      if (stale_bank) {  // the sizes changed since the last compute: again with their bank
        log->debug("the spheres' diameters changed: the pass again with their template bank");
        acc.abandon();
        for (Scratch& sc : scratch) sc.reset_counters();
        bank = template_bank();
        fused_pmm(pa, pl, bank, false, v.d_min, v.d_max);
      }
    }
    // The bank the particles took (pmm's fused pass may have changed it).
    if ((opts.method == Method::pmm || opts.method == Method::automatic) && !bank.fixed && !bank.templates.empty())
      log->info("particle_grid=auto: {} to {} sub-elements per particle", bank.templates.front()->size(),
                bank.templates.back()->size());
    // Only a range of spheres makes a bank (none, or shapes alone, leave d_max = 0).
    if (v.d_max > 0)
      last_diameters.emplace(v.d_min, v.d_max);
    else
      last_diameters.reset();
    if (!fused && !fused_particles && !fused_exact_pass) switch (mesh.kind()) {
      case MeshKind::cartesian:
        run(detail::Context{common, *mesh.cartesian()}, drivers.cartesian, pa, pl);
        break;
      case MeshKind::rectilinear:
        run(detail::RectilinearContext{common, *mesh.rectilinear()}, drivers.rectilinear, pa, pl);
        break;
      case MeshKind::polyhedral: {
        const detail::PolyContext poly{common, mesh.locator()};
        const detail::BoxLattice* lattice = opts.lattice ? mesh.lattice() : nullptr;
        if (!lattice) {
          run(poly, drivers.polyhedral, pa, pl);
          break;
        }
        // The grid of the same cells, with the polyMesh's driver for particles near its boundary.
        std::optional<detail::Context> cartesian;
        std::optional<detail::RectilinearContext> rectilinear;
        if (lattice->cartesian)
          cartesian.emplace(detail::Context{common, *lattice->cartesian});
        else
          rectilinear.emplace(detail::RectilinearContext{common, *lattice->rectilinear});
        run(detail::lattice_context(poly, cartesian ? &*cartesian : nullptr, rectilinear ? &*rectilinear : nullptr,
                                    *lattice),
            detail::lattice_particle, pa, pl);
        break;
      }
    }
    Report rep;
    try {
      rep = gather_report(host, v.volume);  // throws the outside=error failure, naming the host's particle
    } catch (...) {
      acc.abandon();
      throw;
    }
    // When nothing after the commit can fail (no snapshot or weights to record, no
    // smoothing), the merge's pass over the cells also gathers the field's facts and writes
    // out, block by block while each is in the cache.
    const bool facts_in_merge = !opts.incremental && !opts.weights && opts.smoothing_length <= 0;
    block_facts.resize(static_cast<std::size_t>((ncell + detail::kCellBlock - 1) / detail::kCellBlock));
    FieldPass pass(*this, out.data());
    bool out_written = false;
    try {
      out_written = acc.commit(*arena, facts_in_merge ? &pass : nullptr);
    } catch (...) {  // the field may be half written: the next compute starts afresh
      acc.invalidate_kept();
      have_field = weights_kept = false;
      throw;
    }
    if (opts.incremental) record_snapshot(pa);
    if (opts.weights) record_volumes(pa);
    weights_kept = opts.weights;
    cell_weights.valid = false;
    rep.dropped_volume = acc.dropped();
    if (opts.smoothing_length > 0) {
      if (!faces) faces = std::make_unique<detail::FaceGraph>(detail::face_graph(mesh));
      const int iterations = detail::smooth_solid(*faces, mesh, opts.smoothing_length, acc.field(), smoothed);
      log->debug("smoothing_length={}: {} iterations", opts.smoothing_length, iterations);
    } else {
      smoothed.clear();
    }
    const FieldFacts facts = out_written ? pass.total() : field_facts(out.data());
    rep.deposited_volume = facts.sum;
    rep.clipped_volume = facts.clipped;
    overfull_cells = facts.overfull_cells;
    overfull_volume = facts.overfull_volume;
    if (mesh.kind() != MeshKind::polyhedral && !pa.shape_ids)
      rep.outside_particles = v.beyond;  // geometric on grids: the same count for every method
    else if (opts.incremental)
      rep.outside_particles = acc.outside_particles();
    have_field = true;
    report = rep;
    counted_particles = 0;
    for (const Scratch& sc : scratch) counted_particles += sc.counted;
    fused_pass = fused;  // validation and deposits in one pass
    ordered_blocks = arranged_blocks;
    if (log->should_log(spdlog::level::info))  // the note allocates: steady-state computes must not
      log->info("computed {} particles with {} on a {}{}: {} moved, {} sub-elements, {} on the fast path, {} outside",
                pa.n, to_string(opts.method), mesh.kind_name(), lattice_note(), acc.moved(), rep.sub_elements,
                rep.fast_path_particles, rep.outside_particles);
  }

  /// particle_order: pa, or a copy of it in slabs of the field (particle_order.hpp) where
  /// that may pay (arranged_blocks: how many). Null arrays and n <= 0, which compute
  /// refuses next, leave pa as it is.
  ParticleArrays arranged(const ParticleArrays& pa) {
    const std::int64_t layers = mesh.cartesian()     ? mesh.cartesian()->cells()[2]
                                : mesh.rectilinear() ? mesh.rectilinear()->cells()[2]
                                                     : 0;
    arranged_blocks = pa.n > 0 && pa.centres && pa.radii
                          ? detail::order_blocks(opts, pa, mesh.kind() == MeshKind::cartesian, mesh.cell_count(), layers)
                          : 0;
    if (arranged_blocks == 0) return pa;
    const Eigen::AlignedBox3d box = mesh.bounds();
    const ParticleArrays out = blocked_order.arrange(*arena, pa, box.min()[2], box.max()[2], arranged_blocks);
    if (!out.host_index) arranged_blocks = 0;  // a bad particle: validation names it
    return out;
  }

  /// How the polyMesh's box lattice served this compute ("" when it did not).
  std::string lattice_note() const {
    const detail::BoxLattice* l = mesh.lattice();
    if (!l) return "";
    std::ostringstream note;
    note << " (a lattice of " << l->cells[0] << " x " << l->cells[1] << " x " << l->cells[2] << " box cells, "
         << (l->cartesian ? "uniform" : "graded");
    if (opts.lattice)
      note << ": " << lattice_particles << " particles on the " << (l->cartesian ? "Cartesian" : "rectilinear")
           << " grid's path)";
    else
      note << ", not used: lattice=0)";
    return note.str();
  }

  /// Particle p as the drivers see it.
  detail::Particle particle(const ParticleArrays& pa, std::int64_t p) const {
    const double r = pa.radius(p);
    detail::Particle part{pa.host(p), mesh.wrap(pa.centre(p)), r, 0.0, pa.orientation(p), pa.rotation_key(p)};
    if (pa.shape_ids && !shapes[pa.shape_id(p)].is_sphere) {
      const RegisteredShape& sh = shapes[pa.shape_id(p)];
      part.volume = sh.shape.volume() * r * r * r;
      if (sh.variants) part.shape_template = (*sh.variants)[shape_variant(part.rotation_key)].get();
      part.centroid = sh.shape.centroid();
      part.shape = &sh.shape;
      part.shaped = true;
    } else {
      part.volume = sphere_volume(r);
    }
    part.outside = opts.outside;
    // outside=error with a tolerance: a particle within it of the mesh goes to the nearest cells.
    if (opts.outside == Outside::error && opts.outside_tolerance > 0 && within_tolerance(part))
      part.outside = Outside::nearest;
    return part;
  }

  /// Phase 1 with the mesh kind's context: particles turn into deposits.
  template <class MeshContext>
  void run(const MeshContext& ctx, detail::DriverFn<MeshContext> driver, const ParticleArrays& pa,
           const detail::AccumulationPlan& pl) {
    if (!driver)  // configure refuses this; a mesh kind without the driver never gets here
      throw Error(VFE_ERROR_UNSUPPORTED, "method=" + std::string(to_string(opts.method)) + " is not available on a " +
                                             mesh.kind_name() + "; " + detail::method_drivers(opts.method).instead);
    auto body = [&](Scratch& s, std::int64_t p) { driver(ctx, s, particle(pa, p)); };
    acc.deposit(*arena, scratch, pl, pa.n, body, [&](std::int64_t p) { return moved(pa, p); });
  }

  /// outside=error with a tolerance: true when the particle, shrunk by outside_tolerance,
  /// lies inside the mesh (a DEM wall contact, not an error). Exact on the grids (their
  /// domain is a box); on a polyMesh the shrunk ball's 26 probe points (axes, edges and
  /// corners of its cube, on its surface) must all lie in cells.
  bool within_tolerance(const detail::Particle& p) const {
    const double r = std::max(p.radius * (p.shaped ? 0.0 : 1.0) - opts.outside_tolerance, 0.0);
    if (mesh.kind() != MeshKind::polyhedral) {
      const Eigen::AlignedBox3d box = mesh.bounds();
      for (int d = 0; d < 3; ++d) {
        if ((mesh.periodic() >> d) & 1u) continue;
        if (p.centre[d] - r < box.min()[d] || p.centre[d] + r > box.max()[d]) return false;
      }
      return true;
    }
    const CellLocator& loc = *mesh.locator();
    for (int i = -1; i <= 1; ++i)
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          const Eigen::Vector3d dir(i, j, k);
          const Eigen::Vector3d x = dir.isZero() ? p.centre : Eigen::Vector3d(p.centre + r * dir.normalized());
          if (loc.locate(x) < 0) return false;
        }
    return true;
  }

  // --- incremental ------------------------------------------------------------------------

  bool snapshot_matches(const ParticleArrays& pa) const {
    return snapshot.with_shapes == (pa.shape_ids != nullptr) &&
           snapshot.with_orientations == (opts.orientation == Orientation::given);
  }

  /// True when particle p (kept from the last compute) must be redone.
  bool moved(const ParticleArrays& pa, std::int64_t p) const {
    if (!snapshot_matches(pa)) return true;
    const std::int64_t stride = snapshot.with_orientations ? 8 : 4;
    const double* old = &snapshot.particles[static_cast<std::size_t>(p * stride)];
    const Eigen::Vector3d c = pa.centre(p);
    const double tol = opts.move_tolerance;
    if (std::abs(c[0] - old[0]) > tol || std::abs(c[1] - old[1]) > tol || std::abs(c[2] - old[2]) > tol ||
        pa.radius(p) != old[3])
      return true;
    if (snapshot.with_orientations)
      for (int k = 0; k < 4; ++k)
        if (pa.orientation(p)[k] != old[4 + k]) return true;
    return snapshot.with_shapes && pa.shape_id(p) != snapshot.shape_ids[static_cast<std::size_t>(p)];
  }

  void record_snapshot(const ParticleArrays& pa) {
    const bool matches = snapshot_matches(pa);
    snapshot.with_shapes = pa.shape_ids != nullptr;
    snapshot.with_orientations = opts.orientation == Orientation::given;
    const std::int64_t stride = snapshot.with_orientations ? 8 : 4;
    snapshot.particles.resize(static_cast<std::size_t>(pa.n * stride));
    snapshot.shape_ids.resize(snapshot.with_shapes ? static_cast<std::size_t>(pa.n) : 0);
    auto record = [&](std::int64_t p) {
      double* st = &snapshot.particles[static_cast<std::size_t>(p * stride)];
      const Eigen::Vector3d c = pa.centre(p);
      for (int d = 0; d < 3; ++d) st[d] = c[d];
      st[3] = pa.radius(p);
      if (snapshot.with_orientations)
        for (int k = 0; k < 4; ++k) st[4 + k] = pa.orientation(p)[k];
      if (snapshot.with_shapes) snapshot.shape_ids[static_cast<std::size_t>(p)] = pa.shape_id(p);
    };
    if (!matches || acc.moved() == pa.n) {
      for (std::int64_t p = 0; p < pa.n; ++p) record(p);
    } else {
      for (const std::int64_t p : acc.moved_particles()) record(p);
    }
  }

  // --- weights ------------------------------------------------------------------------------

  void record_volumes(const ParticleArrays& pa) {
    particle_volumes.resize(static_cast<std::size_t>(pa.n));
    arena->execute([&] {
      tbb::parallel_for(std::int64_t(0), pa.n, [&](std::int64_t p) { particle_volumes[p] = particle_volume(pa, p); });
    });
  }

  void require_weights(const char* what) const {
    if (!have_field)
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  std::string(what) + " needs a successful compute first; call a compute with weights=1");
    if (!weights_kept || (acc.blocks().empty() && acc.kept_particles() > 0))
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  std::string(what) + " needs the weights of the last compute; set weights=1 before computing");
    if (static_cast<std::int64_t>(particle_volumes.size()) != acc.kept_particles())
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  std::string(what) + " needs the weights of the last compute; set weights=1 before computing");
  }

  /// Calls f(particle, cell, fraction) for every weight of every particle in particle order
  /// within [b*block, ...); the dropped slot is not a weight.
  template <class F>
  void for_block_weights(std::int64_t b, F&& f) const {
    const detail::DepositBlock& block = acc.blocks()[static_cast<std::size_t>(b)];
    const std::int64_t first = b * detail::kDepositBlock;
    const std::int64_t count = static_cast<std::int64_t>(block.offsets.size()) - 1;
    for (std::int64_t i = 0; i < count; ++i) {
      const double inv = 1.0 / particle_volumes[static_cast<std::size_t>(first + i)];
      for (std::uint32_t k = block.offsets[i]; k < block.offsets[i + 1]; ++k)
        if (block.deposits[k].cell != mesh.cell_count()) f(first + i, block.deposits[k].cell, block.deposits[k].volume * inv);
    }
  }

  void build_cell_weights() const {
    if (cell_weights.valid) return;
    const std::int64_t ncell = mesh.cell_count();
    const std::int64_t nblocks = static_cast<std::int64_t>(acc.blocks().size());
    CellWeights& w = cell_weights;
    w.offsets.assign(static_cast<std::size_t>(ncell + 1), 0);
    for (std::int64_t b = 0; b < nblocks; ++b)
      for_block_weights(b, [&](std::int64_t, std::int64_t c, double) { ++w.offsets[static_cast<std::size_t>(c + 1)]; });
    for (std::int64_t c = 0; c < ncell; ++c) w.offsets[c + 1] += w.offsets[c];
    w.particles.resize(static_cast<std::size_t>(w.offsets[ncell]));
    w.fractions.resize(w.particles.size());
    std::vector<std::int64_t> at(w.offsets.begin(), w.offsets.end() - 1);
    for (std::int64_t b = 0; b < nblocks; ++b)  // particle order: stable, deterministic sums
      for_block_weights(b, [&](std::int64_t p, std::int64_t c, double f) {
        const std::int64_t k = at[static_cast<std::size_t>(c)]++;
        w.particles[static_cast<std::size_t>(k)] = p;
        w.fractions[static_cast<std::size_t>(k)] = f;
      });
    w.valid = true;
  }

  /// deposit's loop: per cell c and component j, sum(c, j, terms) where terms(add) calls
  /// add(fraction, value) for the cell's particles in particle order.
  template <class Sum>
  void for_cell_sums(std::int64_t k, Sum&& sum, std::span<const double> values) const {
    build_cell_weights();
    const CellWeights& w = cell_weights;
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, mesh.cell_count(), 1024),
                        [&](const tbb::blocked_range<std::int64_t>& r) {
                          for (std::int64_t c = r.begin(); c < r.end(); ++c)
                            for (std::int64_t j = 0; j < k; ++j)
                              sum(c, j, [&](auto&& add) {
                                for (std::int64_t e = w.offsets[c]; e < w.offsets[c + 1]; ++e)
                                  add(w.fractions[e], values[w.particles[e] * k + j]);
                              });
                        });
    });
  }

  // --- reports --------------------------------------------------------------------------

  /// The counters of this compute from the threads' scratch. Throws the outside=error
  /// failure: callers call it before they change the field.
  Report gather_report(const ParticleArrays& pa, double particle_volume_sum) {
    Report rep{};
    lattice_particles = 0;
    auto_paths[0] = auto_paths[1] = auto_paths[2] = 0;
    located_cells = general_cells = 0;
    rep.particles = pa.n;
    rep.particle_volume = particle_volume_sum;
    rep.particle_grid_min = std::numeric_limits<std::int64_t>::max();
    std::int64_t first_error = std::numeric_limits<std::int64_t>::max();
    for (const Scratch& s : scratch) {
      rep.fast_path_particles += s.fast_path;
      rep.sub_elements += s.sub_elements;
      rep.outside_particles += s.outside_particles;
      lattice_particles += s.lattice_particles;
      auto_paths[0] += s.auto_fast;
      auto_paths[1] += s.auto_pmm;
      auto_paths[2] += s.auto_exact;
      located_cells += s.located_cells;
      general_cells += s.general_cells;
      rep.particle_grid_min = std::min(rep.particle_grid_min, s.grid_min);
      rep.particle_grid_max = std::max(rep.particle_grid_max, s.grid_max);
      first_error = std::min(first_error, s.first_error);
    }
    // Methods without sub-elements report 1 (a pmm compute of no particle reports 0).
    if (rep.particle_grid_max == 0) rep.particle_grid_min = rep.particle_grid_max = opts.method == Method::pmm ? 0 : 1;
    if (first_error != std::numeric_limits<std::int64_t>::max()) {
      const Eigen::Vector3d cp = pa.centre(first_error);
      const Eigen::AlignedBox3d box = mesh.bounds();
      std::ostringstream msg;
      msg.precision(9);
      msg << "particle " << first_error << " at (" << cp[0] << ", " << cp[1] << ", " << cp[2] << ") with radius "
          << pa.radius(first_error) << " reaches outside the mesh [" << box.min().transpose() << "] - ["
          << box.max().transpose() << "] (bounding box; " << std::max<std::int64_t>(rep.outside_particles, 1)
          << " particles do); enlarge the mesh or choose outside=nearest, centre or drop";
      throw Error(VFE_ERROR_OUT_OF_DOMAIN, msg.str());
    }
    return rep;
  }

  /// The field the host sees: the accumulator's, smoothed when smoothing_length > 0.
  const std::vector<double>& field() const { return smoothed.empty() ? acc.field() : smoothed; }
  /// The cells that may hold solid (null: any), of field().
  const std::vector<std::int64_t>* touched() const { return smoothed.empty() ? acc.touched() : nullptr; }

  /// Cells whose solid volume exceeds their volume (eps < 0) and that excess: a solver must
  /// not see them silently (a scene that does not match the mesh, cells smaller than the
  /// particles under a point method).
  std::int64_t overfull_cells = 0;
  double overfull_volume = 0;
  // Which paths the last compute took: pmm's particles counted per octant, and whether
  // validation and deposits ran as one pass.
  std::int64_t counted_particles = 0;
  bool fused_pass = false;
  bool projected_counts = false;  ///< pmm's counts took the template's projections on the bank
  /// The spheres' smallest and largest diameters the last compute's validation found: pmm's
  /// fused pass takes its bank from them and validates as it goes (compute).
  std::optional<std::pair<double, double>> last_diameters;
  /// Particles of the last compute that the box lattice's grid path took.
  std::int64_t lattice_particles = 0;
  /// method=auto: particles of the last compute on the fast path, pmm and exact.
  std::int64_t auto_paths[3] = {0, 0, 0};
  /// exact on a polyMesh: cut-cell overlaps of the last compute by the located sum and by
  /// the general formula.
  std::int64_t located_cells = 0, general_cells = 0;
  using FieldFacts = detail::FieldFacts;
  /// The facts of cells [begin, end) of f added to facts.
  void add_block_facts(const double* f, std::int64_t begin, std::int64_t end, FieldFacts& facts) const {
    if (const CartesianGrid* g = mesh.cartesian())
      detail::add_uniform_field_facts(f, begin, end, g->cell_volume(), opts.alpha_min, facts);
    else
      detail::add_field_facts(f, begin, end, [this](std::int64_t c) { return mesh.cell_volume(c); }, opts.alpha_min,
                              facts);
  }

  /// The facts of each block of the field (detail::kCellBlock cells), summed in block order
  /// afterwards: the same sums for any thread count.
  std::vector<FieldFacts> block_facts;
  /// The field's facts block by block, each block copied to out (when given) once added.
  class FieldPass final : public detail::CellPass {
   public:
    FieldPass(Impl& engine, double* out) : e_(engine), out_(out) {}
    void cells(std::int64_t block, std::int64_t begin, std::int64_t end, const double* field) override {
      FieldFacts& f = e_.block_facts[static_cast<std::size_t>(block)];
      f = FieldFacts{};
      e_.add_block_facts(field, begin, end, f);
      if (out_) std::copy(field + begin, field + end, out_ + begin);
    }
    FieldFacts total() const {
      FieldFacts t;
      for (const FieldFacts& f : e_.block_facts) t.add(f);
      return t;
    }

   private:
    Impl& e_;
    double* out_;
  };

  /// The facts of field() (over the touched cells when it lists them: the others hold no
  /// solid), and field() copied to out when given.
  FieldFacts field_facts(double* out) {
    const std::vector<double>& f = field();
    if (const auto* cells = touched()) {
      FieldFacts facts;
      for (const std::int64_t c : *cells) add_block_facts(f.data(), c, c + 1, facts);
      if (out) std::copy(f.begin(), f.end(), out);
      return facts;
    }
    const std::int64_t ncell = static_cast<std::int64_t>(f.size());
    block_facts.resize(static_cast<std::size_t>((ncell + detail::kCellBlock - 1) / detail::kCellBlock));
    FieldPass pass(*this, out);
    arena->execute([&] {
      tbb::parallel_for(std::size_t(0), block_facts.size(), [&](std::size_t b) {
        const std::int64_t begin = std::int64_t(b) * detail::kCellBlock;
        pass.cells(std::int64_t(b), begin, std::min(ncell, begin + detail::kCellBlock), f.data());
      });
    });
    return pass.total();
  }
};

// --- the facade ------------------------------------------------------------------------------

namespace {

void check_size(std::size_t size, std::int64_t expected, const char* what, const char* per) {
  if (static_cast<std::int64_t>(size) != expected)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, std::string(what) + " has " + std::to_string(size) + " values but needs " +
                                                std::to_string(expected) + " (" + per + "); pass a buffer of that size");
}

PolyMeshData polymesh_data_of(const PolyMeshArrays& a) {
  auto fail = [](const std::string& what) {
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "polyMesh arrays: " + what);
  };
  if (a.n_points < 0 || a.n_faces < 0 || a.n_internal_faces < 0 || a.n_internal_faces > a.n_faces)
    fail("counts must satisfy n_points >= 0 and 0 <= n_internal_faces <= n_faces");
  if ((a.n_points > 0 && !a.points) || (a.n_faces > 0 && (!a.face_offsets || !a.owner)) ||
      (a.n_internal_faces > 0 && !a.neighbour))
    fail("points, face_offsets, owner or neighbour is NULL; pass arrays of the documented sizes");
  if (a.n_faces > 0 && a.face_offsets[0] != 0) fail("face_offsets[0] must be 0");
  PolyMeshData m;
  m.points.resize(static_cast<std::size_t>(a.n_points));
  for (std::int64_t i = 0; i < a.n_points; ++i)
    m.points[i] = Eigen::Vector3d(a.points[3 * i], a.points[3 * i + 1], a.points[3 * i + 2]);
  m.face_offsets.assign(a.face_offsets, a.face_offsets + a.n_faces + 1);
  for (std::int64_t f = 0; f < a.n_faces; ++f)
    if (m.face_offsets[f + 1] < m.face_offsets[f] + 3)
      fail("face " + std::to_string(f) + " has fewer than 3 points (face_offsets must increase by at least 3)");
  const std::int64_t n_face_points = a.n_faces > 0 ? m.face_offsets.back() : 0;
  if (n_face_points > 0 && !a.face_points) fail("face_points is NULL");
  m.face_points.assign(a.face_points, a.face_points + n_face_points);
  for (const std::int64_t q : m.face_points)
    if (q < 0 || q >= a.n_points) fail("a face point label " + std::to_string(q) + " is not in [0, n_points)");
  m.owner.assign(a.owner, a.owner + a.n_faces);
  m.neighbour.assign(a.neighbour, a.neighbour + a.n_internal_faces);
  PolyPatch boundary;
  boundary.name = "boundary";
  boundary.type = "patch";
  boundary.start_face = a.n_internal_faces;
  boundary.n_faces = a.n_faces - a.n_internal_faces;
  if (boundary.n_faces > 0) m.patches.push_back(boundary);
  m.source = "(arrays)";
  return m;
}

}  // namespace

Engine::Engine(const CartesianGridSpec& grid) : impl_(std::make_unique<Impl>(grid)) {}
Engine::Engine(const PolyMeshSpec& mesh)
    : impl_(std::make_unique<Impl>(std::make_unique<PolyMesh>(PolyMesh::read(mesh.dir)))) {}
Engine::Engine(const RectilinearGridSpec& grid) : impl_(std::make_unique<Impl>(RectilinearGrid(grid.nodes))) {}
Engine::Engine(const PolyMeshArrays& mesh)
    : impl_(std::make_unique<Impl>(std::make_unique<PolyMesh>(polymesh_data_of(mesh)))) {}
Engine::~Engine() = default;

void Engine::configure(std::string_view options) {
  UseGuard guard(impl_->busy);
  Options next = parse_options(options, impl_->opts);
  const detail::MethodDrivers& row = detail::method_drivers(next.method);
  const bool available = impl_->mesh.kind() == MeshKind::cartesian     ? row.cartesian != nullptr
                         : impl_->mesh.kind() == MeshKind::rectilinear ? row.rectilinear != nullptr
                                                                       : row.polyhedral != nullptr;
  if (!available)
    throw Error(VFE_ERROR_UNSUPPORTED, "method=" + std::string(to_string(next.method)) + " is not available on a " +
                                           impl_->mesh.kind_name() + "; " + row.instead);
  if (next.periodic && impl_->mesh.kind() == MeshKind::polyhedral)
    throw Error(VFE_ERROR_UNSUPPORTED,
                "periodic axes are available on Cartesian and rectilinear grids only; an OpenFOAM polyMesh's "
                "cyclic patches are not supported (use periodic=none)");
  if (next.touched_only && next.incremental)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "touched_only=1 and incremental=1 do not combine: incremental already updates only the cells of the "
                "particles that moved; choose one of them");
  if (next.touched_only && next.accumulation == Accumulation::atomic && !next.deterministic)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "touched_only=1 lists the touched cells in per-thread fields and does not combine with "
                "accumulation=atomic; use accumulation=private, sorted or auto");
  if (next.deterministic && (next.accumulation == Accumulation::privatised || next.accumulation == Accumulation::atomic))
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "deterministic=1 sums every cell in fixed point from per-block deposit lists; accumulation=" +
                    option_value(next, "accumulation") + " adds doubles in whatever order threads run: use "
                    "accumulation=auto or sorted with deterministic=1");
  const bool new_arena = next.threads != impl_->opts.threads;
  if (next.periodic != impl_->mesh.periodic()) impl_->faces.reset();  // the face graph wraps with the axes
  impl_->mesh.set_periodic(next.periodic);
  impl_->opts = next;
  impl_->acc.invalidate_kept();  // deposits kept by incremental=1 may no longer hold
  if (new_arena) impl_->make_arena();
  impl_->log->set_level(spdlog::level::from_str(next.log_level));
  // The report's clipped volume follows alpha_min, as vfe_void_fraction does.
  if (impl_->have_field) impl_->report.clipped_volume = impl_->field_facts(nullptr).clipped;
}

std::string Engine::option(std::string_view key) const { return option_value(impl_->opts, key); }
std::string Engine::options() const { return format_options(impl_->opts); }
std::int64_t Engine::cell_count() const { return impl_->mesh.cell_count(); }
bool Engine::is_polymesh() const { return impl_->mesh.kind() != MeshKind::cartesian; }

void Engine::cell_volumes(std::span<double> out) const {
  check_size(out.size(), cell_count(), "output", "one per cell");
  for (std::int64_t c = 0; c < cell_count(); ++c) out[c] = impl_->mesh.cell_volume(c);
}

void Engine::cell_centres(std::span<double> out) const {
  check_size(out.size(), 3 * cell_count(), "output", "3 per cell");
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    const Eigen::Vector3d x = impl_->mesh.cell_centre(c);
    for (int d = 0; d < 3; ++d) out[3 * c + d] = x[d];
  }
}

void Engine::locate(std::span<const double> points, std::span<std::int64_t> cells) const {
  check_size(points.size(), 3 * static_cast<std::int64_t>(cells.size()), "points", "3 per point");
  const detail::EngineMesh& m = impl_->mesh;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const Eigen::Vector3d x(points[3 * i], points[3 * i + 1], points[3 * i + 2]);
    cells[i] = m.cartesian()     ? m.cartesian()->locate(m.wrap(x))
               : m.rectilinear() ? m.rectilinear()->locate(m.wrap(x))
                                 : m.locator()->locate(x);
  }
}

PolyMeshBuffers read_polymesh_buffers(const std::string& dir) {
  const PolyMeshData m = read_polymesh(dir);
  PolyMeshBuffers b;
  b.points.reserve(3 * m.points.size());
  for (const Eigen::Vector3d& p : m.points) b.points.insert(b.points.end(), {p[0], p[1], p[2]});
  b.face_offsets = m.face_offsets;
  b.face_points = m.face_points;
  b.owner = m.owner;
  b.neighbour = m.neighbour;
  for (const PolyPatch& p : m.patches) b.patches.push_back({p.name, p.type, p.start_face, p.n_faces});
  return b;
}

std::vector<std::int64_t> read_polymesh_labels(const std::string& dir, const std::string& name) {
  return read_label_list_file(dir, name);
}

Engine::PolyTopology Engine::poly_topology() const {
  std::unique_ptr<PolyMesh> built = impl_->mesh.polyhedra();
  const PolyMesh* mesh = built ? built.get() : impl_->mesh.polyhedral();
  if (!mesh) throw Error(VFE_ERROR_INVALID_ARGUMENT, "poly_topology: this engine is on a Cartesian grid");
  const PolyMesh& m = *mesh;
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

void Engine::compute(const ParticleView& particles, std::span<double> out) {
  UseGuard guard(impl_->busy);
  impl_->compute(arrays_of(particles), out);
}

void Engine::compute(const vfe_particles& particles, std::span<double> out) {
  UseGuard guard(impl_->busy);
  impl_->compute(arrays_of(particles), out);
}

void Engine::void_fraction(std::span<double> out) const {
  UseGuard guard(impl_->busy);
  check_size(out.size(), cell_count(), "output", "one per cell");
  const double alpha_min = impl_->opts.alpha_min;
  const std::vector<double>& solid = impl_->field();
  for (std::int64_t c = 0; c < cell_count(); ++c) {
    const double eps = 1.0 - solid[static_cast<std::size_t>(c)] / impl_->mesh.cell_volume(c);
    out[c] = alpha_min > 0 && eps < alpha_min ? alpha_min : eps;
  }
}

const Report& Engine::last_report() const { return impl_->report; }

namespace detail {

bool report_field(const Report& r, std::string_view key, double& value) noexcept {
  const std::pair<std::string_view, double> fields[] = {
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
  };
  for (const auto& [name, v] : fields)
    if (key == name) {
      value = v;
      return true;
    }
  return false;
}

}  // namespace detail

double Engine::last_report_value(std::string_view key) const {
  double field = 0;
  if (detail::report_field(impl_->report, key, field)) return field;
  const std::vector<std::int64_t>* touched = impl_->touched();
  const std::pair<const char*, double> facts[] = {
      {"moved_particles", double(impl_->have_field ? impl_->acc.moved() : 0)},
      {"touched_cells", impl_->have_field && touched ? double(touched->size()) : -1.0},
      {"overfull_cells", double(impl_->overfull_cells)},
      {"overfull_volume", impl_->overfull_volume},
      {"counted_particles", double(impl_->counted_particles)},
      {"fused_pass", impl_->fused_pass ? 1.0 : 0.0},
      {"binned_regions", double(impl_->have_field ? impl_->acc.binned_regions() : 0)},
      {"projected_counts", impl_->have_field && impl_->projected_counts ? 1.0 : 0.0},
      {"ordered_blocks", double(impl_->have_field ? impl_->ordered_blocks : 0)},
      {"lattice_cells", impl_->mesh.lattice() ? double(impl_->mesh.cell_count()) : 0.0},
      {"lattice_particles", double(impl_->have_field ? impl_->lattice_particles : 0)},
      {"auto_fast", double(impl_->have_field ? impl_->auto_paths[0] : 0)},
      {"auto_pmm", double(impl_->have_field ? impl_->auto_paths[1] : 0)},
      {"auto_exact", double(impl_->have_field ? impl_->auto_paths[2] : 0)},
      {"exact_located_cells", double(impl_->have_field ? impl_->located_cells : 0)},
      {"exact_general_cells", double(impl_->have_field ? impl_->general_cells : 0)},
  };
  std::string known = "the vfe_report fields";
  for (const auto& [name, value] : facts) {
    if (key == name) return value;
    known += ", " + std::string(name);
  }
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "unknown report key '" + std::string(key.substr(0, 64)) +
                                              "'; known keys: " + known);
}

std::int32_t Engine::add_shape(std::string_view spec) {
  UseGuard guard(impl_->busy);
  Impl::RegisteredShape sh{parse_shape_spec(spec), false, 0, nullptr, 0, 0, 0};
  sh.is_sphere = sh.shape.kind() == kernels::Shape::Kind::sphere;
  sh.eq_diameter = std::cbrt(6.0 * sh.shape.volume() / std::numbers::pi);
  impl_->shapes.push_back(std::move(sh));
  impl_->acc.invalidate_kept();
  return static_cast<std::int32_t>(impl_->shapes.size() - 1);
}

double Engine::shape_volume(std::int32_t id) const {
  if (id < 0 || id >= static_cast<std::int32_t>(impl_->shapes.size()))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "shape id " + std::to_string(id) + " is not registered");
  return impl_->shapes[id].shape.volume();
}

double Engine::shape_reach(std::int32_t id) const {
  shape_volume(id);  // checks the id
  const kernels::Shape& shape = impl_->shapes[id].shape;
  if (shape.kind() == kernels::Shape::Kind::sphere) return 1.0;
  const Eigen::AlignedBox3d& b = shape.bounds();
  return b.min().cwiseAbs().cwiseMax(b.max().cwiseAbs()).norm();
}

std::int64_t Engine::particle_grid_for(double diameter, double cell_size) const {
  const Options& o = impl_->opts;
  std::int64_t n = o.particle_grid;
  if (n == 0) {
    const detail::AutoRule rule = detail::TemplateCache::auto_rule(o, cell_size);
    n = detail::auto_particle_count(detail::auto_step(diameter, cell_size * cell_size * cell_size, rule), rule);
  }
  return static_cast<std::int64_t>(impl_->templates.get(o, n).size());
}

void Engine::set_log_callback(vfe_log_fn fn, void* user) {
  UseGuard guard(impl_->busy);
  const auto level = impl_->log->level();
  spdlog::sink_ptr sink = fn ? spdlog::sink_ptr(std::make_shared<CallbackSink>(fn, user))
                             : spdlog::sink_ptr(std::make_shared<spdlog::sinks::stderr_sink_mt>());
  impl_->log = std::make_shared<spdlog::logger>("vfe", std::move(sink));
  impl_->log->set_level(level);
}

Engine::WeightsSize Engine::weights_size() const {
  impl_->require_weights("weights");
  WeightsSize size{impl_->acc.kept_particles(), 0};
  const std::int64_t nblocks = static_cast<std::int64_t>(impl_->acc.blocks().size());
  for (std::int64_t b = 0; b < nblocks; ++b)
    impl_->for_block_weights(b, [&](std::int64_t, std::int64_t, double) { ++size.entries; });
  return size;
}

void Engine::weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells, std::span<double> fractions) const {
  const WeightsSize size = weights_size();
  check_size(offsets.size(), size.particles + 1, "offsets", "one per particle plus one");
  check_size(cells.size(), size.entries, "cells", "one per weight entry");
  check_size(fractions.size(), size.entries, "fractions", "one per weight entry");
  std::int64_t k = 0, last = -1;
  offsets[0] = 0;
  const std::int64_t nblocks = static_cast<std::int64_t>(impl_->acc.blocks().size());
  for (std::int64_t b = 0; b < nblocks; ++b)
    impl_->for_block_weights(b, [&](std::int64_t p, std::int64_t c, double f) {
      for (; last < p; ++last) offsets[last + 1] = k;
      cells[k] = c;
      fractions[k] = f;
      ++k;
    });
  for (; last < size.particles; ++last) offsets[last + 1] = k;
}

void Engine::deposit(std::int32_t components, std::span<const double> values, std::span<double> out) const {
  impl_->require_weights("deposit");
  if (components < 1 || components > 64)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "components is " + std::to_string(components) + "; give 1 to 64");
  const std::int64_t k = components, ncell = cell_count(), n = impl_->acc.kept_particles();
  check_size(values.size(), n * k, "values", "components per particle of the last compute");
  check_size(out.size(), ncell * k, "output", "components per cell");
  if (impl_->opts.deterministic) {  // fixed point: the same sums in any particle order
    std::vector<int> exponents(static_cast<std::size_t>(k));
    for (std::int64_t j = 0; j < k; ++j) {
      double largest = 0;
      for (std::int64_t p = 0; p < n; ++p) largest = std::max(largest, std::abs(values[p * k + j]));
      exponents[j] = fixed_unit_exponent(largest);
    }
    std::vector<FixedSum> sums(out.size());
    deposit_fixed(components, values, exponents, sums);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = from_fixed(sums[i], exponents[i % k]);
    return;
  }
  impl_->for_cell_sums(k, [&](std::int64_t c, std::int64_t j, auto&& terms) {
    double sum = 0;  // particle order
    terms([&](double f, double v) { sum += f * v; });
    out[c * k + j] = sum;
  }, values);
}

void Engine::deposit_fixed(std::int32_t components, std::span<const double> values, std::span<const int> exponents,
                           std::span<FixedSum> out) const {
  impl_->require_weights("deposit");
  const std::int64_t k = components, n = impl_->acc.kept_particles();
  check_size(values.size(), n * k, "values", "components per particle of the last compute");
  check_size(out.size(), cell_count() * k, "output", "components per cell");
  check_size(exponents.size(), k, "exponents", "one per component");
  for (std::int64_t p = 0; p < n; ++p)  // beyond 2^-80 x 2^127 the sums could overflow
    for (std::int64_t j = 0; j < k; ++j)
      if (!(std::abs(values[p * k + j]) < std::ldexp(1.0, exponents[j] + 81)))
        throw Error(VFE_ERROR_INVALID_ARGUMENT, "value " + std::to_string(j) + " of particle " + std::to_string(p) +
                                                    " is not finite or exceeds the largest magnitude the fixed-point "
                                                    "sums were scaled for; pass finite values");
  impl_->for_cell_sums(k, [&](std::int64_t c, std::int64_t j, auto&& terms) {
    FixedSum sum = 0;
    terms([&](double f, double v) { sum += detail::to_fixed(f * v, exponents[j]); });
    out[c * k + j] = sum;
  }, values);
}

void Engine::set_deterministic_volume(double largest_particle_volume) {
  impl_->deterministic_volume_bound = largest_particle_volume > 0 ? largest_particle_volume : 0;
}

double Engine::largest_particle_volume(const vfe_particles& particles) const {
  const ParticleArrays pa = arrays_of(particles);
  const auto nshapes = static_cast<std::int32_t>(impl_->shapes.size());
  double largest = 0;
  for (std::int64_t p = 0; p < pa.n; ++p) {
    if (pa.shape_ids && (pa.shape_id(p) < 0 || pa.shape_id(p) >= nshapes)) continue;
    const double v = impl_->particle_volume(pa, p);
    if (v < 1e300) largest = std::max(largest, v);  // as validation: NaN and overflow are refused there
  }
  return largest;
}

Engine::FixedField Engine::fixed_solid() const {
  if (impl_->acc.fixed_field().empty() && cell_count() > 0)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "no fixed-point field: compute with deterministic=1 first");
  return {impl_->acc.fixed_field(), impl_->acc.fixed_exponent()};
}

void Engine::interpolate(std::int32_t components, std::span<const double> cell_field, std::span<double> out) const {
  impl_->require_weights("interpolate");
  if (components < 1 || components > 64)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "components is " + std::to_string(components) + "; give 1 to 64");
  const std::int64_t k = components, ncell = cell_count(), n = impl_->acc.kept_particles();
  check_size(cell_field.size(), ncell * k, "cell_field", "components per cell");
  check_size(out.size(), n * k, "output", "components per particle of the last compute");
  const std::int64_t nblocks = static_cast<std::int64_t>(impl_->acc.blocks().size());
  impl_->arena->execute([&] {
    tbb::parallel_for(std::int64_t(0), nblocks, [&](std::int64_t b) {
      const std::int64_t first = b * detail::kDepositBlock, last = std::min(n, first + detail::kDepositBlock);
      for (std::int64_t p = first; p < last; ++p)
        for (std::int64_t j = 0; j < k; ++j) out[p * k + j] = 0;
      // Weighted sums, then normalised by each particle's covered share.
      std::vector<double> share(static_cast<std::size_t>(last - first), 0.0);
      impl_->for_block_weights(b, [&](std::int64_t p, std::int64_t c, double f) {
        share[static_cast<std::size_t>(p - first)] += f;
        for (std::int64_t j = 0; j < k; ++j) out[p * k + j] += f * cell_field[c * k + j];
      });
      for (std::int64_t p = first; p < last; ++p) {
        const double s = share[static_cast<std::size_t>(p - first)];
        for (std::int64_t j = 0; j < k; ++j) out[p * k + j] = s > 0 ? out[p * k + j] / s : 0.0;
      }
    });
  });
}

}  // namespace vfe
