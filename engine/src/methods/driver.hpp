// What the per-method drivers share: one particle's deposits, the window of cells it can
// reach, and the outside policy. Each method's driver is one function in its own file
// (methods/<method>.cpp); its mathematics is in kernels/. The engine (engine.cpp)
// validates, schedules particle blocks over threads, calls a driver per particle and
// accumulates the deposits.
#pragma once

#include "cartesian_grid.hpp"
#include "options.hpp"
#include "particle_grid.hpp"
#include "pmm_plan.hpp"

#include <vfe/kernels/octant_split.hpp>
#include <vfe/kernels/particle_template.hpp>

#include <vfe/error.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace vfe::kernels {
class Shape;
}

namespace vfe::detail {

struct Deposit {
  std::int64_t cell;  ///< mesh cell, or cell_count() for the dropped-volume slot
  double volume;
};

/// Per-thread working memory, allocated once and reused by every particle.
struct Scratch {
  std::vector<Deposit> deposits;                 // one particle's deposits, merged by cell
  TemplateMemo template_memo;                    // pmm: the bank's last templates for this thread
  std::vector<double> nodes[3], orthant, patch;  // exact method
  std::vector<double> window;                    // volume per cell of the particle's window
  std::vector<std::int32_t> local_cells;         // pmm: window cell of each sub-element
  std::vector<double> lanes;                     // pmm: four partial sums per window cell
  std::vector<double> axis[3];                   // separable methods: weights per axis
  std::vector<std::int64_t> candidate_cells;     // polyMesh exact: cells near the particle
  std::vector<Eigen::Vector3d> cell_points;      // polyMesh exact: one cell's boundary polygons
  std::vector<std::int32_t> cell_face_offsets, cell_face_points;
  std::vector<Eigen::Vector3d> mapped_points;    // exact shapes: a cell's vertices in the ellipsoid's frame
  // polyMesh exact: each face's term of the located sum (owner's orientation) for the
  // particle numbered poly_particle, so that a face two cut cells share is computed once
  // (face-sized), and the particle that last marked each cell (cell-sized): entries of
  // earlier particles are stale, none is ever cleared (walk_ball_cells)
  struct FaceTerm {
    std::uint64_t particle;
    double value;
    bool sure;  ///< false: the centre lies within rounding of the face's plane or an edge line
  };
  std::vector<FaceTerm> face_terms;
  std::uint64_t poly_particle = 0;
  std::vector<std::uint64_t> cell_particle;
  std::int64_t fast_path = 0, sub_elements = 0, outside_particles = 0;
  std::int64_t counted = 0;  ///< pmm: particles whose sub-elements were counted per octant
  std::int64_t lattice_particles = 0;  // polyMesh of box cells: particles the grid's driver took
  std::int64_t auto_fast = 0, auto_pmm = 0, auto_exact = 0;  // method=auto: particles per path
  std::int64_t located_cells = 0, general_cells = 0;  // polyMesh exact: cut cells per overlap formula
  std::int64_t first_error = std::numeric_limits<std::int64_t>::max();
  std::int64_t grid_min = std::numeric_limits<std::int64_t>::max(), grid_max = 0;

