#include <vfe/engine.hpp>

#include "cartesian_grid.hpp"
#include "options.hpp"

#include <vfe/kernels/particle_template.hpp>
#include <vfe/kernels/sphere_box_overlap.hpp>

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
#include <sstream>

namespace vfe {

namespace {

using kernels::ParticleTemplate;

struct Deposit {
  std::int64_t cell;
  double volume;
};

/// Largest particle grid `auto` may choose (a particle 8x larger than its cell).
constexpr std::int64_t kMaxAutoGrid = 5 * 27 * 512;
/// Particles per block of the deterministic (sorted) accumulation: fixed, so the
/// summation order never depends on the thread count.
constexpr std::int64_t kSortedBlock = 512;

/// Per-thread working memory, allocated once and reused by every particle.
struct Scratch {
  std::vector<Deposit> deposits;  // one particle's deposits, merged by cell
  std::vector<double> nodes[3], orthant, patch;  // exact method
  std::vector<double> window;                    // pmm: volume per cell of the particle's window
  std::int64_t fast_path = 0, sub_elements = 0, outside_particles = 0;
  std::int64_t first_error = std::numeric_limits<std::int64_t>::max();
  std::int64_t grid_min = std::numeric_limits<std::int64_t>::max(), grid_max = 0;

  void reset_counters() {
    fast_path = sub_elements = outside_particles = grid_max = 0;
    first_error = grid_min = std::numeric_limits<std::int64_t>::max();
  }

  void add(std::int64_t cell, double v) {
    // A particle touches a handful of cells: a backward linear search is the cheapest merge.
    for (auto it = deposits.rbegin(); it != deposits.rend(); ++it)
      if (it->cell == cell) {
        it->volume += v;
        return;
      }
    deposits.push_back({cell, v});
  }
};

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
  tbb::enumerable_thread_specific<std::vector<double>> private_fields;
  std::vector<std::vector<Deposit>> blocks;       // sorted accumulation
  std::vector<std::pair<std::int64_t, std::int64_t>> sort_keys;  // (cell, sequence)
  std::vector<double> sort_values;

  std::map<std::pair<int, std::int64_t>, std::unique_ptr<ParticleTemplate>> template_cache;
  std::vector<const ParticleTemplate*> bank;  // by (auto step - bank_first)
  std::int64_t bank_first = 0;

  explicit Impl(const CartesianGridSpec& spec) : grid(spec) {
    log = std::make_shared<spdlog::logger>("vfe", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    log->set_level(spdlog::level::warn);
    make_arena();
    solid.reserve(grid.cell_count() + 1);
    work.reserve(grid.cell_count() + 1);
    solid.assign(grid.cell_count(), 0.0);
  }

  void make_arena() {
    arena = std::make_unique<tbb::task_arena>(opts.threads > 0 ? opts.threads : +tbb::task_arena::automatic);
  }

  // --- particle grid ------------------------------------------------------------------

  /// auto: 5 * ceil(27 / chi^3) (DESIGN section 5's default criterion), in steps of 5.
  std::int64_t auto_steps(double diameter) const { return auto_steps(diameter, grid.cell_volume()); }
  static std::int64_t auto_steps(double diameter, double cell_volume) {
    const double x = 27.0 * diameter * diameter * diameter / cell_volume;
    const double k = std::ceil(x * (1.0 - 1e-12));
    return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::min(k, 1e9)), 1, kMaxAutoGrid / 5);
  }

  const ParticleTemplate& get_template(std::int64_t n) {
    const int family = static_cast<int>(opts.template_family);
    auto& slot = template_cache[{family, n}];
    if (!slot) {
      const int ni = static_cast<int>(n);
      slot = std::make_unique<ParticleTemplate>(opts.template_family == TemplateFamily::spherical
                                                    ? kernels::make_spherical_template(ni)
                                                    : kernels::make_fibonacci_template(ni));
      log->debug("built {} template for particle_grid={}: {} sub-elements", slot->family, n, slot->size());
    }
    return *slot;
  }

