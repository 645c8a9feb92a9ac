// vfe_mpi: an ordinary vfe engine per rank on its block plus ghosts, a reverse halo sum of
// the ghost deposits into their owners, and the C API's promises kept across ranks (every
// collective call has the same status on every rank).
#include <vfe/vfe_mpi.h>

#include <vfe/engine.hpp>

#include "halo.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <limits>
#include <new>
#include <sstream>
#include <string>
#include <vector>

using vfe::Error;
using vfe::mpi::Box;
using vfe::mpi::Decomposition;
using vfe::mpi::Halo;
using vfe::mpi::Index3;

struct vfe_mpi_engine {
  MPI_Comm comm = MPI_COMM_NULL;
  int rank = 0, size = 1;
  std::array<double, 3> origin{}, spacing{};
  Decomposition dec;
  std::unique_ptr<vfe::Engine> local;  // on dec.extended(rank)
  Halo halo;
  std::vector<double> extended;        // the local engine's field
  std::vector<double> solid;           // owned cells after the halo sum
  bool have_field = false;
  vfe_report report{};
  double local_cpu_seconds = 0, local_seconds = 0, exchange_seconds = 0;  // of the last compute, this rank
  std::string error;
  vfe_log_fn log_fn = nullptr;
  void* log_user = nullptr;

  Box block() const { return dec.blocks[static_cast<std::size_t>(rank)]; }
  std::int64_t owned_cells() const { return block().count(); }
  double cell_volume() const { return spacing[0] * spacing[1] * spacing[2]; }
};

namespace {

thread_local std::string g_create_error;

// CPU time of the calling thread: the local compute's cost, whatever else shares the cores.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// Builds the local engine on the extended block and its halo plan; keeps the options and
// log callback of the engine it replaces. Collective.
void rebuild(vfe_mpi_engine& e, const Index3& ghost) {
  Decomposition dec = e.dec;
  dec.ghost = ghost;
  const Box ext = dec.extended(e.rank);
  vfe::CartesianGridSpec spec;
  for (int d = 0; d < 3; ++d) {
    spec.origin[d] = e.origin[d] + static_cast<double>(ext.lo[d]) * e.spacing[d];
    spec.spacing[d] = e.spacing[d];
    spec.cells[d] = ext.hi[d] - ext.lo[d];
  }
  auto local = std::make_unique<vfe::Engine>(spec);
  if (e.local) local->configure(e.local->options());
  if (e.log_fn) local->set_log_callback(e.log_fn, e.log_user);
  Halo halo(e.comm, dec, e.rank);
  e.dec = dec;
  e.local = std::move(local);
  e.halo = std::move(halo);
  e.extended.assign(static_cast<std::size_t>(ext.count()), 0.0);
}

// The first failing rank's status and message, on every rank: one allreduce when all
// succeeded, which also takes the maximum over ranks of `maxima` (in place). Collective.
vfe_status agree(vfe_mpi_engine& e, vfe_status mine, const std::string& message, std::span<double> maxima = {}) {
  std::vector<double> in(1 + maxima.size()), out(in.size());
  in[0] = -double(mine == VFE_OK ? e.size : e.rank);  // the largest is the first failing rank
  std::copy(maxima.begin(), maxima.end(), in.begin() + 1);
  MPI_Allreduce(in.data(), out.data(), int(in.size()), MPI_DOUBLE, MPI_MAX, e.comm);
  std::copy(out.begin() + 1, out.end(), maxima.begin());
  const int first = int(-out[0]);
  if (first == e.size) return VFE_OK;
  int status = mine;
  MPI_Bcast(&status, 1, MPI_INT, first, e.comm);
  std::string text = message;
  int length = static_cast<int>(text.size());
  MPI_Bcast(&length, 1, MPI_INT, first, e.comm);
  text.resize(static_cast<std::size_t>(length));
  MPI_Bcast(text.data(), length, MPI_CHAR, first, e.comm);
  e.error = e.size > 1 ? "rank " + std::to_string(first) + ": " + text : text;
  return static_cast<vfe_status>(status);
}

// A rank's part of a collective call: its status and message, exceptions caught.
template <class F>
vfe_status attempt(F&& f, std::string& message) {
  try {
    f();
    return VFE_OK;
  } catch (const Error& err) {
    message = err.what();
    return err.status();
  } catch (const std::bad_alloc&) {
    message = "out of memory";
    return VFE_ERROR_OUT_OF_MEMORY;
  } catch (const std::exception& err) {
    message = err.what();
    return VFE_ERROR_INTERNAL;
  }
}

// Runs a rank's part of a collective call and agrees on its outcome.
template <class F>
vfe_status collective(vfe_mpi_engine& e, F&& f, std::span<double> maxima = {}) {
  std::string message;
  const vfe_status mine = attempt(f, message);
  return agree(e, mine, message, maxima);
}

// Runs a rank-local call: errors go to e.error and the status.
template <class F>
vfe_status local_call(const vfe_mpi_engine* e, F&& f) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  std::string message;
  const vfe_status s = attempt(f, message);
  if (s != VFE_OK) const_cast<vfe_mpi_engine&>(*e).error = message;  // the message is the handle's only mutable state
  return s;
}