  // pmm on a polyMesh (methods/polymesh.cpp; it also fills candidate_cells): the cells one
  // particle's sub-elements visit, with the volume they receive and, once a walk passes
  // through, their face planes (outward for that cell).
  struct PolyFace {
    Eigen::Vector3d normal, centre;  ///< outward unit normal, face centre
    double out_limit, deep_limit;    ///< beyond out_limit: outside; below deep_limit: deep
    std::int64_t next;               ///< the cell across the face, -1 on the boundary
  };
  struct PolyCell {
    std::int64_t cell;
    Eigen::Vector3d lo, hi;   ///< the cell's bounds
    bool deep;                ///< cell_accepts_deep_points
    std::int64_t first_face;  ///< in poly_faces, -1 until cached
    std::int64_t face_count;
    std::int64_t hits;        ///< sub-elements found in the cell
    double volume;            ///< their volume
  };
  std::vector<PolyFace> poly_faces;
  std::vector<PolyCell> poly_cells;
  std::vector<std::int32_t> poly_local;      // mesh cell -> index in poly_cells or -1 (mesh-sized)
  // mesh cell c -> entries 2c, 2c + 1: the points at the lowest and highest corner of a
  // cell that is a box, -1 for other cells, -2 not known yet (2 x mesh-sized)
  std::vector<std::int32_t> poly_box_corners;
  // Where the particle's box is tiled by box cells: their lattice (the cell boundaries
  // inside the box per axis) and the poly_cells index of each lattice cell (-1: no cell).
  std::vector<double> poly_nodes[3];
  std::vector<Eigen::AlignedBox3d> poly_boxes;  // the candidates' boxes
  std::vector<std::int32_t> poly_lattice;
  // outside=nearest: the cells whose centres can be nearest to a point of the particle,
  // by distance from its centre, with the volume they receive.
  struct PolyNear {
    Eigen::Vector3d centre;
    double distance;  ///< from the particle's centre
    std::int64_t cell;
    std::int64_t hits;
    double volume;
  };
  std::vector<PolyNear> poly_near;
  std::vector<std::int64_t> poly_near_cells;
  // The particle's box cut into bins, each with what it learnt: a cell holding one of its
  // sub-elements, whether that cell holds all the bin, the candidate cells whose bounds
  // reach it, the poly_near entries that can be nearest to its points (counts -1 until
  // needed).
  struct PolyBin {
    std::int32_t hint;   ///< index in poly_cells, or -1
    std::int32_t whole;  ///< index in poly_cells of the cell holding the bin, -1 untested, -2 none
    std::int32_t cells_first, cells_count;
    std::int32_t near_first, near_count;
  };
  std::vector<PolyBin> poly_bins;
  std::vector<PolyBin> poly_coarse_bins;  // 2 x 2 x 2 bins each (their near lists only)
  std::vector<std::int64_t> poly_bin_cells;
  std::vector<std::int32_t> poly_bin_near;

  void reset_counters() {
    fast_path = sub_elements = outside_particles = lattice_particles = grid_max = counted = 0;
    auto_fast = auto_pmm = auto_exact = 0;
    located_cells = general_cells = 0;
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

  void count_grid(std::int64_t n) {
    grid_min = std::min(grid_min, n);
    grid_max = std::max(grid_max, n);
  }
};

/// One particle as the drivers see it.
struct Particle {
  std::int64_t index;         ///< position in the host's arrays (error messages)
  Eigen::Vector3d centre;     ///< wrapped into the periodic axes
  double radius;              ///< sphere radius, or the shape's scale
  double volume;
  const double* orientation;  ///< quaternion (w, x, y, z) or null
  std::uint64_t rotation_key; ///< orientation=random draws the rotation from it (host id or index)
  /// A non-spherical particle: pmm's template of its shape (null for spheres: the bank's),
  /// and its centroid in template units (direct's point).
  const kernels::ParticleTemplate* shape_template = nullptr;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  const kernels::Shape* shape = nullptr;  ///< the body itself (exact's overlaps), null for spheres
  bool shaped = false;
  /// The outside policy for this particle: the option's, except that outside=error lets a
  /// particle within outside_tolerance of the mesh go to the nearest cells.
  Outside outside = Outside::nearest;
};

/// What every driver reads during one compute (never writes), whatever the mesh.
struct MethodContext {
  const Options& opts;
  TemplateBank bank;
  const kernels::ParticleTemplate& divided;  ///< the divided method's 29 points
};

/// The Cartesian grid's drivers' context.
struct Context : MethodContext {
  const CartesianGrid& grid;

