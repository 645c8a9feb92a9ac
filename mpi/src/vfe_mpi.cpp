// vfe_mpi: an ordinary vfe engine per rank on its block (or processor mesh) plus ghosts, a
// reverse halo sum of the ghost deposits into their owners, and the C API's promises kept
// across ranks (every collective call has the same status on every rank). The distributed
// engine is a backend of libvfe's vfe_engine handle (vfe/detail/engine_backend.hpp), so a
// host calls vfe.h's functions on it.
#include <vfe/vfe_mpi.h>

#include <vfe/detail/engine_backend.hpp>
#include <vfe/engine.hpp>

#include "halo.hpp"
#include "polymesh_ghosts.hpp"

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
using vfe::Engine;
using vfe::FixedSum;
using vfe::fixed_unit_exponent;
using vfe::from_fixed;
using vfe::mpi::Box;
using vfe::mpi::Decomposition;
using vfe::mpi::Halo;
using vfe::mpi::Index3;

namespace {

// A decomposed polyMesh: this rank's cells with their global ids, and the ghost layer the
// local engine is built on (owned cells first, then ghosts).
struct DistributedPolyMesh {
  vfe::mpi::RankPolyMesh mesh;
  std::vector<double> boxes;           // per owned cell: lo xyz, hi xyz
  std::vector<double> volumes;         // per owned cell
  double largest_cell = 0;             // largest bounding-box side of any cell on any rank
  double width = -1;                   // of the current ghost layer (length)
  std::vector<std::int64_t> cell_ids;  // global cell per local cell
  std::vector<int> ghost_owner;        // per ghost
  std::vector<std::int64_t> rim;       // ghosts on the layer's outer edge
  std::int64_t ghost_bytes = 0;
};

// The engine of one rank: a local vfe::Engine on the owned cells plus ghosts, the halo plan,
// and the owned-cell field and report of the last compute. Its methods are vfe.h's calls;
// the collective ones agree on their outcome over comm and throw the same Error everywhere.
struct DistributedEngine final : vfe::detail::EngineBackend {
  MPI_Comm comm = MPI_COMM_NULL;
  int rank = 0, size = 1;
  std::array<double, 3> origin{}, spacing{};
  Decomposition dec;
  std::unique_ptr<DistributedPolyMesh> poly;  // set for a polyMesh; dec is unused then
  std::unique_ptr<vfe::Engine> local;  // on dec.extended(rank), or a polyMesh's owned + ghost cells
  Halo halo;
  std::vector<double> extended;        // the local engine's field
  std::vector<double> solid;           // owned cells after the halo sum
  bool have_field = false;
  vfe_report report{};
  double local_cpu_seconds = 0, local_seconds = 0, exchange_seconds = 0;  // of the last compute, this rank
  vfe_log_fn log_fn = nullptr;
  void* log_user = nullptr;
  std::vector<std::string> shape_specs;  // registered on every local engine, in id order
  std::vector<double> shape_reaches;     // per shape: vfe::Engine::shape_reach

  /// Duplicates comm (the caller may free its own).
  explicit DistributedEngine(MPI_Comm c) {
    MPI_Comm_dup(c, &comm);
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
  }
  /// Collective (vfe_destroy).
  ~DistributedEngine() override {
    local.reset();
    halo = Halo();
    MPI_Comm_free(&comm);
  }

  Box block() const { return dec.blocks[static_cast<std::size_t>(rank)]; }
  std::int64_t owned_cells() const { return poly ? poly->mesh.cell_count() : block().count(); }
  double cell_volume(std::size_t c) const {
    return poly ? poly->volumes[c] : spacing[0] * spacing[1] * spacing[2];
  }

  void agree(vfe_status mine, const std::string& message) override;
  void configure(std::string_view options) override;
  std::int64_t cell_count() const override { return owned_cells(); }
  void cell_volumes(std::span<double> out) const override;
  void compute(const vfe_particles& particles, std::span<double> out) override;
  void void_fraction(std::span<double> out) const override;
  std::int32_t add_shape(std::string_view spec) override;
  vfe::Engine::WeightsSize weights_size() const override { return local->weights_size(); }
  void weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells,
               std::span<double> fractions) const override;
  void deposit(std::int32_t components, std::span<const double> values, std::span<double> out) override;
  void interpolate(std::int32_t components, std::span<const double> cell_field, std::span<double> out) override;
  void set_log_callback(vfe_log_fn fn, void* user) override;
  const vfe::Report& last_report() const override { return report; }
  double last_report_value(std::string_view key) const override;
};

// CPU time of the calling thread: the local compute's cost, whatever else shares the cores.
double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

// Gives a new local engine the options, log callback and shapes of the one it replaces.
void keep_settings(const DistributedEngine& e, vfe::Engine& local) {
  if (e.local) local.configure(e.local->options());
  if (e.log_fn) local.set_log_callback(e.log_fn, e.log_user);
  for (const std::string& spec : e.shape_specs) local.add_shape(spec);
}

// Builds the local engine on the extended block and its halo plan; keeps the options and
// log callback of the engine it replaces. Collective.
void rebuild(DistributedEngine& e, const Index3& ghost) {
  Decomposition dec = e.dec;
  dec.ghost = ghost;
  const Box ext = dec.extended(e.rank);
  vfe::CartesianGridSpec spec;
  for (int d = 0; d < 3; ++d) {
    spec.origin[d] = e.origin[d];  // the block of the global grid: its coordinates, bit for bit
    spec.first_cell[d] = ext.lo[d];
    spec.spacing[d] = e.spacing[d];
    spec.cells[d] = ext.hi[d] - ext.lo[d];
  }
  auto local = std::make_unique<vfe::Engine>(spec);
  keep_settings(e, *local);
  Halo halo(e.comm, vfe::mpi::cartesian_halo(dec, e.rank));
  e.dec = dec;
  e.local = std::move(local);
  e.halo = std::move(halo);
  e.extended.assign(static_cast<std::size_t>(ext.count()), 0.0);
}