void require(bool ok, const std::string& message) {
  if (!ok) throw Error(VFE_ERROR_INVALID_ARGUMENT, message);
}

// Global cell of a centre under the particle contract: periodic axes wrapped, others clamped.
Index3 centre_cell(const vfe_mpi_engine& e, const double* x) {
  Index3 c{};
  for (int d = 0; d < 3; ++d) {
    const std::int64_t n = e.dec.cells[d];
    const double f = std::floor((x[d] - e.origin[d]) / e.spacing[d]);
    const double clamped = std::clamp(f, -1e18, 1e18);
    std::int64_t i = static_cast<std::int64_t>(clamped);
    if (e.dec.periodic[d])
      i = ((i % n) + n) % n;
    else
      i = std::clamp<std::int64_t>(i, 0, n - 1);
    c[d] = i;
  }
  return c;
}

int owner_of(const vfe_mpi_engine& e, const Index3& cell) {
  // Blocks tile the grid, so exactly one holds the cell. Linear in the ranks (see
  // docs/scaling.md for when a lookup table would pay).
  for (int q = 0; q < e.size; ++q)
    if (e.dec.blocks[static_cast<std::size_t>(q)].contains(cell)) return q;
  return -1;
}

// How far beyond a particle's centre its deposits can land, per axis, in cells, plus one
// cell so that a deposit never reaches the ghost layer's last cells (checked after compute).
Index3 ghost_needed(const vfe_mpi_engine& e, double max_radius) {
  const std::string method = e.local->option("method");
  double reach = 0, extra_cells = 0;
  if (method == "direct")
    reach = 0;
  else if (method == "pmm" || method == "exact" || method == "divided" || method == "big_particle")
    reach = max_radius;
  else if (method == "gaussian")
    reach = 6.0 * std::stod(e.local->option("sigma")) * max_radius;  // 3 sigma, sigma in diameters
  else if (method == "porous_cube")
    reach = std::stod(e.local->option("gamma")) * max_radius;  // half of gamma * d
  else if (method == "trilinear")
    extra_cells = 1;  // the 8 cells whose centres surround the particle's centre
  else
    throw Error(VFE_ERROR_UNSUPPORTED, "method " + method + " has no known footprint in vfe_mpi");
  Index3 g{};
  for (int d = 0; d < 3; ++d)
    g[d] = static_cast<std::int64_t>(std::ceil(reach / e.spacing[d])) + static_cast<std::int64_t>(extra_cells) + 1;
  return g;
}

// Sum of |value| over the last ghost layer on each side that faces another block: the
// margin cell of ghost_needed, which only a footprint wider than assumed can reach.
double edge_layer_volume(const vfe_mpi_engine& e) {
  const Box ext = e.dec.extended(e.rank);
  const Index3 n = ext.extent();
  double sum = 0;
  for (int d = 0; d < 3; ++d) {
    if (e.dec.ghost[d] == 0) continue;
    for (int side = 0; side < 2; ++side) {
      // A side the grid's boundary clipped has its own cells there (outside= sends volume to them).
      const bool interior =
          side == 0 ? ext.lo[d] == e.block().lo[d] - e.dec.ghost[d] : ext.hi[d] == e.block().hi[d] + e.dec.ghost[d];
      if (!interior) continue;
      Box layer{{0, 0, 0}, n};
      layer.lo[d] = side == 0 ? 0 : n[d] - 1;
      layer.hi[d] = layer.lo[d] + 1;
      for (std::int64_t k = layer.lo[2]; k < layer.hi[2]; ++k)
        for (std::int64_t j = layer.lo[1]; j < layer.hi[1]; ++j)
          for (std::int64_t i = layer.lo[0]; i < layer.hi[0]; ++i)
            sum += std::abs(e.extended[static_cast<std::size_t>(i + n[0] * (j + n[1] * k))]);
    }
  }
  return sum;
}

// Copies the owned cells between an extended-block field and an owned-cell field (k values
// per cell): to_owned reads extended, else writes it.
void copy_owned(const vfe_mpi_engine& e, bool to_owned, double* extended, double* owned, int k) {
  const Box ext = e.dec.extended(e.rank), b = e.block();
  const Index3 n = ext.extent(), m = b.extent();
  for (std::int64_t z = 0; z < m[2]; ++z)
    for (std::int64_t y = 0; y < m[1]; ++y) {
      double* in_extended =
          extended + k * ((b.lo[0] - ext.lo[0]) + n[0] * ((y + b.lo[1] - ext.lo[1]) + n[1] * (z + b.lo[2] - ext.lo[2])));
      double* in_owned = owned + k * (m[0] * (y + m[1] * z));
      if (to_owned)
        std::copy_n(in_extended, m[0] * k, in_owned);
      else
        std::copy_n(in_owned, m[0] * k, in_extended);
    }
}