  const kernels::ParticleTemplate& template_for(const Particle& p, Scratch& s) const {
    return p.shape_template ? *p.shape_template : bank.template_for(2 * p.radius, grid.cell_volume(), s.template_memo);
  }
};

/// The outside policy, the one place it is decided: volume of particle p that lies beyond
/// the mesh goes to nearest() (the cell nearest to where it is), to centre() (the cell of
/// the particle's centre, or the nearest to it), to the dropped-volume slot, or marks the
/// compute failed. flagged counts the particle once.
template <class Nearest, class CentreCell>
void apply_outside(Scratch& s, const Particle& p, double volume, Outside policy, std::int64_t dropped_slot,
                   bool& flagged, Nearest&& nearest, CentreCell&& centre) {
  if (!flagged) {
    flagged = true;
    ++s.outside_particles;
  }
  switch (policy) {
    case Outside::nearest: s.add(nearest(), volume); break;
    case Outside::centre: s.add(centre(), volume); break;
    case Outside::drop: s.add(dropped_slot, volume); break;
    case Outside::error: s.first_error = std::min(s.first_error, p.index); break;
  }
}

/// Refuses a footprint of more than 2^26 cells (2^20 along one axis): a particle that large
/// against its cells (or wrapping a periodic grid many times) would cost without bound.
inline void check_footprint(std::int64_t particle, double per_axis_max, double cells) {
  if (per_axis_max > double(1 << 20) || cells > double(1 << 26))
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "particle " + std::to_string(particle) + " spans about " + std::to_string(std::min(cells, 1e300)) +
                    " cells (limit 2^26, 2^20 along one axis); use cells no smaller than about 1/400 of the "
                    "particle diameter, or a periodic grid larger than the particle");
}

/// The cells a footprint around a centre can touch: per axis the cells from the one holding
/// centre - half to the one holding centre + half, clamped to one layer of virtual cells
/// around the mesh (coordinates -1 and n stand for "beyond this side"). Its local cell
/// (i, j, k) has index i + m[0] * (j + m[1] * k).
struct Window {
  std::int64_t lo[3];
  std::int64_t m[3];
  std::size_t size() const { return static_cast<std::size_t>(m[0] * m[1] * m[2]); }
};
inline Window make_window(const CartesianGrid& grid, const Eigen::Vector3d& c, const Eigen::Vector3d& half) {
  Window w;
  for (int d = 0; d < 3; ++d) {
    const std::int64_t n = grid.cells()[d];
    if (grid.periodic(d)) {  // real coordinates; emit_window wraps them
      w.lo[d] = grid.axis_index(d, c[d] - half[d]);
      w.m[d] = grid.axis_index(d, c[d] + half[d]) - w.lo[d] + 1;
      continue;
    }
    w.lo[d] = std::clamp<std::int64_t>(grid.axis_index(d, c[d] - half[d]), -1, n);
    w.m[d] = std::clamp<std::int64_t>(grid.axis_index(d, c[d] + half[d]), -1, n) - w.lo[d] + 1;
  }
  return w;
}

/// Node coordinates of a window's cells along axis d in the global grid's cell units
/// (local cell g spans [first + g, first + g + 1], as axis_coordinate measures),
/// m[d] + 1 values; the virtual cell below the mesh starts at -infinity and the one above
/// ends at +infinity.
void window_nodes(const CartesianGrid& grid, const Window& w, int d, std::vector<double>& nodes);

/// The one mesh cell wholly holding the box centre +- half, or -1 (always -1 with
/// fast_path=0, so every particle takes the general path).
std::int64_t single_cell(const Context& ctx, const Eigen::Vector3d& centre, const Eigen::Vector3d& half);

/// Volume of particle p that lies outside the mesh, handled by `policy`. nearest_cell is
/// the mesh cell nearest to where the volume is; flagged counts the particle once.
void outside(const Context& ctx, Scratch& s, const Particle& p, double volume, std::int64_t nearest_cell,
             bool& flagged, Outside policy);

/// Turns the window's volumes (s.window, local cell order) into deposits: cells of the
/// mesh first (distinct, no search), then the virtual cells beyond the mesh through the
/// outside policy.
void emit_window(const Context& ctx, Scratch& s, const Particle& p, const Window& w, Outside policy);

/// Deposits every point of a template (unit sphere) mapped by centre + radius * rotation *
/// point to the cell holding it, through the window machinery; rotation null = the
/// particle's (particle_rotation). Counts the particle's grid and sub-elements, and takes
/// the fast path (one deposit) when the whole template lies in one cell.
void deposit_points(const Context& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                    const Eigen::Matrix3d* rotation, Outside policy);

/// The rotation of particle p's template under the orientation option.
Eigen::Matrix3d particle_rotation(const Options& opts, const Particle& p);

/// The same rotation rounded to floats, row by row (9 values): the rotation bank's own float
/// copy when orientation=random draws from it, else particle_rotation converted into buffer.
const float* particle_rotation_rows(const Options& opts, const Particle& p, float buffer[9]);

/// deposit_points' counting path (kernels/octant_split.hpp) for a window of at most two
/// cells per axis, all of them mesh cells: the cells of the straightforward locate (floor of
/// base + (r / h) R q per axis, base the centre in cell units from the window's corner; R
/// given as floats row by row, particle_rotation_rows) with
/// one comparison per point and split axis; sink(cell, volume) per cell reached. False,
/// with nothing added, when it does not apply or float cannot decide a point: the caller
/// then locates every point.
template <class Sink>
bool deposit_by_octants(const Context& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                        const float* rotation_rows, const Window& w, const Eigen::Vector3d& base, Sink&& sink) {
  if (t.split_points.empty() || !ctx.opts.fast_path) return false;
  const CartesianGrid& grid = ctx.grid;
  unsigned split = 0;
  float tau[3] = {0, 0, 0};
  std::int64_t g[3][2];
  for (int d = 0; d < 3; ++d) {
    if (w.m[d] > 2) return false;
    g[d][0] = grid.cell_axis(d, w.lo[d]);
    g[d][1] = grid.cell_axis(d, w.lo[d] + w.m[d] - 1);
    if (g[d][0] < 0 || g[d][1] < 0) return false;  // part of the window lies beyond the mesh
    if (w.m[d] == 2) {
      // base_d + (r / h_d) R_d . q >= 1  <=>  R_d . q >= (1 - base_d) / (r / h_d)
      const double scale = p.radius / grid.spacing()[d];
      if (!(scale > 1e-6)) return false;  // the guard band would be below double's resolution
      split |= 1u << d;
      tau[d] = static_cast<float>((1.0 - base[d]) / scale);
    }
  }
  std::int32_t counts[8];
  if (!kernels::octant_counter(t).by_split[split](t, rotation_rows, tau, counts)) return false;
  ++s.counted;
  const double share = p.volume * t.fractions[0];
  for (int o = 0; o < 8; ++o)
    if (counts[o]) sink(grid.index(g[0][o & 1], g[1][(o >> 1) & 1], g[2][(o >> 2) & 1]), share * double(counts[o]));
  return true;
}

/// pmm's two quick cases for a sphere whose window of cells lies in the mesh, on a grid
/// without periodic axes: the whole template in one cell (the fast path) or in at most
/// 2 x 2 x 2 cells, counted per octant. What every particle reads (the grid's numbers, the
/// template when the bank has one, the counting code, the rotation bank) is gathered once,
/// so a pass over many particles builds one and calls it per particle.
class PmmQuick {
 public:
  /// chunks: for a pass by chunks (window_grid(), finish_chunk); a quick case for one
  /// particle needs neither, and skips the bank's templates' set-up.
  explicit PmmQuick(const Context& ctx, bool chunks = false)
      : ctx_(ctx),
        single_(ctx.bank.templates.size() == 1 ? ctx.bank.templates.front() : nullptr),
        counter_(single_ ? &kernels::octant_counter(*single_) : nullptr),
        bank_rows_(ctx.opts.orientation == Orientation::random && ctx.opts.rotation_bank
                       ? kernels::banked_rotation_rows_table()
                       : nullptr),
        seed_(ctx.opts.seed),
        usable_(ctx.opts.fast_path && !ctx.grid.periodic_mask()),
        from_origin_(!ctx.grid.is_block()) {
    const CartesianGrid& grid = ctx.grid;
    double h_max = 0;
    for (int d = 0; d < 3; ++d) {
      grid_.origin[d] = grid.origin()[d];
      grid_.inv_h[d] = 1.0 / grid.spacing()[d];
      grid_.h[d] = grid.spacing()[d];
      h_max = std::max(h_max, grid_.h[d]);
      first_[d] = grid.first(d);
      lo_bound_[d] = double(first_[d]);
      grid_.hi_bound[d] = double(first_[d] + grid.cells()[d]);
    }
    // Counting needs r / h_d > 1e-6 on each split axis, or the guard band would be below
    // double's resolution; asked of every axis, it is r > 1e-6 h_max.
    grid_.min_radius = 1e-6 * h_max;
    nx_ = grid.cells()[0], nxy_ = nx_ * grid.cells()[1];
    for (unsigned o = 0; o < 8; ++o) corner_offset_[o] = (o & 1) + nx_ * ((o >> 1) & 1) + nxy_ * ((o >> 2) & 1);
    // Several templates: each sphere's by the bank's diameter thresholds (spheres of one
    // cell volume), each countable.
    const TemplateBank& bank = ctx.bank;
    auto countable = [](const kernels::ParticleTemplate* t) { return !t->split_points.empty(); };
    several_ = chunks && !single_ && bank.templates.size() <= kMostChunkTemplates && !bank.thresholds.empty() &&
               bank.threshold_cell_volume == grid.cell_volume() &&
               std::all_of(bank.templates.begin(), bank.templates.end(), countable);
    window_grid_ = chunks && usable_ && from_origin_ && (single_ || several_) && bank_rows_ &&
                   grid.cell_count() < (std::int64_t(1) << 31) && first_[0] == 0 && first_[1] == 0 && first_[2] == 0;
    if (window_grid_) {
      chunk_templates_ = bank.templates.size();
      grid_.reach = 0;
      grid_.countable = true;
      for (std::size_t k = 0; k < chunk_templates_; ++k) {
        templates_[k] = bank.templates[k];
        counters_[k] = &kernels::octant_counter(*templates_[k]);
        // The planning's windows hold every template of the bank: a sphere whose own
        // template lies in one cell may be counted, its points all in one octant.
        grid_.reach = std::max(grid_.reach, templates_[k]->reach);
        grid_.countable &= countable(templates_[k]);
      }
    }
    // A counted sphere's query: its bank slot's projections where the bank has them for the
    // template, else its slot's float rows.
    projected_ = window_grid_ && single_ && ctx.bank.projections && counter_->projected_batch_by_split[1];
    if (projected_) {
      query_base_ = ctx.bank.projections->of_slot(0);
      query_stride_ = static_cast<std::int64_t>(ctx.bank.projections->of_slot(1) - query_base_);
    } else {
      query_base_ = bank_rows_;
      query_stride_ = 9;
    }
    grid_.seed = seed_;
    grid_.nx = static_cast<std::int32_t>(window_grid_ ? nx_ : 0);
    grid_.nxy = static_cast<std::int32_t>(window_grid_ ? nxy_ : 0);
  }