  void prepare_templates(const Validation& v) {
    bank.clear();
    if (opts.method != Method::pmm) return;
    if (opts.particle_grid > 0) {
      bank_first = 0;
      bank.push_back(&get_template(opts.particle_grid));
      return;
    }
    bank_first = auto_steps(v.d_min);
    const std::int64_t last = auto_steps(v.d_max);
    for (std::int64_t k = bank_first; k <= last; ++k) bank.push_back(&get_template(5 * k));
  }

  const ParticleTemplate& template_for(double diameter) const {
    if (opts.particle_grid > 0) return *bank.front();
    return *bank[static_cast<std::size_t>(auto_steps(diameter) - bank_first)];
  }

  // --- validation ---------------------------------------------------------------------

  Validation validate(const ParticleView& pv, std::int64_t cs, std::int64_t rs, std::int64_t qs) {
    const bool need_q = opts.orientation == Orientation::given;
    auto bad_particle = [&](std::int64_t p) {
      const double* c = pv.centres + p * cs;
      const double r = pv.radii[p * rs];
      if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2])) return true;
      if (!(r > 0) || !std::isfinite(r)) return true;
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
        msg << "radius " << pv.radii[p * rs] << " is not a finite number > 0; pass positive radii";
      else
        msg << "orientation quaternion is zero or not finite; pass unit quaternions (w, x, y, z) "
               "or use orientation=random";
      throw Error(VFE_ERROR_INVALID_ARGUMENT, msg.str());
    }
    return v;
  }

  // --- per-particle kernels -------------------------------------------------------------

  /// Volume that lies outside the mesh, handled by the `outside` policy. nearest_cell is
  /// the mesh cell nearest to where the volume is.
  void outside(Scratch& s, std::int64_t p, double volume, std::int64_t nearest_cell,
               const Eigen::Vector3d& centre, bool& flagged) {
    if (!flagged) {
      flagged = true;
      ++s.outside_particles;
    }
    switch (opts.outside) {
      case Outside::nearest: s.add(nearest_cell, volume); break;
      case Outside::centre: s.add(grid.nearest(centre), volume); break;
      case Outside::drop: s.add(grid.cell_count(), volume); break;  // the dropped-volume slot
      case Outside::error: s.first_error = std::min(s.first_error, p); break;
    }
  }

  /// The one cell wholly holding the sphere, or -1.
  std::int64_t single_cell(const Eigen::Vector3d& c, double r) const {
    std::int64_t idx[3];
    for (int d = 0; d < 3; ++d) {
      const std::int64_t lo = grid.axis_index(d, c[d] - r);
      if (lo != grid.axis_index(d, c[d] + r) || lo < 0 || lo >= grid.cells()[d]) return -1;
      idx[d] = lo;
    }
    return grid.index(idx[0], idx[1], idx[2]);
  }

  void direct_particle(Scratch& s, std::int64_t p, const Eigen::Vector3d& c, double volume) {
    ++s.sub_elements;
    const std::int64_t cell = grid.locate(c);
    bool flagged = false;
    if (cell >= 0)
      s.add(cell, volume);
    else
      outside(s, p, volume, grid.nearest(c), c, flagged);
  }

  void pmm_particle(Scratch& s, std::int64_t p, const Eigen::Vector3d& c, double r, double volume,
                    const double* q) {
    const ParticleTemplate& t = template_for(2 * r);
    const std::int64_t n = static_cast<std::int64_t>(t.size());
    s.grid_min = std::min(s.grid_min, n);
    s.grid_max = std::max(s.grid_max, n);
    if (const std::int64_t cell = single_cell(c, r); cell >= 0) {
      ++s.fast_path;
      s.add(cell, volume);
      return;
    }
    s.sub_elements += n;
    Eigen::Matrix3d rotation;
    switch (opts.orientation) {
      case Orientation::none: rotation.setIdentity(); break;
      case Orientation::random: rotation = kernels::random_rotation(std::uint64_t(p), opts.seed); break;
      case Orientation::given: rotation = kernels::rotation_from_quaternion(q); break;
    }
    // Map template points straight to cell units relative to the window of cells the
    // particle can reach, so locating is a truncation and a clamp per axis and deposits
    // accumulate without a search.
    const Window w = window(c, r * t.reach);
    const Eigen::Vector3d inv_h = grid.spacing().cwiseInverse();
    const Eigen::Matrix3d to_cells = inv_h.asDiagonal() * rotation * r;
    Eigen::Vector3d base;
    for (int d = 0; d < 3; ++d) base[d] = grid.axis_coordinate(d, c[d]) - double(w.lo[d]);
    if (base.cwiseAbs().maxCoeff() > 0x1p40) {  // absurdly far from the mesh: one point
      bool flagged = false;
      outside(s, p, volume, grid.nearest(c), c, flagged);
      return;
    }
    s.window.assign(static_cast<std::size_t>(w.m[0] * w.m[1] * w.m[2]), 0.0);
    const std::int64_t m0 = w.m[0], m1 = w.m[1], m2 = w.m[2];
    kernels::pmm_deposit(
        t, base, to_cells, volume,
        [m0, m1, m2](const Eigen::Vector3d& x) {
          // Truncation equals floor after the clamp at 0 (x > -2^40 here).
          const std::int64_t i = std::clamp<std::int64_t>(static_cast<std::int64_t>(x[0]), 0, m0 - 1);
          const std::int64_t j = std::clamp<std::int64_t>(static_cast<std::int64_t>(x[1]), 0, m1 - 1);
          const std::int64_t k = std::clamp<std::int64_t>(static_cast<std::int64_t>(x[2]), 0, m2 - 1);
          return i + m0 * (j + m1 * k);
        },
        [&s](std::int64_t local, const Eigen::Vector3d&, double v) { s.window[local] += v; });
    emit_window(s, p, w, c);
  }

  /// Cells a sphere of the given reach around c can touch, clamped to one layer of
  /// virtual cells around the mesh (coordinates -1 and n stand for "beyond this side").
  struct Window {
    std::int64_t lo[3];
    std::int64_t m[3];
  };
  Window window(const Eigen::Vector3d& c, double reach) const {
    Window w;
    for (int d = 0; d < 3; ++d) {
      const std::int64_t n = grid.cells()[d];
      w.lo[d] = std::clamp<std::int64_t>(grid.axis_index(d, c[d] - reach), -1, n);
      w.m[d] = std::clamp<std::int64_t>(grid.axis_index(d, c[d] + reach), -1, n) - w.lo[d] + 1;
    }
    return w;
  }

  /// Turns a particle's window into deposits: cells of the mesh first (distinct, no
  /// search), then the virtual cells beyond the mesh through the outside policy.
  void emit_window(Scratch& s, std::int64_t p, const Window& w, const Eigen::Vector3d& c) {
    bool any_outside = false;
    std::size_t local = 0;
    for (std::int64_t k = 0; k < w.m[2]; ++k)
      for (std::int64_t j = 0; j < w.m[1]; ++j)
        for (std::int64_t i = 0; i < w.m[0]; ++i, ++local) {
          const double v = s.window[local];
          if (v == 0.0) continue;
          const std::int64_t gi = w.lo[0] + i, gj = w.lo[1] + j, gk = w.lo[2] + k;
          if (gi < 0 || gj < 0 || gk < 0 || gi >= grid.cells()[0] || gj >= grid.cells()[1] || gk >= grid.cells()[2])
            any_outside = true;
          else
            s.deposits.push_back({grid.index(gi, gj, gk), v});
        }
    if (!any_outside) return;
    bool flagged = false;
    local = 0;
    for (std::int64_t k = 0; k < w.m[2]; ++k)
      for (std::int64_t j = 0; j < w.m[1]; ++j)
        for (std::int64_t i = 0; i < w.m[0]; ++i, ++local) {
          const double v = s.window[local];
          const std::int64_t g[3] = {w.lo[0] + i, w.lo[1] + j, w.lo[2] + k};
          bool out = false;
          for (int d = 0; d < 3; ++d) out |= g[d] < 0 || g[d] >= grid.cells()[d];
          if (v == 0.0 || !out) continue;
          outside(s, p, v, grid.index(grid.clamp_axis(0, g[0]), grid.clamp_axis(1, g[1]), grid.clamp_axis(2, g[2])),
                  c, flagged);
        }
  }

  void exact_particle(Scratch& s, std::int64_t p, const Eigen::Vector3d& c, double r, double volume) {
    if (const std::int64_t cell = single_cell(c, r); cell >= 0) {
      ++s.fast_path;
      s.add(cell, volume);
      return;
    }
    std::int64_t lo[3], hi[3];
    bool empty = false;
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::max<std::int64_t>(grid.axis_index(d, c[d] - r), 0);
      hi[d] = std::min<std::int64_t>(grid.axis_index(d, c[d] + r), grid.cells()[d] - 1);
      if (lo[d] > hi[d]) empty = true;
    }
    bool flagged = false;
    if (empty) {
      outside(s, p, volume, grid.nearest(c), c, flagged);
      return;
    }
    int m[3];
    for (int d = 0; d < 3; ++d) {
      m[d] = static_cast<int>(hi[d] - lo[d] + 1);
      s.nodes[d].resize(m[d] + 1);
      for (int i = 0; i <= m[d]; ++i)
        s.nodes[d][i] = grid.origin()[d] + double(lo[d] + i) * grid.spacing()[d];
    }
    s.sub_elements += std::int64_t(m[0]) * m[1] * m[2];
    double inside = 0;
    kernels::sphere_patch_overlaps(c, r, s.nodes[0].data(), m[0], s.nodes[1].data(), m[1],
                                   s.nodes[2].data(), m[2], s.orthant, s.patch,
                                   [&](int i, int j, int k, double v) {
                                     s.add(grid.index(lo[0] + i, lo[1] + j, lo[2] + k), v);
                                     inside += v;
                                   });
    // What the patch misses lies outside the mesh (beyond round-off).
    const double rest = volume - inside;
    if (rest > 1e-12 * volume) outside(s, p, rest, grid.nearest(c), c, flagged);
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
    return double(grid.cell_count()) * threads <= 8.0 * double(n) ? Accumulation::privatised
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
    const std::int64_t ncell = grid.cell_count();
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
    const Accumulation acc = strategy(pv.n);
    log->debug("compute: {} particles, method={}, accumulation={}", pv.n, to_string(opts.method), int(acc));

    for (Scratch& s : scratch) s.reset_counters();
    work.assign(ncell + 1, 0.0);

    auto particle = [&](Scratch& s, std::int64_t p) {
      s.deposits.clear();
      const double* cp = pv.centres + p * cs;
      const Eigen::Vector3d c(cp[0], cp[1], cp[2]);
      const double r = pv.radii[p * rs];
      const double volume = 4.0 / 3.0 * std::numbers::pi * r * r * r;
      switch (opts.method) {
        case Method::direct: direct_particle(s, p, c, volume); break;
        case Method::pmm:
          pmm_particle(s, p, c, r, volume, pv.orientations ? pv.orientations + p * qs : nullptr);
          break;
        case Method::exact: exact_particle(s, p, c, r, volume); break;
      }
    };

    switch (acc) {
      case Accumulation::privatised:
      case Accumulation::automatic: {
        for_particles(pv.n, [&](std::int64_t b, std::int64_t e) {
          Scratch& s = scratch.local();
          std::vector<double>& f = private_fields.local();
          if (f.size() != static_cast<std::size_t>(ncell + 1)) f.assign(ncell + 1, 0.0);
          for (std::int64_t p = b; p < e; ++p) {
            particle(s, p);
            for (const Deposit& d : s.deposits) f[d.cell] += d.volume;
          }
        });
        // Merge over cells in parallel, copies innermost; leave the copies zeroed for reuse.
        arena->execute([&] {
          tbb::parallel_for(tbb::blocked_range<std::int64_t>(0, ncell + 1, 4096),
                            [&](const tbb::blocked_range<std::int64_t>& r) {
                              for (auto& f : private_fields) {
                                if (f.size() != static_cast<std::size_t>(ncell + 1)) continue;
                                for (std::int64_t c = r.begin(); c < r.end(); ++c) {
                                  work[c] += f[c];
                                  f[c] = 0.0;
                                }
                              }
                            });
        });
        break;
      }
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

    Report rep{};
    rep.particles = pv.n;
    rep.particle_volume = v.volume;
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
    if (rep.particle_grid_max == 0) rep.particle_grid_min = rep.particle_grid_max = opts.method == Method::pmm ? 0 : 1;
    if (first_error != std::numeric_limits<std::int64_t>::max()) {
      const double* cp = pv.centres + first_error * cs;
      std::ostringstream msg;
      msg.precision(9);
      msg << "particle " << first_error << " at (" << cp[0] << ", " << cp[1] << ", " << cp[2]
          << ") with radius " << pv.radii[first_error * rs] << " reaches outside the mesh ["
          << grid.origin().transpose() << "] - [" << grid.upper().transpose() << "] ("
          << rep.outside_particles
          << " particles do); enlarge the mesh or choose outside=nearest, centre or drop";
      throw Error(VFE_ERROR_OUT_OF_DOMAIN, msg.str());
    }
    rep.dropped_volume = work[ncell];
    work.resize(ncell);
    double deposited = 0;
    for (double x : work) deposited += x;
    rep.deposited_volume = deposited;
    rep.clipped_volume = clipped_volume(work);
    solid.swap(work);
    have_field = true;
    report = rep;
    std::copy(solid.begin(), solid.end(), out.begin());
    log->info("computed {} particles with {}: {} sub-elements, {} on the fast path, {} outside", pv.n,
              to_string(opts.method), rep.sub_elements, rep.fast_path_particles, rep.outside_particles);
  }

  /// Solid volume that clipping eps at alpha_min removes (0 when alpha_min is 0: no clip).
  double clipped_volume(const std::vector<double>& field) const {
    if (opts.alpha_min <= 0) return 0.0;
    const double vc = grid.cell_volume();
    double clipped = 0;
    for (double vs : field) clipped += std::max(0.0, vs - (1.0 - opts.alpha_min) * vc);
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
    std::vector<std::int64_t> offset(nblocks + 1, 0);
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
Engine::~Engine() = default;

void Engine::configure(std::string_view options) {
  Options next = parse_options(options, impl_->opts);
  const bool new_arena = next.threads != impl_->opts.threads;
  impl_->opts = next;
  if (new_arena) impl_->make_arena();
  impl_->log->set_level(spdlog::level::from_str(next.log_level));
}

std::string Engine::option(std::string_view key) const { return option_value(impl_->opts, key); }
std::string Engine::options() const { return format_options(impl_->opts); }
std::int64_t Engine::cell_count() const { return impl_->grid.cell_count(); }

void Engine::cell_volumes(std::span<double> out) const {
  if (static_cast<std::int64_t>(out.size()) != cell_count())
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "output has " + std::to_string(out.size()) +
                                                " values but the mesh has " + std::to_string(cell_count()) +
                                                " cells; pass a buffer of cell_count values");
  std::fill(out.begin(), out.end(), impl_->grid.cell_volume());
}

void Engine::compute(const ParticleView& particles, std::span<double> out) { impl_->compute(particles, out); }

void Engine::void_fraction(std::span<double> out) const {
  const std::int64_t n = cell_count();
  if (static_cast<std::int64_t>(out.size()) != n)
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "output has " + std::to_string(out.size()) +
                                                " values but the mesh has " + std::to_string(n) +
                                                " cells; pass a buffer of cell_count values");
  const double vc = impl_->grid.cell_volume();
  const double alpha_min = impl_->opts.alpha_min;
  for (std::int64_t c = 0; c < n; ++c) {
    const double eps = 1.0 - impl_->solid[c] / vc;
    out[c] = alpha_min > 0 && eps < alpha_min ? alpha_min : eps;
  }
}

const Report& Engine::last_report() const { return impl_->report; }

std::int64_t Engine::particle_grid_for(double diameter, double cell_size) const {
  const std::int64_t n = impl_->opts.particle_grid > 0
                             ? impl_->opts.particle_grid
                             : 5 * Impl::auto_steps(diameter, cell_size * cell_size * cell_size);
  return static_cast<std::int64_t>(impl_->get_template(n).size());
}

}  // namespace vfe