// Element i of a host array with a byte stride (0 = packed: `packed` values per element).
template <class T>
const T* at(const T* base, std::int64_t stride_bytes, std::int64_t packed, std::int64_t i) {
  const std::int64_t step = stride_bytes ? stride_bytes : packed * static_cast<std::int64_t>(sizeof(T));
  return reinterpret_cast<const T*>(reinterpret_cast<const char*>(base) + i * step);
}

std::string describe(const Index3& c) {
  return "(" + std::to_string(c[0]) + ", " + std::to_string(c[1]) + ", " + std::to_string(c[2]) + ")";
}

// The rank's particles checked against the contract; returns the largest radius and, when
// a centre lies outside the grid on a periodic axis, fills wrapped with every centre wrapped
// into the grid (as the serial engine wraps them).
double check_particles(const vfe_mpi_engine& e, const vfe_particles& p, std::vector<double>& wrapped) {
  double max_radius = 0;
  bool wrap = false;
  for (std::int64_t i = 0; i < p.n; ++i) {
    const double* x = at(p.centres, p.centres_stride, 3, i);
    const double r = *at(p.radii, p.radii_stride, 1, i);
    if (std::isfinite(r) && r > max_radius) max_radius = r;
    if (!(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]))) continue;  // the engine names it
    const Index3 c = centre_cell(e, x);
    if (!e.block().contains(c)) {
      std::string who = "particle " + std::to_string(i);
      if (p.ids) who += " (id " + std::to_string(*at(p.ids, p.ids_stride, 1, i)) + ")";
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  who + " has its centre in cell " + describe(c) + ", owned by rank " + std::to_string(owner_of(e, c)) +
                      ", not by this rank " + std::to_string(e.rank) +
                      ": give each particle on the rank owning its centre's cell (vfe_mpi_owner, vfe_mpi_route_particles)");
    }
    for (int d = 0; d < 3; ++d)
      if (e.dec.periodic[d] && (x[d] < e.origin[d] || x[d] >= e.origin[d] + e.spacing[d] * double(e.dec.cells[d])))
        wrap = true;
  }
  if (wrap) {
    wrapped.resize(static_cast<std::size_t>(3 * p.n));
    for (std::int64_t i = 0; i < p.n; ++i) {
      const double* x = at(p.centres, p.centres_stride, 3, i);
      for (int d = 0; d < 3; ++d) {
        double v = x[d];
        if (e.dec.periodic[d]) {
          const double length = e.spacing[d] * double(e.dec.cells[d]);
          v -= length * std::floor((v - e.origin[d]) / length);
        }
        wrapped[static_cast<std::size_t>(3 * i + d)] = v;
      }
    }
  }
  return max_radius;
}

// The report over all ranks: the local reports' sums, particle grid sizes over the ranks
// with particles (grid_extremes: max and -min, already reduced), deposited and clipped volume
// of the owned fields. Returns how many ranks failed the halo sum (in the same allreduce).
int gather_report(vfe_mpi_engine& e, bool halo_failed, const double grid_extremes[2]) {
  const vfe_report r = e.local->last_report();
  const double alpha_min = std::stod(e.local->option("alpha_min"));
  double deposited = 0, clipped = 0;
  for (double v : e.solid) {
    deposited += v;
    if (alpha_min > 0) clipped += std::max(0.0, v - (1.0 - alpha_min) * e.cell_volume());
  }
  double sums[9] = {double(r.particles), double(r.fast_path_particles), double(r.sub_elements),
                    r.particle_volume,   deposited,                      r.dropped_volume,
                    double(r.outside_particles), clipped,               halo_failed ? 1.0 : 0.0};
  double t[9];
  MPI_Allreduce(sums, t, 9, MPI_DOUBLE, MPI_SUM, e.comm);
  vfe_report g{};
  g.particles = static_cast<std::int64_t>(t[0]);
  g.fast_path_particles = static_cast<std::int64_t>(t[1]);
  g.sub_elements = static_cast<std::int64_t>(t[2]);
  g.particle_volume = t[3];
  g.deposited_volume = t[4];
  g.dropped_volume = t[5];
  g.outside_particles = static_cast<std::int64_t>(t[6]);
  g.clipped_volume = t[7];
  g.particle_grid_max = g.particles > 0 ? static_cast<std::int64_t>(grid_extremes[0]) : 0;
  g.particle_grid_min = g.particles > 0 ? static_cast<std::int64_t>(-grid_extremes[1]) : 0;
  e.report = g;
  return static_cast<int>(t[8]);
}