  const Context& context() const { return ctx_; }
  /// The template operator() takes for p.
  const kernels::ParticleTemplate& template_of(const Particle& p, Scratch& s) const {
    return single_ && !p.shape_template ? *single_ : ctx_.template_for(p, s);
  }

  /// What a counted particle gives the sink for an octant it reaches without a sub-element:
  /// nothing, or a zero volume (for a sink adding into a field, where it changes nothing and
  /// saves a branch that often mispredicts).
  enum class EmptyOctants { skip, add_zero };

  /// Adds particle p through sink(cell, volume) and counts as deposit_points does; false,
  /// with nothing added or counted, when neither quick case applies (pmm_particle then
  /// does the general work).
  template <class Sink>
  [[gnu::always_inline]] bool operator()(Scratch& s, const Particle& p, Sink&& sink,
                                         EmptyOctants empty = EmptyOctants::skip) const {
    if (!usable_) return false;
    const kernels::ParticleTemplate& t = template_of(p, s);
    // make_window's cells, for a window inside the grid: there no clamp acts, and on a grid
    // from the origin (not a block) the floor of each bound's coordinate (axis_index's) is
    // its truncation.
    const double r = p.radius, half = r * t.reach;
    std::int64_t lo[3];
    std::int64_t extra = 0;  // or of the window's cells beyond the first per axis
    unsigned two = 0;        // bit d: two cells along d (when extra <= 1)
    for (int d = 0; d < 3; ++d) {
      const double a = (p.centre[d] - half - grid_.origin[d]) * grid_.inv_h[d],
                   b = (p.centre[d] + half - grid_.origin[d]) * grid_.inv_h[d];
      if (!(a >= lo_bound_[d] && b < grid_.hi_bound[d])) return false;  // reaches beyond the grid (or NaN)
      std::int64_t i, j;
      if (from_origin_) {
        i = static_cast<std::int64_t>(a), j = static_cast<std::int64_t>(b);
      } else {
        i = CartesianGrid::fast_floor(a) - first_[d], j = CartesianGrid::fast_floor(b) - first_[d];
      }
      lo[d] = i;
      extra |= j - i;
      two |= unsigned(j - i) << d;
    }
    const std::int64_t cell = lo[0] + nx_ * lo[1] + nxy_ * lo[2];
    const auto size = static_cast<std::int64_t>(t.size());
    if (extra == 0) {
      s.count_grid(size);
      ++s.fast_path;
      sink(cell, p.volume);
      return true;
    }
    if (extra > 1 || t.split_points.empty() || !(r > grid_.min_radius)) return false;
    // base_d + (r / h_d) R_d . q >= 1  <=>  R_d . q >= (1 - base_d) h_d / r, base_d the
    // centre in cell units from the window's corner (deposit_points' base).
    float tau[3];
    const double inv_r = 1.0 / r;
    for (int d = 0; d < 3; ++d) {
      const double base = (p.centre[d] - grid_.origin[d]) * grid_.inv_h[d] - double(lo[d] + first_[d]);
      tau[d] = static_cast<float>((1.0 - base) * grid_.h[d] * inv_r);
    }
    float buffer[9];
    const float* rows = bank_rows_ ? bank_rows_ + 9 * kernels::rotation_bank_slot(p.rotation_key, seed_)
                                   : particle_rotation_rows(ctx_.opts, p, buffer);
    const kernels::OctantCounter& counter = single_ && !p.shape_template ? *counter_ : kernels::octant_counter(t);
    std::int32_t counts[8];
    if (!counter.by_split[two](t, rows, tau, counts)) return false;
    ++s.counted;
    s.count_grid(size);
    s.sub_elements += size;
    add_octants(counts, two, cell, p.volume * t.fractions[0], sink, empty);
    return true;
  }