// The first failing rank's status and message, thrown on every rank as an Error (the
// message prefixed by that rank's number when there are several): one allreduce when all
// succeeded, which also takes the maximum over ranks of `maxima` (in place). Collective.
void agree(DistributedEngine& e, vfe_status mine, const std::string& message, std::span<double> maxima = {}) {
  std::vector<double> in(1 + maxima.size()), out(in.size());
  in[0] = -double(mine == VFE_OK ? e.size : e.rank);  // the largest is the first failing rank
  std::copy(maxima.begin(), maxima.end(), in.begin() + 1);
  MPI_Allreduce(in.data(), out.data(), int(in.size()), MPI_DOUBLE, MPI_MAX, e.comm);
  std::copy(out.begin() + 1, out.end(), maxima.begin());
  const int first = int(-out[0]);
  if (first == e.size) return;
  int status = mine;
  MPI_Bcast(&status, 1, MPI_INT, first, e.comm);
  std::string text = message;
  int length = static_cast<int>(text.size());
  MPI_Bcast(&length, 1, MPI_INT, first, e.comm);
  text.resize(static_cast<std::size_t>(length));
  MPI_Bcast(text.data(), length, MPI_CHAR, first, e.comm);
  throw Error(static_cast<vfe_status>(status), e.size > 1 ? "rank " + std::to_string(first) + ": " + text : text);
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

// Runs a rank's part of a collective call and agrees on its outcome (throws the first
// failure on every rank).
template <class F>
void collective(DistributedEngine& e, F&& f, std::span<double> maxima = {}) {
  std::string message;
  const vfe_status mine = attempt(f, message);
  agree(e, mine, message, maxima);
}

void require(bool ok, const std::string& message) {
  if (!ok) throw Error(VFE_ERROR_INVALID_ARGUMENT, message);
}

// Global cell of a centre under the particle contract: periodic axes wrapped, others clamped.
Index3 centre_cell(const DistributedEngine& e, const double* x) {
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

int owner_of(const DistributedEngine& e, const Index3& cell);

// Rank owning the cell that holds x: on a polyMesh from the local mesh (-1 when x is in no
// cell held here), on a grid from the blocks.
int owner_rank(const DistributedEngine& e, const double* x) {
  if (!e.poly) return owner_of(e, centre_cell(e, x));
  std::int64_t cell = -1;
  e.local->locate({x, 3}, {&cell, 1});
  if (cell < 0) return -1;
  return cell < e.owned_cells() ? e.rank : e.poly->ghost_owner[static_cast<std::size_t>(cell - e.owned_cells())];
}

int owner_of(const DistributedEngine& e, const Index3& cell) {
  // Blocks tile the grid, so exactly one holds the cell. Linear in the ranks (see
  // docs/scaling.md for when a lookup table would pay).
  for (int q = 0; q < e.size; ++q)
    if (e.dec.blocks[static_cast<std::size_t>(q)].contains(cell)) return q;
  return -1;
}

// How far beyond a particle's centre (per axis) the footprint of a sphere of max_radius
// reaches under the local engine's method, or a shaped particle's body (max_shape: its
// scale times its shape's reach, for pmm and direct, the shapes' methods: direct deposits at
// the body's centroid), and how many cells more the method's stencil takes (trilinear's
// cell centres).
double footprint_reach(const DistributedEngine& e, double max_radius, double max_shape, double& extra_cells) {
  const std::string method = e.local->option("method");
  double reach = 0;
  extra_cells = 0;
  if (method == "direct")
    reach = 0;
  else if (method == "pmm" || method == "exact" || method == "divided" || method == "big_particle" ||
           method == "auto")  // auto: per sphere the fast path, pmm or exact, all within the ball
    reach = max_radius;
  else if (method == "gaussian")
    reach = 6.0 * std::stod(e.local->option("sigma")) * max_radius;  // 3 sigma, sigma in diameters
  else if (method == "porous_cube")
    reach = std::stod(e.local->option("gamma")) * max_radius;  // half of gamma * d
  else if (method == "trilinear")
    extra_cells = 1;  // the 8 cells whose centres surround the particle's centre
  else
    throw Error(VFE_ERROR_UNSUPPORTED, "method " + method + " has no known footprint in vfe_mpi");
  return std::max(reach, max_shape);
}

// The reach per axis in cells, plus one cell so that a deposit never reaches the ghost
// layer's last cells (checked after compute).
Index3 ghost_needed(const DistributedEngine& e, double max_radius, double max_shape) {
  double extra_cells = 0;
  const double reach = footprint_reach(e, max_radius, max_shape, extra_cells);
  Index3 g{};
  for (int d = 0; d < 3; ++d)
    g[d] = static_cast<std::int64_t>(std::ceil(reach / e.spacing[d])) + static_cast<std::int64_t>(extra_cells) + 1;
  return g;
}

// The ghost width (a length) a polyMesh needs for particles of max_radius whose centres lie
// at most `beyond` outside this rank's cells (those outside the whole mesh): the footprint,
// and when volume beyond the mesh goes to the nearest cells the cells whose centres can be nearest to a point of it
// (within sqrt(3) (reach + beyond) + the owning cell's diagonal of the point), plus one
// cell so that the layer's outer edge stays clear (checked after compute).
double poly_width_needed(const DistributedEngine& e, double max_radius, double max_shape, double beyond) {
  double extra_cells = 0;
  double reach = footprint_reach(e, max_radius, max_shape, extra_cells) + beyond;
  const double h = e.poly->largest_cell;
  const std::string outside = e.local->option("outside");
  // outside=error with a tolerance sends the tolerated volume to the nearest cells too.
  if (outside == "nearest" || (outside == "error" && std::stod(e.local->option("outside_tolerance")) > 0))
    reach += std::sqrt(3.0) * (reach + h);
  return reach + (1.0 + extra_cells) * h * 1.01;
}

// Sum of |value| over the last ghost layer on each side that faces another block: the
// margin cell of ghost_needed, which only a footprint wider than assumed can reach.
double edge_layer_volume(const DistributedEngine& e) {
  if (e.poly) {
    double sum = 0;
    for (const std::int64_t c : e.poly->rim) sum += std::abs(e.extended[static_cast<std::size_t>(c)]);
    return sum;
  }
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
template <class T>
void copy_owned(const DistributedEngine& e, bool to_owned, T* extended, T* owned, int k) {
  if (e.poly) {  // owned cells come first
    const std::size_t n = static_cast<std::size_t>(e.owned_cells() * k);
    if (to_owned)
      std::copy_n(extended, n, owned);
    else
      std::copy_n(owned, n, extended);
    return;
  }
  const Box ext = e.dec.extended(e.rank), b = e.block();
  const Index3 n = ext.extent(), m = b.extent();
  for (std::int64_t z = 0; z < m[2]; ++z)
    for (std::int64_t y = 0; y < m[1]; ++y) {
      T* in_extended =
          extended + k * ((b.lo[0] - ext.lo[0]) + n[0] * ((y + b.lo[1] - ext.lo[1]) + n[1] * (z + b.lo[2] - ext.lo[2])));
      T* in_owned = owned + k * (m[0] * (y + m[1] * z));
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

// The largest sphere radius and the farthest a shaped particle's body reaches (its scale
// times its shape's reach) among the rank's particles; non-finite scales and unknown shape
// ids are skipped (the local engine names them).
std::array<double, 2> largest_reach(const DistributedEngine& e, const vfe_particles& p) {
  std::array<double, 2> largest{0, 0};
  for (std::int64_t i = 0; i < p.n; ++i) {
    const double r = *at(p.radii, p.radii_stride, 1, i);
    if (!std::isfinite(r)) continue;
    if (!p.shape_ids) {
      largest[0] = std::max(largest[0], r);
      continue;
    }
    const std::int32_t id = *at(p.shape_ids, p.shape_ids_stride, 1, i);
    if (id >= 0 && static_cast<std::size_t>(id) < e.shape_reaches.size())
      largest[1] = std::max(largest[1], r * e.shape_reaches[static_cast<std::size_t>(id)]);
  }
  return largest;
}

// The rank's particles checked against the contract; when a centre lies outside the grid on
// a periodic axis, fills wrapped with every centre wrapped into the grid (as the serial
// engine wraps them).
void check_particles(const DistributedEngine& e, const vfe_particles& p, std::vector<double>& wrapped) {
  bool wrap = false;
  for (std::int64_t i = 0; i < p.n; ++i) {
    const double* x = at(p.centres, p.centres_stride, 3, i);
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
}

// The report over all ranks: the local reports' sums, particle grid sizes over the ranks
// with particles (grid_extremes: max and -min, already reduced), deposited and clipped volume
// of the owned fields. Returns how many ranks failed the halo sum (in the same allreduce).
int gather_report(DistributedEngine& e, bool halo_failed, const double grid_extremes[2]) {
  const vfe_report r = e.local->last_report();
  const double alpha_min = std::stod(e.local->option("alpha_min"));
  double deposited = 0, clipped = 0;
  for (std::size_t c = 0; c < e.solid.size(); ++c) {
    deposited += e.solid[c];
    if (alpha_min > 0) clipped += std::max(0.0, e.solid[c] - (1.0 - alpha_min) * e.cell_volume(c));
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

// Builds the local engine on the owned cells and a ghost layer of the given width, and its
// halo plan; keeps the options and log callback of the engine it replaces. Collective.
void rebuild_poly(DistributedEngine& e, double width) {
  DistributedPolyMesh& p = *e.poly;
  vfe::mpi::GhostedPolyMesh g = vfe::mpi::build_ghosted(e.comm, p.mesh, p.boxes, width);
  Halo halo(e.comm, std::move(g.peers));  // collective: before anything that may fail on one rank
  auto local = std::make_unique<vfe::Engine>(g.mesh.view());
  keep_settings(e, *local);
  e.local = std::move(local);
  e.halo = std::move(halo);
  e.extended.assign(static_cast<std::size_t>(e.local->cell_count()), 0.0);
  p.width = width;
  p.cell_ids = std::move(g.cell_ids);
  p.ghost_owner = std::move(g.ghost_owner);
  p.rim = std::move(g.rim);
  p.ghost_bytes = g.ghost_bytes;
}

// The local cells holding the rank's particles' centres (-1 in none).
std::vector<std::int64_t> locate_centres(const DistributedEngine& e, const vfe_particles& p) {
  std::vector<double> x(static_cast<std::size_t>(3 * p.n));
  for (std::int64_t i = 0; i < p.n; ++i) std::copy_n(at(p.centres, p.centres_stride, 3, i), 3, &x[static_cast<std::size_t>(3 * i)]);
  std::vector<std::int64_t> cells(static_cast<std::size_t>(p.n));
  e.local->locate(x, cells);
  return cells;
}

std::string who(const vfe_particles& p, std::int64_t i) {
  std::string w = "particle " + std::to_string(i);
  if (p.ids) w += " (id " + std::to_string(*at(p.ids, p.ids_stride, 1, i)) + ")";
  return w;
}

std::string wrong_rank(const vfe_particles& p, std::int64_t i, const std::string& cell, int owner, int rank) {
  return who(p, i) + " has its centre in " + cell + ", owned by rank " + std::to_string(owner) + ", not by this rank " +
         std::to_string(rank) + ": give each particle on the rank owning its centre's cell (vfe_mpi_owner, "
         "vfe_mpi_route_particles)";
}

// A polyMesh rank's particles checked against the contract: a centre in a ghost cell
// fails (naming the owner); centres in no cell held here go to `unlocated` for
// place_outside_centres.
void check_poly_particles(const DistributedEngine& e, const vfe_particles& p, std::vector<std::int64_t>& unlocated) {
  const std::vector<std::int64_t> cells = locate_centres(e, p);
  const std::int64_t owned = e.owned_cells();
  for (std::int64_t i = 0; i < p.n; ++i) {
    const double* x = at(p.centres, p.centres_stride, 3, i);
    if (!(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]))) continue;  // the engine names it
    const std::int64_t c = cells[static_cast<std::size_t>(i)];
    if (c < 0)
      unlocated.push_back(i);
    else if (c >= owned)
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  wrong_rank(p, i, "global cell " + std::to_string(e.poly->cell_ids[static_cast<std::size_t>(c)]),
                             e.poly->ghost_owner[static_cast<std::size_t>(c - owned)], e.rank));
  }
}

// Collective. The owners of centres no rank's local mesh placed (every rank passes its own
// list, 3 values per centre; the lists are gathered everywhere): a centre inside a rank's
// cells belongs to that rank, one outside the whole mesh to the rank of the cell whose
// centre is nearest (the serial engine's rule for outside=nearest). Also returns, on every
// rank, how far outside the mesh the farthest of all these centres lies (its distance to
// that nearest cell centre; 0 when all are inside).
std::vector<int> owners_of_unplaced(const DistributedEngine& e, const std::vector<double>& x, double& beyond) {
  const int count = static_cast<int>(x.size());
  std::vector<int> counts(static_cast<std::size_t>(e.size)), displs(static_cast<std::size_t>(e.size), 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, e.comm);
  for (int q = 1; q < e.size; ++q) displs[q] = displs[q - 1] + counts[q - 1];
  std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(x.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, e.comm);
  const std::size_t n = all.size() / 3;
  std::vector<std::int64_t> cells(n);
  e.local->locate(all, cells);
  std::vector<double> centres(static_cast<std::size_t>(3 * e.local->cell_count()));
  e.local->cell_centres(centres);
  centres.resize(static_cast<std::size_t>(3 * e.owned_cells()));
  // (distance, rank): -1 when the centre lies in one of this rank's cells, else the distance
  // to its nearest owned cell centre (brute force: these centres are few); the smallest over
  // ranks names the owner.
  struct Candidate {
    double distance;
    int rank;
  };
  std::vector<Candidate> mine(n), best(n);
  for (std::size_t k = 0; k < n; ++k) {
    double d2 = std::numeric_limits<double>::infinity();
    if (cells[k] >= 0 && cells[k] < e.owned_cells())
      d2 = -1;
    else
      for (std::size_t c = 0; c < centres.size() / 3; ++c) {
        double s = 0;
        for (int d = 0; d < 3; ++d) s += (all[3 * k + d] - centres[3 * c + d]) * (all[3 * k + d] - centres[3 * c + d]);
        d2 = std::min(d2, s);
      }
    mine[k] = {d2 < 0 ? -1.0 : std::sqrt(d2), e.rank};
  }
  MPI_Allreduce(mine.data(), best.data(), static_cast<int>(n), MPI_DOUBLE_INT, MPI_MINLOC, e.comm);
  beyond = 0;
  for (std::size_t k = 0; k < n; ++k) beyond = std::max(beyond, best[k].distance);
  std::vector<int> owners;
  const std::size_t first = static_cast<std::size_t>(displs[static_cast<std::size_t>(e.rank)]) / 3;
  for (std::size_t j = 0; j < x.size() / 3; ++j) owners.push_back(best[first + j].rank);
  return owners;
}

// Collective. The rank's particles whose centres lie in no cell held here (`mine`) must
// belong to it by owners_of_unplaced's rule; returns its `beyond`.
double place_outside_centres(const DistributedEngine& e, const vfe_particles& p, const std::vector<std::int64_t>& mine) {
  std::vector<double> x;
  for (const std::int64_t i : mine) x.insert(x.end(), at(p.centres, p.centres_stride, 3, i), at(p.centres, p.centres_stride, 3, i) + 3);
  double beyond = 0;
  const std::vector<int> owners = owners_of_unplaced(e, x, beyond);
  for (std::size_t j = 0; j < mine.size(); ++j)
    if (owners[j] != e.rank)
      throw Error(VFE_ERROR_INVALID_ARGUMENT, wrong_rank(p, mine[j], "a cell outside this rank's ghost layer, or in no cell "
                                                                     "(then the owner is that of the nearest cell centre)",
                                                         owners[j], e.rank));
  return beyond;
}

}  // namespace

// One compute: three small allreduces (contract and largest radius; the local computes'
// outcome and grid sizes; the report) and one neighbour exchange, plus a rebuild of the
// ghost layer when a footprint needs a wider one.
void DistributedEngine::compute(const vfe_particles& p, std::span<double> out) {
  std::vector<double> wrapped;
  std::vector<std::int64_t> unlocated;  // a polyMesh's particles whose centres lie in no cell held here
  double maxima[4] = {0, 0, 0, 0};  // largest sphere radius, shape reach, unlocated centres, particle volume
  collective(
      *this,
      [&] {
        require(p.n >= 0, "n must be >= 0");
        require(p.n == 0 || (p.centres && p.radii), "centres and radii must not be NULL");
        // The serial engine sizes a shape's auto template from the largest particle of the
        // compute and the mesh's smallest cell: here each rank's own, so the fields would differ.
        if (p.shape_ids && p.n > 0 && local->option("method") == "pmm" && local->option("particle_grid") == "auto")
          throw Error(VFE_ERROR_UNSUPPORTED,
                      "method=pmm with particle_grid=auto sizes a shape's template from the largest particle of the "
                      "compute, which differs per rank on a distributed engine: give particle_grid=N for shapes");
        if (!p.ids && p.n > 0 && local->option("method") == "pmm" && local->option("orientation") == "random")
          throw Error(VFE_ERROR_INVALID_ARGUMENT,
                      "method=pmm with orientation=random rotates each particle by its id, which must not depend on "
                      "the rank: pass the particle ids (vfe_particles.ids, vfe_compute_particles)");
        if (poly) {
          check_poly_particles(*this, p, unlocated);
          maxima[2] = double(unlocated.size());
        } else {
          check_particles(*this, p, wrapped);
        }
        const std::array<double, 2> largest = largest_reach(*this, p);
        maxima[0] = largest[0];
        maxima[1] = largest[1];
        if (local->option("deterministic") == "1") maxima[3] = local->largest_particle_volume(p);
      },
      maxima);
  const double max_radius = maxima[0], max_shape = maxima[1];
  // Every rank has the same largest radius and options, so all decide alike.
  if (poly) {
    double beyond = 0;
    if (maxima[2] > 0)  // some centres lie in no cell this rank holds
      collective(*this, [&] { beyond = place_outside_centres(*this, p, unlocated); });
    const double width = poly_width_needed(*this, max_radius, max_shape, beyond);
    if (width > poly->width) collective(*this, [&] { rebuild_poly(*this, width); });
  } else {
    const Index3 need = ghost_needed(*this, max_radius, max_shape);
    if (need[0] > dec.ghost[0] || need[1] > dec.ghost[1] || need[2] > dec.ghost[2])
      collective(*this, [&] {
        rebuild(*this, {std::max(need[0], dec.ghost[0]), std::max(need[1], dec.ghost[1]),
                        std::max(need[2], dec.ghost[2])});
      });
  }
  double grid_extremes[2] = {0, -std::numeric_limits<double>::max()};
  collective(
      *this,
      [&] {
        vfe_particles mine = p;
        if (!wrapped.empty()) {
          mine.centres = wrapped.data();
          mine.centres_stride = 0;
        }
        const double wall0 = MPI_Wtime(), cpu0 = thread_cpu_seconds();
        local->set_deterministic_volume(maxima[3]);  // deterministic=1: one fixed-point unit on every rank
        local->compute(mine, extended);
        local_cpu_seconds = thread_cpu_seconds() - cpu0;
        local_seconds = MPI_Wtime() - wall0;
        if (edge_layer_volume(*this) != 0)
          throw Error(VFE_ERROR_INTERNAL,
                      "a deposit reached the outer ghost layer, so the ghost layer was narrower than a footprint: "
                      "please report this with the options used");
        const vfe_report& r = local->last_report();
        if (r.particles > 0) {
          grid_extremes[0] = double(r.particle_grid_max);
          grid_extremes[1] = -double(r.particle_grid_min);
        }
      },
      grid_extremes);
  const double exchange0 = MPI_Wtime();
  std::string message;
  const vfe_status halo_sum = attempt(
      [&] {
        std::vector<double> owned(static_cast<std::size_t>(owned_cells()));
        if (local->option("deterministic") == "1") {  // integers: the owner's sum is the serial one, bit for bit
          const Engine::FixedField fixed = local->fixed_solid();
          std::vector<FixedSum> ext(fixed.sums.begin(), fixed.sums.end()), mine(owned.size());
          copy_owned(*this, true, ext.data(), mine.data(), 1);
          halo.reverse_sum(std::span<const FixedSum>(ext), mine, 1);
          for (std::size_t c = 0; c < owned.size(); ++c) owned[c] = from_fixed(mine[c], fixed.exponent);
        } else {
          copy_owned(*this, true, extended.data(), owned.data(), 1);
          halo.reverse_sum(extended, owned, 1);
        }
        solid = std::move(owned);
      },
      message);
  const int halo_failures = gather_report(*this, halo_sum != VFE_OK, grid_extremes);
  exchange_seconds = MPI_Wtime() - exchange0;
  if (halo_failures > 0) {
    have_field = false;
    throw Error(VFE_ERROR_INTERNAL, halo_sum != VFE_OK ? message : "the halo sum failed on another rank");
  }
  have_field = true;
  std::copy(solid.begin(), solid.end(), out.begin());
}

namespace {

void check_blocks(const DistributedEngine& e) {
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
std::string take_periodic(const std::string& options, std::array<bool, 3>& periodic, bool& given) {
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

// The distributed engine behind a handle, or an Error naming the caller when e is
// libvfe's own engine.
const DistributedEngine& distributed(const vfe::detail::EngineBackend* backend, const char* caller) {
  const auto* d = dynamic_cast<const DistributedEngine*>(backend);
  if (!d)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                std::string(caller) + ": the engine is not distributed; pass an engine made by vfe_mpi_create_cartesian, "
                                      "vfe_mpi_create_polymesh or vfe_mpi_create_polymesh_arrays");
  return *d;
}

// Creates a polyMesh engine from the rank's cells that load() gives (run on every rank;
// its failure on one rank fails the call everywhere).
template <class Load>
vfe_status create_polymesh(MPI_Comm comm, vfe_engine** out, const char* caller, Load&& load) {
  return vfe::detail::create_engine(
      [&]() -> std::unique_ptr<vfe::detail::EngineBackend> {
        require(comm != MPI_COMM_NULL, std::string(caller) + ": comm is MPI_COMM_NULL");
        auto e = std::make_unique<DistributedEngine>(comm);
        e->poly = std::make_unique<DistributedPolyMesh>();
        double largest = 0;
        collective(
            *e,
            [&] {
              require(out != nullptr, std::string(caller) + ": out is NULL");
              DistributedPolyMesh& p = *e->poly;
              load(p.mesh);
              vfe::mpi::check_rank_mesh(p.mesh);
              p.boxes = vfe::mpi::cell_boxes(p.mesh);
              for (std::size_t c = 0; c < p.boxes.size() / 6; ++c)
                for (int d = 0; d < 3; ++d) largest = std::max(largest, p.boxes[6 * c + 3 + d] - p.boxes[6 * c + d]);
              const vfe::Engine owned(p.mesh.mesh.view());  // validates the rank's mesh and gives its volumes
              p.volumes.resize(static_cast<std::size_t>(owned.cell_count()));
              owned.cell_volumes(p.volumes);
            },
            {&largest, 1});
        e->poly->largest_cell = largest;
        collective(*e, [&] { rebuild_poly(*e, 1.01 * largest); });
        return e;
      },
      out);
}

}  // namespace

void DistributedEngine::agree(vfe_status mine, const std::string& message) { ::agree(*this, mine, message); }

void DistributedEngine::configure(std::string_view options) {
  std::array<bool, 3> periodic = dec.periodic;
  bool periodic_given = false;
  std::string rest;
  collective(*this, [&] {
    // On a polyMesh periodic= goes to the local engine, which refuses it.
    rest = poly ? std::string(options) : take_periodic(std::string(options), periodic, periodic_given);
    // Checked on a scratch engine first, so a refused option string changes nothing.
    vfe::Engine scratch(vfe::CartesianGridSpec{});
    scratch.configure(local->options());
    scratch.configure(rest);
    // The engine's smoothing is an implicit diffusion over the whole mesh: no ghost layer
    // reaches as far, so it would need a distributed solve.
    if (std::stod(scratch.option("smoothing_length")) != 0)
      throw Error(VFE_ERROR_UNSUPPORTED,
                  "smoothing_length: the smoothing solves a diffusion over the whole mesh, which a distributed engine "
                  "does not do across ranks; set smoothing_length=0 and smooth on the host's decomposed mesh");
  });
  collective(*this, [&] {
    local->configure(rest);
    if (periodic_given && periodic != dec.periodic) {
      dec.periodic = periodic;
      rebuild(*this, dec.ghost);
    }
    have_field = false;
  });
}

void DistributedEngine::cell_volumes(std::span<double> out) const {
  for (std::int64_t c = 0; c < owned_cells(); ++c) out[c] = cell_volume(static_cast<std::size_t>(c));
}

void DistributedEngine::void_fraction(std::span<double> out) const {
  require(have_field, "no compute since creation or the last configure; compute first");
  const double alpha_min = std::stod(local->option("alpha_min"));
  for (std::size_t c = 0; c < solid.size(); ++c) {
    const double eps = 1.0 - solid[c] / cell_volume(c);
    out[c] = alpha_min > 0 && eps < alpha_min ? alpha_min : eps;
  }
}

std::int32_t DistributedEngine::add_shape(std::string_view spec) {
  // Read on a scratch engine first, so a spec one rank cannot read (a mesh file it does not
  // see) adds the shape on no rank and the ids stay the same on every rank.
  double reach = 0;
  collective(*this, [&] {
    vfe::Engine scratch(vfe::CartesianGridSpec{});
    reach = scratch.shape_reach(scratch.add_shape(spec));
  });
  std::int32_t id = -1;
  collective(*this, [&] { id = local->add_shape(spec); });
  shape_specs.emplace_back(spec);  // rebuilt local engines register it again (keep_settings)
  shape_reaches.push_back(reach);
  return id;
}

void DistributedEngine::weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells,
                                std::span<double> fractions) const {
  local->weights(offsets, cells, fractions);
  if (poly) {
    for (std::int64_t& cell : cells) cell = poly->cell_ids[static_cast<std::size_t>(cell)];
    return;
  }
  const Box ext = dec.extended(rank);
  const Index3 n = ext.extent(), g = dec.cells;
  for (std::int64_t& cell : cells) {
    Index3 ijk{cell % n[0], (cell / n[0]) % n[1], cell / (n[0] * n[1])};
    for (int d = 0; d < 3; ++d) ijk[d] = (((ijk[d] + ext.lo[d]) % g[d]) + g[d]) % g[d];
    cell = ijk[0] + g[0] * (ijk[1] + g[1] * ijk[2]);
  }
}

void DistributedEngine::deposit(std::int32_t components, std::span<const double> values, std::span<double> out) {
  const std::size_t k = static_cast<std::size_t>(components);
  std::vector<double> owned(static_cast<std::size_t>(owned_cells()) * k);
  if (local->option("deterministic") == "1") {
    // Fixed point in units set by each component's largest |value| over all ranks, so that
    // owners add the ghosts' integers exactly: the serial engine's sums, bit for bit.
    std::vector<double> largest(k, 0.0);
    collective(
        *this,
        [&] {
          const std::size_t n = static_cast<std::size_t>(local->weights_size().particles);
          for (std::size_t i = 0; i < std::min(values.size(), n * k); ++i)
            largest[i % k] = std::max(largest[i % k], std::abs(values[i]));
        },
        largest);
    collective(*this, [&] {
      std::vector<int> exponents(k);
      for (std::size_t j = 0; j < k; ++j) exponents[j] = fixed_unit_exponent(largest[j]);
      std::vector<FixedSum> ext(extended.size() * k), mine(owned.size());
      local->deposit_fixed(components, values, exponents, ext);
      copy_owned(*this, true, ext.data(), mine.data(), components);
      halo.reverse_sum(std::span<const FixedSum>(ext), mine, components);
      for (std::size_t i = 0; i < owned.size(); ++i) owned[i] = from_fixed(mine[i], exponents[i % k]);
    });
  } else {
    collective(*this, [&] {
      std::vector<double> ext(extended.size() * k);
      local->deposit(components, values, ext);
      copy_owned(*this, true, ext.data(), owned.data(), components);
      halo.reverse_sum(ext, owned, components);
    });
  }
  std::copy(owned.begin(), owned.end(), out.begin());
}

void DistributedEngine::interpolate(std::int32_t components, std::span<const double> cell_field,
                                    std::span<double> out) {
  std::vector<double> result;
  collective(*this, [&] {
    std::vector<double> ext(extended.size() * static_cast<std::size_t>(components), 0.0);
    copy_owned(*this, false, ext.data(), const_cast<double*>(cell_field.data()), components);  // reads cell_field
    halo.forward_fill(cell_field, ext, components);
    result.resize(out.size());
    local->interpolate(components, ext, result);
  });
  std::copy(result.begin(), result.end(), out.begin());
}

void DistributedEngine::set_log_callback(vfe_log_fn fn, void* user) {
  local->set_log_callback(fn, user);
  log_fn = fn;
  log_user = user;
}

double DistributedEngine::last_report_value(std::string_view key) const {
  double field = 0;
  if (vfe::detail::report_field(report, key, field)) return field;  // over all ranks
  const std::int64_t halo_values = halo.ghost_cells_sent();
  const std::pair<std::string_view, double> facts[] = {  // this rank's
      {"ghost_width", poly ? poly->width : double(*std::max_element(dec.ghost.begin(), dec.ghost.end()))},
      {"ghost_bytes", poly ? double(poly->ghost_bytes) : 0.0},
      {"neighbours", double(halo.peers().size())},
      {"local_cells", double(extended.size())},
      {"halo_values", double(halo_values)},
      {"halo_bytes", double(halo_values) * double(sizeof(double))},
      {"local_seconds", local_seconds},
      {"local_cpu_seconds", local_cpu_seconds},
      {"exchange_seconds", exchange_seconds},
  };
  for (const auto& [name, value] : facts)
    if (name == key) return value;
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "unknown report key '" + std::string(key.substr(0, 64)) +
                                              "' for a distributed engine; see vfe_mpi.h for its keys");
}

extern "C" {

vfe_status vfe_mpi_create_cartesian(MPI_Comm comm, const double origin[3], const double spacing[3],
                                    const int64_t global_cells[3], const int64_t block_lo[3],
                                    const int64_t block_hi[3], vfe_engine** out) {
  return vfe::detail::create_engine(
      [&]() -> std::unique_ptr<vfe::detail::EngineBackend> {
        require(comm != MPI_COMM_NULL, "vfe_mpi_create_cartesian: comm is MPI_COMM_NULL");
        auto e = std::make_unique<DistributedEngine>(comm);
        // Arguments are checked after the blocks are gathered, so that every rank fails alike.
        const bool given = origin && spacing && global_cells && block_lo && block_hi && out;
        std::int64_t mine[6] = {0, 0, 0, 0, 0, 0};
        if (given)
          for (int d = 0; d < 3; ++d) {
            mine[d] = block_lo[d];
            mine[3 + d] = block_hi[d];
          }
        std::vector<std::int64_t> all(static_cast<std::size_t>(6 * e->size));
        MPI_Allgather(mine, 6, MPI_INT64_T, all.data(), 6, MPI_INT64_T, e->comm);
        collective(*e, [&] {
          require(given,
                  "vfe_mpi_create_cartesian: origin, spacing, global_cells, block_lo, block_hi and out must not be NULL");
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
        collective(*e, [&] { rebuild(*e, {1, 1, 1}); });
        return e;
      },
      out);
}

vfe_status vfe_mpi_create_polymesh(MPI_Comm comm, const char* processor_dir, vfe_engine** out) {
  int size = 1;
  if (comm != MPI_COMM_NULL) MPI_Comm_size(comm, &size);
  return create_polymesh(comm, out, "vfe_mpi_create_polymesh", [&](vfe::mpi::RankPolyMesh& m) {
    require(processor_dir != nullptr, "vfe_mpi_create_polymesh: processor_dir is NULL");
    m.mesh = vfe::read_polymesh_buffers(processor_dir);
    const std::int64_t points = static_cast<std::int64_t>(m.mesh.points.size() / 3);
    const std::int64_t faces = static_cast<std::int64_t>(m.mesh.owner.size());
    std::int64_t cells = 0;
    for (const std::int64_t c : m.mesh.owner) cells = std::max(cells, c + 1);
    const bool decomposed = [&] {
      try {
        m.cell_ids = vfe::read_polymesh_labels(processor_dir, "cellProcAddressing");
        return true;
      } catch (const Error& err) {
        if (err.status() != VFE_ERROR_IO || size > 1) throw;
        return false;
      }
    }();
    if (decomposed) {
      m.point_ids = vfe::read_polymesh_labels(processor_dir, "pointProcAddressing");
      m.face_ids = vfe::read_polymesh_labels(processor_dir, "faceProcAddressing");
    } else {  // one rank on an undecomposed mesh: its own numbering is the global one
      for (std::int64_t i = 0; i < points; ++i) m.point_ids.push_back(i);
      for (std::int64_t i = 0; i < faces; ++i) m.face_ids.push_back(i + 1);
      for (std::int64_t i = 0; i < cells; ++i) m.cell_ids.push_back(i);
    }
    m.coupled.assign(static_cast<std::size_t>(faces), 0);
    for (const vfe::PolyMeshBuffers::Patch& patch : m.mesh.patches)
      if (patch.type == "processor")
        std::fill_n(m.coupled.begin() + patch.start_face, patch.n_faces, 1);
      else
        require(patch.type.rfind("processorCyclic", 0) != 0 && patch.type.rfind("cyclic", 0) != 0,
                "vfe_mpi_create_polymesh: patch '" + patch.name + "' of " + std::string(processor_dir) + " is " +
                    patch.type + "; cyclic patches are not supported (their transforms are not applied)");
  });
}

vfe_status vfe_mpi_create_polymesh_arrays(MPI_Comm comm, const vfe_mpi_polymesh* mesh, vfe_engine** out) {
  return create_polymesh(comm, out, "vfe_mpi_create_polymesh_arrays", [&](vfe::mpi::RankPolyMesh& m) {
    require(mesh != nullptr, "vfe_mpi_create_polymesh_arrays: mesh is NULL");
    const vfe_mpi_polymesh& a = *mesh;
    require(a.n_points >= 0 && a.n_faces >= 0 && a.n_internal_faces >= 0 && a.n_internal_faces <= a.n_faces &&
                a.n_coupled_faces >= 0,
            "vfe_mpi_create_polymesh_arrays: counts must satisfy n_points, n_faces, n_coupled_faces >= 0 and "
            "0 <= n_internal_faces <= n_faces");
    require((a.n_points == 0 || (a.points && a.point_ids)) &&
                (a.n_faces == 0 || (a.face_offsets && a.face_points && a.owner && a.face_ids)) &&
                (a.n_internal_faces == 0 || a.neighbour) && (a.n_coupled_faces == 0 || a.coupled_faces),
            "vfe_mpi_create_polymesh_arrays: an array is NULL; pass arrays of the sizes vfe_mpi.h gives");
    const auto copy = [](auto* first, std::int64_t n) { return std::vector(first, first + n); };
    m.mesh.points = copy(a.points, 3 * a.n_points);
    m.mesh.face_offsets = copy(a.face_offsets, a.n_faces + 1);
    require(m.mesh.face_offsets.front() == 0 && std::is_sorted(m.mesh.face_offsets.begin(), m.mesh.face_offsets.end()),
            "vfe_mpi_create_polymesh_arrays: face_offsets must start at 0 and not decrease");
    m.mesh.face_points = copy(a.face_points, m.mesh.face_offsets.back());
    m.mesh.owner = copy(a.owner, a.n_faces);
    m.mesh.neighbour = copy(a.neighbour, a.n_internal_faces);
    m.point_ids = copy(a.point_ids, a.n_points);
    m.face_ids = copy(a.face_ids, a.n_faces);
    std::int64_t cells = 0;
    for (const std::int64_t c : m.mesh.owner) cells = std::max(cells, c + 1);
    require(cells == 0 || a.cell_ids, "vfe_mpi_create_polymesh_arrays: cell_ids is NULL");
    m.cell_ids = copy(a.cell_ids, cells);
    m.coupled.assign(static_cast<std::size_t>(a.n_faces), 0);
    for (std::int64_t i = 0; i < a.n_coupled_faces; ++i) {
      const std::int64_t f = a.coupled_faces[i];
      require(f >= a.n_internal_faces && f < a.n_faces,
              "vfe_mpi_create_polymesh_arrays: coupled face " + std::to_string(f) +
                  " is not a boundary face (n_internal_faces <= face < n_faces)");
      m.coupled[static_cast<std::size_t>(f)] = 1;
    }
  });
}

vfe_status vfe_mpi_owner(const vfe_engine* e, const double centre[3], int* rank) {
  return vfe::detail::with_backend(e, [&](const vfe::detail::EngineBackend* backend) {
    const DistributedEngine& d = distributed(backend, "vfe_mpi_owner");
    require(centre && rank, "vfe_mpi_owner: centre and rank must not be NULL");
    require(std::isfinite(centre[0]) && std::isfinite(centre[1]) && std::isfinite(centre[2]),
            "vfe_mpi_owner: the centre must be finite");
    const int owner = owner_rank(d, centre);
    require(owner >= 0, "vfe_mpi_owner: the centre lies in no cell this rank owns or holds as a ghost; on a polyMesh "
                        "a rank knows its own cells and its ghost layer only (vfe_mpi_route_particles finds any owner)");
    *rank = owner;
  });
}

vfe_status vfe_mpi_route_particles(const vfe_engine* engine, int64_t n, const double* centres, const double* radii,
                                   const int64_t* ids, int64_t* n_out, double** centres_out, double** radii_out,
                                   int64_t** ids_out) {
  return vfe::detail::with_backend(engine, [&](vfe::detail::EngineBackend* backend) {
  auto& m = const_cast<DistributedEngine&>(distributed(backend, "vfe_mpi_route_particles"));
  const DistributedEngine* e = &m;
  std::vector<double> got_centres, got_radii;
  std::vector<std::int64_t> got_ids;
  collective(m, [&] {
    require(n >= 0, "vfe_mpi_route_particles: n must be >= 0");
    require(n == 0 || (centres && radii && ids), "vfe_mpi_route_particles: centres, radii and ids must not be NULL");
    require(n_out && centres_out && radii_out && ids_out, "vfe_mpi_route_particles: outputs must not be NULL");
    std::vector<int> dest(static_cast<std::size_t>(n));
    std::vector<int> counts(static_cast<std::size_t>(e->size), 0);
    std::vector<double> unplaced;  // a polyMesh's centres in no cell held here
    for (std::int64_t i = 0; i < n; ++i) {
      const double* x = centres + 3 * i;
      require(std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]),
              "vfe_mpi_route_particles: particle " + std::to_string(i) + " has a non-finite centre");
      dest[static_cast<std::size_t>(i)] = owner_rank(*e, x);
      if (dest[static_cast<std::size_t>(i)] < 0) unplaced.insert(unplaced.end(), x, x + 3);
    }
    if (e->poly) {
      double beyond = 0;
      const std::vector<int> owners = owners_of_unplaced(*e, unplaced, beyond);
      std::size_t next = 0;
      for (int& d : dest)
        if (d < 0) d = owners[next++];
    }
    for (const int d : dest) ++counts[static_cast<std::size_t>(d)];
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
  const std::size_t count = got_radii.size();
  double* c = static_cast<double*>(std::malloc(std::max<std::size_t>(1, 3 * count) * sizeof(double)));
  double* r = static_cast<double*>(std::malloc(std::max<std::size_t>(1, count) * sizeof(double)));
  int64_t* i = static_cast<int64_t*>(std::malloc(std::max<std::size_t>(1, count) * sizeof(int64_t)));
  if (!c || !r || !i) {
    std::free(c);
    std::free(r);
    std::free(i);
    // This rank only: the exchange itself succeeded everywhere.
    throw Error(VFE_ERROR_OUT_OF_MEMORY, "vfe_mpi_route_particles: out of memory for the received particles");
  }
  std::copy(got_centres.begin(), got_centres.end(), c);
  std::copy(got_radii.begin(), got_radii.end(), r);
  std::copy(got_ids.begin(), got_ids.end(), i);
  *n_out = static_cast<int64_t>(count);
  *centres_out = c;
  *radii_out = r;
  *ids_out = i;
  });
}

}  // extern "C"