// One compute: three small allreduces (contract and largest radius; the local computes'
// outcome and grid sizes; the report) and one neighbour exchange, plus a rebuild of the
// ghost layer when a footprint needs a wider one.
vfe_status compute(vfe_mpi_engine* e, const vfe_particles* p, double* out) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  std::vector<double> wrapped;
  double max_radius = 0;
  vfe_status s = collective(
      *e,
      [&] {
        require(p != nullptr, "vfe_mpi_compute_particles: particles is NULL");
        require(p->n >= 0, "vfe_mpi_compute: n must be >= 0");
        require(out != nullptr || e->owned_cells() == 0, "vfe_mpi_compute: solid_volume is NULL; pass owned-cell storage");
        require(p->n == 0 || (p->centres && p->radii), "vfe_mpi_compute: centres and radii must not be NULL");
        if (p->shape_ids) throw Error(VFE_ERROR_UNSUPPORTED, "vfe_mpi computes spheres only: pass shape_ids = NULL");
        if (!p->ids && p->n > 0 && e->local->option("method") == "pmm" && e->local->option("orientation") == "random")
          throw Error(VFE_ERROR_INVALID_ARGUMENT,
                      "method=pmm with orientation=random rotates each particle by its id, which must not depend on "
                      "the rank: pass the particle ids (vfe_particles.ids, vfe_mpi_compute_particles)");
        max_radius = check_particles(*e, *p, wrapped);
      },
      {&max_radius, 1});
  if (s != VFE_OK) return s;
  // Every rank has the same largest radius and options, so all decide alike.
  Index3 need{};
  s = local_call(e, [&] { need = ghost_needed(*e, max_radius); });
  if (s != VFE_OK) return s;
  if (need[0] > e->dec.ghost[0] || need[1] > e->dec.ghost[1] || need[2] > e->dec.ghost[2]) {
    s = collective(*e, [&] {
      rebuild(*e, {std::max(need[0], e->dec.ghost[0]), std::max(need[1], e->dec.ghost[1]),
                   std::max(need[2], e->dec.ghost[2])});
    });
    if (s != VFE_OK) return s;
  }
  double grid_extremes[2] = {0, -std::numeric_limits<double>::max()};
  s = collective(
      *e,
      [&] {
        vfe_particles local = *p;
        if (!wrapped.empty()) {
          local.centres = wrapped.data();
          local.centres_stride = 0;
        }
        const double wall0 = MPI_Wtime(), cpu0 = thread_cpu_seconds();
        e->local->compute(local, e->extended);
        e->local_cpu_seconds = thread_cpu_seconds() - cpu0;
        e->local_seconds = MPI_Wtime() - wall0;
        if (edge_layer_volume(*e) != 0)
          throw Error(VFE_ERROR_INTERNAL,
                      "a deposit reached the outer ghost layer, so the ghost layer was narrower than a footprint: "
                      "please report this with the options used");
        const vfe_report& r = e->local->last_report();
        if (r.particles > 0) {
          grid_extremes[0] = double(r.particle_grid_max);
          grid_extremes[1] = -double(r.particle_grid_min);
        }
      },
      grid_extremes);
  if (s != VFE_OK) return s;
  const double exchange0 = MPI_Wtime();
  std::string message;
  const vfe_status halo = attempt(
      [&] {
        std::vector<double> owned(static_cast<std::size_t>(e->owned_cells()));
        copy_owned(*e, true, e->extended.data(), owned.data(), 1);
        e->halo.reverse_sum(e->extended, owned, 1);
        e->solid = std::move(owned);
      },
      message);
  const int halo_failures = gather_report(*e, halo != VFE_OK, grid_extremes);
  e->exchange_seconds = MPI_Wtime() - exchange0;
  if (halo_failures > 0) {
    e->have_field = false;
    e->error = halo != VFE_OK ? message : "the halo sum failed on another rank";
    return VFE_ERROR_INTERNAL;
  }
  e->have_field = true;
  if (e->owned_cells() > 0) std::copy(e->solid.begin(), e->solid.end(), out);
  return VFE_OK;
}