  /// The templates finish_chunk counts with (window_grid()): the bank's.
  std::span<const kernels::ParticleTemplate* const> chunk_templates() const {
    return {templates_, chunk_templates_};
  }
  /// Whether finish_chunk counts from the template's projections on the rotation bank.
  bool counts_from_projections() const { return projected_; }

  /// plan_sphere_windows' grid for this context (built for chunks), or null where the quick
  /// cases need more than it decides (a block, periodic axes, several templates without the bank's diameter
  /// thresholds or more than kMostChunkTemplates of them, rotations not from the bank, 2^31
  /// cells or more along an axis).
  const QuickGrid* window_grid() const { return window_grid_ ? &grid_ : nullptr; }

  /// What finish_chunk took, tallied over a chunk and added to the Scratch's counters once
  /// (commit): counters in memory cost a load and a store per particle around every call.
  struct Tally {
    std::int64_t fast = 0, counted = 0, sub_elements = 0;
    std::uint64_t templates = 0;  ///< bit k: template k of the bank served a sphere
  };
  void commit(Scratch& s, const Tally& t) const {
    for (std::size_t k = 0; k < chunk_templates_; ++k)
      if ((t.templates >> k) & 1u) s.count_grid(static_cast<std::int64_t>(templates_[k]->size()));
    s.fast_path += t.fast;
    s.counted += t.counted;
    s.sub_elements += t.sub_elements;
  }

  /// The most templates a bank may have for finish_chunk (a bit each in Tally::templates).
  static constexpr std::size_t kMostChunkTemplates = 64;

  /// The most spheres finish_chunk takes.
  static constexpr std::int64_t kChunk = kQuickSpheres;

  /// operator() for spheres [0, n) of a chunk (n <= kChunk) planned by plan_sphere_windows
  /// on window_grid(), one path after another: in a shuffled stream the path (fast, the set
  /// of split axes of a count, general) changes at random from one sphere to the next, which
  /// the CPU mispredicts; sorted by path, each path is a loop of its own (one counting call
  /// and one unrolled code of adds per set of split axes). Only the order of the adds
  /// changes. sink adds into a field: sink(cell, volume), and sink.prefetch(cell) asks for
  /// the line of a later add; a counted sphere adds to every octant its split axes reach,
  /// zeros included (EmptyOctants::add_zero). With several templates, radius(k) gives sphere
  /// k's radius (its template's by the bank's thresholds), and each split set is counted one
  /// template after another. taken(k, fast) for each sphere added (fast: by the fast path),
  /// declined(k) for each of the others.
  template <class Sink, class Radius, class Taken, class Declined>
  void finish_chunk(Tally& tally, const QuickWindows& w, std::int64_t n, Sink&& sink, Radius&& radius,
                    Taken&& taken, Declined&& declined) const {
    static_assert(kChunk <= 256, "a sphere of the chunk is a byte of order");
    const auto add = sink;  // a copy in registers: an add's store could otherwise alias it
    std::uint8_t templ[kChunk];  // each sphere's template in the bank (several templates)
    if (several_)
      for (std::int64_t i = 0; i < n; ++i)
        templ[i] = static_cast<std::uint8_t>(ctx_.bank.threshold_index(2 * radius(i)));  // template_for's diameter
    // The spheres by path, without a branch; the line of each one's first cell asked for.
    std::uint8_t order[QuickWindows::general + 1][kChunk];
    std::int32_t size[QuickWindows::general + 1] = {};
    for (std::int64_t i = 0; i < n; ++i) {
      const std::int32_t path = w.path[i];
      add.prefetch(w.cell[i]);  // in the grid for every path
      order[path][size[path]++] = static_cast<std::uint8_t>(i);
    }
    std::uint64_t used = 0;
    for (std::int32_t j = 0; j < size[QuickWindows::fast]; ++j) {
      const std::int64_t i = order[QuickWindows::fast][j];
      add(w.cell[i], w.volume[i]);
      if (several_) used |= std::uint64_t(1) << templ[i];
      taken(i, true);
    }
    if (size[QuickWindows::fast] > 0 && !several_) used |= 1;
    tally.templates |= used;
    tally.fast += size[QuickWindows::fast];
    // One set of buffers for every set of split axes (seven would not stay in L1).
    SetBuffers buffers;
    auto finish = [&]<unsigned kSplit>(std::integral_constant<unsigned, kSplit>) {
      const std::uint8_t* set = order[kSplit];
      const std::int32_t m = size[kSplit];
      if (m == 0) return;
      if (!several_)
        finish_set<kSplit>(tally, w, 0, set, m, buffers, add, taken, declined);
      else
        finish_set_by_template<kSplit>(tally, w, templ, set, m, buffers, add, taken, declined);
    };
    [&]<unsigned... kSet>(std::integer_sequence<unsigned, kSet...>) {
      (finish(std::integral_constant<unsigned, kSet + 1>{}), ...);
    }(std::make_integer_sequence<unsigned, 7>{});
    for (std::int32_t j = 0; j < size[QuickWindows::general]; ++j) declined(order[QuickWindows::general][j]);
  }