void check_blocks(const vfe_mpi_engine& e) {
  for (int d = 0; d < 3; ++d) {
    require(std::isfinite(e.origin[d]), "origin must be finite");
    require(std::isfinite(e.spacing[d]) && e.spacing[d] > 0, "spacing must be finite and > 0 on every axis");
    require(e.dec.cells[d] > 0, "global_cells must be > 0 on every axis");
  }
  std::int64_t total = 0;
  for (int q = 0; q < e.size; ++q) {
    const Box& b = e.dec.blocks[static_cast<std::size_t>(q)];
    for (int d = 0; d < 3; ++d)
      require(b.lo[d] >= 0 && b.hi[d] <= e.dec.cells[d] && b.lo[d] < b.hi[d],
              "rank " + std::to_string(q) + "'s block [" + describe(b.lo) + ", " + describe(b.hi) +
                  ") must satisfy 0 <= block_lo < block_hi <= global_cells on every axis");
    total += b.count();
    for (int other = 0; other < q; ++other)
      require(intersect(b, e.dec.blocks[static_cast<std::size_t>(other)]).empty(),
              "the blocks of ranks " + std::to_string(other) + " and " + std::to_string(q) +
                  " overlap: blocks must tile the grid without overlap");
  }
  require(total == e.dec.cells[0] * e.dec.cells[1] * e.dec.cells[2],
          "the blocks cover " + std::to_string(total) + " cells of " +
              std::to_string(e.dec.cells[0] * e.dec.cells[1] * e.dec.cells[2]) + ": they must tile the whole grid");
}

// Splits off periodic= (the global grid's, handled here) from the options for the local engine.
std::string take_periodic(const char* options, std::array<bool, 3>& periodic, bool& given) {
  std::istringstream in(options);
  std::string token, rest;
  given = false;
  while (in >> token) {
    if (token.rfind("periodic=", 0) == 0) {
      const std::string v = token.substr(9);
      std::array<bool, 3> axes{false, false, false};
      require(!v.empty(), "periodic: give axes among x, y, z (e.g. periodic=xy) or none");
      if (v != "none")
        for (char c : v) {
          require(c >= 'x' && c <= 'z', "periodic: '" + v + "' is not a set of axes; use any of x, y, z or none");
          axes[static_cast<std::size_t>(c - 'x')] = true;
        }
      periodic = axes;
      given = true;
    } else {
      rest += token + " ";
    }
  }
  return rest;
}

}  // namespace

extern "C" {

vfe_status vfe_mpi_create_cartesian(MPI_Comm comm, const double origin[3], const double spacing[3],
                                    const int64_t global_cells[3], const int64_t block_lo[3],
                                    const int64_t block_hi[3], vfe_mpi_engine** out) {
  // Arguments are checked after the blocks are gathered, so that every rank fails alike.
  auto e = std::make_unique<vfe_mpi_engine>();
  if (comm == MPI_COMM_NULL) {
    g_create_error = "vfe_mpi_create_cartesian: comm is MPI_COMM_NULL";
    return VFE_ERROR_INVALID_ARGUMENT;
  }
  MPI_Comm_dup(comm, &e->comm);
  MPI_Comm_rank(e->comm, &e->rank);
  MPI_Comm_size(e->comm, &e->size);
  const bool given = origin && spacing && global_cells && block_lo && block_hi && out;
  std::int64_t mine[6] = {0, 0, 0, 0, 0, 0};
  if (given)
    for (int d = 0; d < 3; ++d) {
      mine[d] = block_lo[d];
      mine[3 + d] = block_hi[d];
    }
  std::vector<std::int64_t> all(static_cast<std::size_t>(6 * e->size));
  MPI_Allgather(mine, 6, MPI_INT64_T, all.data(), 6, MPI_INT64_T, e->comm);
  const vfe_status s = collective(*e, [&] {
    require(given, "vfe_mpi_create_cartesian: origin, spacing, global_cells, block_lo, block_hi and out must not be NULL");
    for (int d = 0; d < 3; ++d) {
      e->origin[d] = origin[d];
      e->spacing[d] = spacing[d];
      e->dec.cells[d] = global_cells[d];
    }
    e->dec.blocks.resize(static_cast<std::size_t>(e->size));
    for (int q = 0; q < e->size; ++q)
      for (int d = 0; d < 3; ++d) {
        e->dec.blocks[static_cast<std::size_t>(q)].lo[d] = all[static_cast<std::size_t>(6 * q + d)];
        e->dec.blocks[static_cast<std::size_t>(q)].hi[d] = all[static_cast<std::size_t>(6 * q + 3 + d)];
      }
    check_blocks(*e);
  });
  if (s == VFE_OK) {
    const vfe_status built = collective(*e, [&] { rebuild(*e, {1, 1, 1}); });
    if (built == VFE_OK) {
      *out = e.release();
      return VFE_OK;
    }
    g_create_error = e->error;
    MPI_Comm_free(&e->comm);
    return built;
  }
  g_create_error = e->error;
  MPI_Comm_free(&e->comm);
  return s;
}

vfe_status vfe_mpi_create_polymesh(MPI_Comm, const char* processor_dir, vfe_mpi_engine** out) {
  (void)processor_dir;
  (void)out;
  g_create_error =
      "vfe_mpi_create_polymesh is not implemented yet: decompose a Cartesian grid with vfe_mpi_create_cartesian";
  return VFE_ERROR_UNSUPPORTED;
}

void vfe_mpi_destroy(vfe_mpi_engine* e) {
  if (!e) return;
  e->local.reset();
  e->halo = Halo();
  if (e->comm != MPI_COMM_NULL) MPI_Comm_free(&e->comm);
  delete e;
}

vfe_status vfe_mpi_configure(vfe_mpi_engine* e, const char* options) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  std::array<bool, 3> periodic = e->dec.periodic;
  bool periodic_given = false;
  std::string rest;
  vfe_status s = collective(*e, [&] {
    require(options != nullptr, "vfe_mpi_configure: options is NULL");
    rest = take_periodic(options, periodic, periodic_given);
    // Checked on a scratch engine first, so a refused option string changes nothing.
    vfe::Engine scratch(vfe::CartesianGridSpec{});
    scratch.configure(e->local->options());
    scratch.configure(rest);
    // The engine's smoothing is an implicit diffusion over the whole mesh: no ghost layer
    // reaches as far, so it would need a distributed solve.
    if (std::stod(scratch.option("smoothing_length")) != 0)
      throw Error(VFE_ERROR_UNSUPPORTED,
                  "smoothing_length: the smoothing solves a diffusion over the whole mesh, which vfe_mpi does not "
                  "do across ranks; set smoothing_length=0 and smooth on the host's decomposed mesh");
  });
  if (s != VFE_OK) return s;
  return collective(*e, [&] {
    e->local->configure(rest);
    if (periodic_given && periodic != e->dec.periodic) {
      e->dec.periodic = periodic;
      rebuild(*e, e->dec.ghost);
    }
    e->have_field = false;
  });
}