 private:
  /// A set's queries and results in finish_chunk.
  struct SetBuffers {
    kernels::OctantQuery query[kChunk];
    std::int32_t counts[8 * kChunk];
    std::uint8_t decided[kChunk];
  };

  /// finish_set for spheres order[0, m) of several templates (templ[i]: sphere i's): sorted
  /// by template (a counting sort), then one template after another. Out of line: the one
  /// template's code stays as it was.
  template <unsigned kSplit, class Sink, class Taken, class Declined>
  [[gnu::noinline]] void finish_set_by_template(Tally& tally, const QuickWindows& w, const std::uint8_t* templ,
                                                const std::uint8_t* order, std::int32_t m, SetBuffers& b,
                                                const Sink& add, Taken& taken, Declined& declined) const {
    std::int32_t first[kMostChunkTemplates + 1] = {};
    for (std::int32_t j = 0; j < m; ++j) ++first[templ[order[j]] + 1];
    for (std::size_t k = 0; k < chunk_templates_; ++k) first[k + 1] += first[k];
    std::int32_t next[kMostChunkTemplates];
    std::copy(first, first + chunk_templates_, next);
    std::uint8_t by_template[kChunk];
    for (std::int32_t j = 0; j < m; ++j) by_template[next[templ[order[j]]]++] = order[j];
    for (std::size_t k = 0; k < chunk_templates_; ++k)
      if (first[k + 1] > first[k])
        finish_set<kSplit>(tally, w, k, by_template + first[k], first[k + 1] - first[k], b, add, taken, declined);
  }

  /// finish_chunk's counted spheres of split set kSplit and template `templ` of the bank:
  /// spheres order[0, m) of w.
  template <unsigned kSplit, class Sink, class Taken, class Declined>
  [[gnu::always_inline]] void finish_set(Tally& tally, const QuickWindows& w, std::size_t templ,
                                         const std::uint8_t* order, std::int32_t m, SetBuffers& b, const Sink& add,
                                         Taken&& taken, Declined&& declined) const {
    const kernels::ParticleTemplate& t = *templates_[templ];
    const kernels::OctantCounter& counter = *counters_[templ];
    for (std::int32_t j = 0; j < m; ++j) {
      const std::int64_t i = order[j];
      b.query[j] = {query_base_ + query_stride_ * w.slot[i], {w.tau[0][i], w.tau[1][i], w.tau[2][i]}};
      // The lines of the octants across y and z, while the count runs (finish_chunk asked
      // for the first cell's).
#pragma GCC unroll 4
      for (unsigned o = 2; o < 8; o += 2)
        if ((o & ~kSplit) == 0) add.prefetch(w.cell[i] + corner_offset_[o]);
    }
    const std::int32_t* const counts = b.counts;
    const std::uint8_t* const decided = b.decided;
    (projected_ ? counter.projected_batch_by_split : counter.batch_by_split)[kSplit](
        t, b.query, static_cast<std::size_t>(m), b.counts, b.decided);
    const double fraction = t.fractions[0];
    std::int64_t counted = 0;
    // The octants' offsets in registers: an add's store could otherwise alias them.
    std::int64_t offset[8];
    std::copy(corner_offset_, corner_offset_ + 8, offset);
    for (std::int32_t j = 0; j < m; ++j) {
      const std::int64_t i = order[j];
      if (!decided[j]) {
        declined(i);
        continue;
      }
      ++counted;
      const std::int32_t* c = counts + 8 * j;
      const std::int64_t cell = w.cell[i];
      const double share = w.volume[i] * fraction;
#pragma GCC unroll 8
      for (unsigned o = 0; o < 8; ++o)
        if ((o & ~kSplit) == 0) add(cell + offset[o], share * double(c[o]));
      taken(i, false);
    }
    tally.counted += counted;
    tally.sub_elements += counted * static_cast<std::int64_t>(t.size());
    if (counted) tally.templates |= std::uint64_t(1) << templ;
  }

  /// A count's adds: share per sub-element into each octant the split axes reach.
  template <class Sink>
  [[gnu::always_inline]] void add_octants(const std::int32_t counts[8], unsigned two, std::int64_t cell,
                                          double share, Sink&& sink, EmptyOctants empty) const {
    for (unsigned o = two;; o = (o - 1) & two) {
      if (counts[o] || empty == EmptyOctants::add_zero) sink(cell + corner_offset_[o], share * double(counts[o]));
      if (o == 0) break;
    }
  }

  const Context& ctx_;
  const kernels::ParticleTemplate* single_;  ///< the bank's one template, or null
  const kernels::OctantCounter* counter_;  ///< single_'s counting code
  const float* bank_rows_;  ///< orientation=random from the bank: its float rows; else null
  /// finish_chunk counts from single_'s projections on the bank; its query of bank slot k
  /// is query_base_ + query_stride_ k (the projections' rows, else the float rotation rows).
  bool projected_ = false;
  const float* query_base_ = nullptr;
  std::int64_t query_stride_ = 0;
  std::uint64_t seed_;
  bool usable_, from_origin_;
  /// The grid's numbers both quick paths read (nx and nxy set only for window_grid()).
  QuickGrid grid_{};
  double lo_bound_[3];
  std::int64_t first_[3], nx_, nxy_, corner_offset_[8];
  bool window_grid_ = false;
  /// window_grid(): the bank's templates and their counting codes, entries [0,
  /// chunk_templates_) only (a PmmQuick for one particle sets none: no half a kilobyte to
  /// clear per particle); several_: more than one, each sphere's found by
  /// TemplateBank::threshold_index.
  std::size_t chunk_templates_ = 0;
  const kernels::ParticleTemplate* templates_[kMostChunkTemplates];
  const kernels::OctantCounter* counters_[kMostChunkTemplates];
  bool several_ = false;
};

/// PmmQuick for one particle (callers that meet a particle at a time).
template <class Sink>
bool pmm_sphere_quick(const Context& ctx, Scratch& s, const Particle& p, Sink&& sink) {
  return PmmQuick(ctx)(s, p, sink);
}

// One function per method: the particle's deposits into s (s.deposits is empty on entry).
void direct_particle(const Context& ctx, Scratch& s, const Particle& p);
void pmm_particle(const Context& ctx, Scratch& s, const Particle& p);
void exact_particle(const Context& ctx, Scratch& s, const Particle& p);
void divided_particle(const Context& ctx, Scratch& s, const Particle& p);
void gaussian_particle(const Context& ctx, Scratch& s, const Particle& p);
void porous_cube_particle(const Context& ctx, Scratch& s, const Particle& p);
void big_particle_particle(const Context& ctx, Scratch& s, const Particle& p);
void trilinear_particle(const Context& ctx, Scratch& s, const Particle& p);

}  // namespace vfe::detail