int64_t vfe_mpi_cell_count(const vfe_mpi_engine* e) { return e ? e->owned_cells() : -1; }

vfe_status vfe_mpi_cell_volumes(const vfe_mpi_engine* e, double* out) {
  return local_call(e, [&] {
    require(out != nullptr, "vfe_mpi_cell_volumes: out is NULL");
    std::fill_n(out, e->owned_cells(), e->cell_volume());
  });
}

vfe_status vfe_mpi_owner(const vfe_mpi_engine* e, const double centre[3], int* rank) {
  return local_call(e, [&] {
    require(centre && rank, "vfe_mpi_owner: centre and rank must not be NULL");
    require(std::isfinite(centre[0]) && std::isfinite(centre[1]) && std::isfinite(centre[2]),
            "vfe_mpi_owner: the centre must be finite");
    *rank = owner_of(*e, centre_cell(*e, centre));
  });
}

vfe_status vfe_mpi_compute(vfe_mpi_engine* e, int64_t n, const double* centres, const double* radii,
                           const double* orientations, double* solid_volume) {
  vfe_particles p{};
  p.n = n;
  p.centres = centres;
  p.radii = radii;
  p.orientations = orientations;
  return compute(e, &p, solid_volume);
}

vfe_status vfe_mpi_compute_particles(vfe_mpi_engine* e, const vfe_particles* p, double* solid_volume) {
  return compute(e, p, solid_volume);
}

vfe_status vfe_mpi_void_fraction(const vfe_mpi_engine* e, double* out) {
  return local_call(e, [&] {
    require(out != nullptr, "vfe_mpi_void_fraction: out is NULL");
    require(e->have_field, "vfe_mpi_void_fraction: no compute since creation or the last configure; compute first");
    const double alpha_min = std::stod(e->local->option("alpha_min"));
    for (std::size_t c = 0; c < e->solid.size(); ++c) {
      const double eps = 1.0 - e->solid[c] / e->cell_volume();
      out[c] = alpha_min > 0 && eps < alpha_min ? alpha_min : eps;
    }
  });
}

vfe_status vfe_mpi_deposit(vfe_mpi_engine* e, int32_t components, const double* values, double* out) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  std::vector<double> owned;
  const vfe_status s = collective(*e, [&] {
    require(components >= 1, "vfe_mpi_deposit: components must be >= 1");
    require(out != nullptr || e->owned_cells() == 0, "vfe_mpi_deposit: out is NULL");
    const std::int64_t particles = e->local->weights_size().particles;
    require(values != nullptr || particles == 0, "vfe_mpi_deposit: values is NULL");
    std::vector<double> extended(e->extended.size() * static_cast<std::size_t>(components));
    e->local->deposit(components, {values, static_cast<std::size_t>(particles * components)}, extended);
    owned.resize(static_cast<std::size_t>(e->owned_cells() * components));
    copy_owned(*e, true, extended.data(), owned.data(), components);
    e->halo.reverse_sum(extended, owned, components);
  });
  if (s == VFE_OK) std::copy(owned.begin(), owned.end(), out);
  return s;
}

vfe_status vfe_mpi_interpolate(vfe_mpi_engine* e, int32_t components, const double* cell_field, double* out) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  std::vector<double> result;
  const vfe_status s = collective(*e, [&] {
    require(components >= 1, "vfe_mpi_interpolate: components must be >= 1");
    require(cell_field != nullptr || e->owned_cells() == 0, "vfe_mpi_interpolate: cell_field is NULL");
    const std::int64_t particles = e->local->weights_size().particles;
    require(out != nullptr || particles == 0, "vfe_mpi_interpolate: out is NULL");
    std::vector<double> extended(e->extended.size() * static_cast<std::size_t>(components), 0.0);
    copy_owned(*e, false, extended.data(), const_cast<double*>(cell_field), components);  // reads cell_field
    e->halo.forward_fill({cell_field, static_cast<std::size_t>(e->owned_cells() * components)}, extended, components);
    result.resize(static_cast<std::size_t>(particles * components));
    e->local->interpolate(components, extended, result);
  });
  if (s == VFE_OK) std::copy(result.begin(), result.end(), out);
  return s;
}

vfe_status vfe_mpi_weights_size(const vfe_mpi_engine* e, int64_t* n_particles, int64_t* n_entries) {
  return local_call(e, [&] {
    require(n_particles && n_entries, "vfe_mpi_weights_size: n_particles and n_entries must not be NULL");
    const vfe::Engine::WeightsSize w = e->local->weights_size();
    *n_particles = w.particles;
    *n_entries = w.entries;
  });
}

vfe_status vfe_mpi_weights(const vfe_mpi_engine* e, int64_t* offsets, int64_t* cells, double* fractions) {
  return local_call(e, [&] {
    const vfe::Engine::WeightsSize w = e->local->weights_size();
    require(offsets && (w.entries == 0 || (cells && fractions)), "vfe_mpi_weights: output arrays must not be NULL");
    std::vector<std::int64_t> o(static_cast<std::size_t>(w.particles + 1)), c(static_cast<std::size_t>(w.entries));
    std::vector<double> f(static_cast<std::size_t>(w.entries));
    e->local->weights(o, c, f);
    const Box ext = e->dec.extended(e->rank);
    const Index3 n = ext.extent(), g = e->dec.cells;
    for (std::int64_t& cell : c) {
      Index3 ijk{cell % n[0], (cell / n[0]) % n[1], cell / (n[0] * n[1])};
      for (int d = 0; d < 3; ++d) ijk[d] = (((ijk[d] + ext.lo[d]) % g[d]) + g[d]) % g[d];
      cell = ijk[0] + g[0] * (ijk[1] + g[1] * ijk[2]);
    }
    std::copy(o.begin(), o.end(), offsets);
    std::copy(c.begin(), c.end(), cells);
    std::copy(f.begin(), f.end(), fractions);
  });
}

vfe_status vfe_mpi_last_report(const vfe_mpi_engine* e, vfe_report* out) {
  return local_call(e, [&] {
    require(out != nullptr, "vfe_mpi_last_report: out is NULL");
    *out = e->report;
  });
}

vfe_status vfe_mpi_last_report_value(const vfe_mpi_engine* e, const char* key, double* out) {
  return local_call(e, [&] {
    require(key && out, "vfe_mpi_last_report_value: key and out must not be NULL");
    const vfe_report& r = e->report;
    const std::int64_t halo_values = e->halo.ghost_cells_sent();
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
        {"ghost_width", double(*std::max_element(e->dec.ghost.begin(), e->dec.ghost.end()))},
        {"neighbours", double(e->halo.neighbours().size())},
        {"local_cells", double(e->extended.size())},
        {"halo_values", double(halo_values)},
        {"halo_bytes", double(halo_values) * double(sizeof(double))},
        {"local_seconds", e->local_seconds},
        {"local_cpu_seconds", e->local_cpu_seconds},
        {"exchange_seconds", e->exchange_seconds},
    };
    for (const auto& [name, value] : facts)
      if (std::strcmp(name, key) == 0) {
        *out = value;
        return;
      }
    throw Error(VFE_ERROR_INVALID_ARGUMENT, std::string("vfe_mpi_last_report_value: unknown key '") + key +
                                                "'; see vfe_mpi.h for the keys");
  });
}

const char* vfe_mpi_last_error(const vfe_mpi_engine* e) { return e ? e->error.c_str() : g_create_error.c_str(); }

vfe_status vfe_mpi_set_log_callback(vfe_mpi_engine* e, vfe_log_fn fn, void* user) {
  return local_call(e, [&] {
    e->local->set_log_callback(fn, user);
    e->log_fn = fn;
    e->log_user = user;
  });
}

vfe_status vfe_mpi_route_particles(const vfe_mpi_engine* e, int64_t n, const double* centres, const double* radii,
                                   const int64_t* ids, int64_t* n_out, double** centres_out, double** radii_out,
                                   int64_t** ids_out) {
  if (!e) return VFE_ERROR_INVALID_ARGUMENT;
  auto& m = const_cast<vfe_mpi_engine&>(*e);  // collective calls record their message on the handle
  std::vector<double> got_centres, got_radii;
  std::vector<std::int64_t> got_ids;
  const vfe_status s = collective(m, [&] {
    require(n >= 0, "vfe_mpi_route_particles: n must be >= 0");
    require(n == 0 || (centres && radii && ids), "vfe_mpi_route_particles: centres, radii and ids must not be NULL");
    require(n_out && centres_out && radii_out && ids_out, "vfe_mpi_route_particles: outputs must not be NULL");
    std::vector<int> dest(static_cast<std::size_t>(n));
    std::vector<int> counts(static_cast<std::size_t>(e->size), 0);
    for (std::int64_t i = 0; i < n; ++i) {
      const double* x = centres + 3 * i;
      require(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]),
              "vfe_mpi_route_particles: particle " + std::to_string(i) + " has a non-finite centre");
      dest[static_cast<std::size_t>(i)] = owner_of(*e, centre_cell(*e, x));
      ++counts[static_cast<std::size_t>(dest[static_cast<std::size_t>(i)])];
    }
    // Packed records of 5 doubles (centre, radius, id's bits), grouped by destination.
    std::vector<int> displs(static_cast<std::size_t>(e->size), 0);
    for (int q = 1; q < e->size; ++q) displs[q] = displs[q - 1] + counts[q - 1];
    std::vector<double> send(static_cast<std::size_t>(5 * n));
    std::vector<int> fill = displs;
    for (std::int64_t i = 0; i < n; ++i) {
      double* rec = &send[static_cast<std::size_t>(5 * fill[static_cast<std::size_t>(dest[static_cast<std::size_t>(i)])]++)];
      std::copy_n(centres + 3 * i, 3, rec);
      rec[3] = radii[i];
      std::memcpy(&rec[4], &ids[i], sizeof(double));
    }
    std::vector<int> recv_counts(static_cast<std::size_t>(e->size));
    MPI_Alltoall(counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, e->comm);
    std::vector<int> sc(counts.size()), sd(counts.size()), rc(counts.size()), rd(counts.size());
    std::int64_t total = 0;
    for (int q = 0; q < e->size; ++q) {
      sc[q] = 5 * counts[q];
      sd[q] = 5 * displs[q];
      rc[q] = 5 * recv_counts[q];
      rd[q] = static_cast<int>(5 * total);
      total += recv_counts[q];
    }
    std::vector<double> recv(static_cast<std::size_t>(5 * total));
    MPI_Alltoallv(send.data(), sc.data(), sd.data(), MPI_DOUBLE, recv.data(), rc.data(), rd.data(), MPI_DOUBLE, e->comm);
    got_centres.resize(static_cast<std::size_t>(3 * total));
    got_radii.resize(static_cast<std::size_t>(total));
    got_ids.resize(static_cast<std::size_t>(total));
    for (std::int64_t i = 0; i < total; ++i) {
      std::copy_n(&recv[static_cast<std::size_t>(5 * i)], 3, &got_centres[static_cast<std::size_t>(3 * i)]);
      got_radii[static_cast<std::size_t>(i)] = recv[static_cast<std::size_t>(5 * i + 3)];
      std::memcpy(&got_ids[static_cast<std::size_t>(i)], &recv[static_cast<std::size_t>(5 * i + 4)], sizeof(double));
    }
  });
  if (s != VFE_OK) return s;
  const std::size_t count = got_radii.size();
  double* c = static_cast<double*>(std::malloc(std::max<std::size_t>(1, 3 * count) * sizeof(double)));
  double* r = static_cast<double*>(std::malloc(std::max<std::size_t>(1, count) * sizeof(double)));
  int64_t* i = static_cast<int64_t*>(std::malloc(std::max<std::size_t>(1, count) * sizeof(int64_t)));
  if (!c || !r || !i) {
    std::free(c);
    std::free(r);
    std::free(i);
    m.error = "vfe_mpi_route_particles: out of memory for the received particles";
    return VFE_ERROR_OUT_OF_MEMORY;  // this rank only: the exchange itself succeeded everywhere
  }
  std::copy(got_centres.begin(), got_centres.end(), c);
  std::copy(got_radii.begin(), got_radii.end(), r);
  std::copy(got_ids.begin(), got_ids.end(), i);
  *n_out = static_cast<int64_t>(count);
  *centres_out = c;
  *radii_out = r;
  *ids_out = i;
  return VFE_OK;
}

}  // extern "C"
