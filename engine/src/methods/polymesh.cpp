// direct and pmm on an OpenFOAM polyMesh: the particle's centre by the cell locator's
// spatial hash, its sub-elements by SubElements below (a lattice where box cells tile the
// particle's box, else walks between the cells found so far), each in the cell the locator
// gives; the fast path and outside policy that exact shares.
#include "methods/polymesh.hpp"

#include <vfe/kernels/v3_clones.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace vfe::detail {

bool ball_inside_cell(const PolyMesh& mesh, std::int64_t cell, const Eigen::Vector3d& c, double r) {
  if (!mesh.cell_is_convex(cell)) return false;
  for (const std::int64_t f : mesh.cell_faces(cell)) {
    const double sign = mesh.owner(f) == cell ? 1.0 : -1.0;
    const double depth = sign * (mesh.face_centre(f) - c).dot(mesh.face_normal(f));
    if (!(depth > r + mesh.face_warp(f) + mesh.location_tolerance())) return false;
  }
  return true;
}

void outside_poly(const PolyContext& ctx, Scratch& s, const Particle& p, double volume, const Eigen::Vector3d& at,
                  std::int64_t centre_cell, bool& flagged, Outside policy) {
  apply_outside(s, p, volume, policy, ctx.locator->mesh().cell_count(), flagged,
                [&] { return ctx.locator->nearest_cell(at); },
                [&] { return centre_cell >= 0 ? centre_cell : ctx.locator->nearest_cell(p.centre); });
}

namespace {

constexpr int kMaxWalkSteps = 64;
// The lattice is tried with at most this many candidate cells and used with at most this
// many lattice cells.
constexpr std::size_t kMaxLatticeCandidates = 64, kMaxLatticeCells = 4096;

/// The points at the lowest and the highest corner of cell c when the cell is a box, or
/// (-1, -1): the cell is convex, every face lies in one of the six planes of the box of
/// the cell's points (all its points, hence its apex, share that coordinate) and each plane
/// is taken. The cell is then the intersection of those faces' inner half-spaces, the box:
/// a point strictly inside the box is in the cell, one outside the closed box is not.
std::array<std::int32_t, 2> box_corners(const PolyMesh& mesh, std::int64_t c) {
  constexpr std::array<std::int32_t, 2> kNone{-1, -1};
  if (!mesh.cell_is_convex(c) || mesh.point_count() > std::numeric_limits<std::int32_t>::max()) return kNone;
  const auto& points = mesh.points();
  const auto point = [&](std::int64_t q) -> const Eigen::Vector3d& { return points[static_cast<std::size_t>(q)]; };
  Eigen::AlignedBox3d box(point(mesh.face(mesh.cell_faces(c)[0])[0]));
  for (const std::int64_t f : mesh.cell_faces(c))
    for (const std::int64_t q : mesh.face(f)) box.extend(point(q));
  unsigned sides = 0;
  std::array<std::int32_t, 2> corners = kNone;
  for (const std::int64_t f : mesh.cell_faces(c)) {
    const auto face = mesh.face(f);
    const Eigen::Vector3d& first = point(face[0]);
    int side = -1;
    for (int d = 0; d < 3 && side < 0; ++d) {
      const bool lower = first[d] == box.min()[d];
      if (!lower && first[d] != box.max()[d]) continue;
      bool shared = true;
      for (const std::int64_t q : face) shared = shared && point(q)[d] == first[d];
      if (shared) side = 2 * d + (lower ? 0 : 1);
    }
    if (side < 0) return kNone;
    sides |= 1u << side;
    for (const std::int64_t q : face) {
      if (point(q) == box.min()) corners[0] = static_cast<std::int32_t>(q);
      if (point(q) == box.max()) corners[1] = static_cast<std::int32_t>(q);
    }
  }
  return sides == 63u && corners[0] >= 0 && corners[1] >= 0 ? corners : kNone;
}

/// Locates the sub-elements of one particle on a polyMesh, each in the cell
/// CellLocator::locate_from gives (cell_contains, or what is equivalent to it, decides
/// every answer, and by the tie rule at most one cell holds a point), and gives
/// outside=nearest the cell KdTreeLocator::nearest_cell gives. Working memory is the
/// Scratch's; finish() emits the deposits and resets it.
///
/// Where the cells whose bounds reach the particle's box are all boxes (box_corners),
/// they tile it as a lattice: a point strictly inside a lattice cell is in the cell that
/// covers it, or outside the mesh when none does; a point on a lattice plane takes the
/// general way. The general way walks from a cell that held an earlier sub-element of
/// the same bin of the particle's box, across the face whose plane the point lies
/// furthest beyond, to the cell holding it; when the walk meets the boundary, the cells
/// whose bounds reach the bin decide.
class SubElements {
 public:
  static constexpr std::int64_t kNoBin = -2;  ///< a point's bin, not computed yet

  /// half: half the side of the particle's box, which holds every sub-element (the ball
  /// of radius half about the centre does); points: the template size (chooses the bins).
  SubElements(const PolyContext& ctx, Scratch& s, const Particle& p, double half, std::int64_t points,
              std::int64_t centre_cell)
      : ctx_(ctx), mesh_(ctx.locator->mesh()), s_(s), p_(p), half_(half), centre_cell_(centre_cell),
        box_(p.centre - Eigen::Vector3d::Constant(half), p.centre + Eigen::Vector3d::Constant(half)) {
    const auto cells = static_cast<std::size_t>(mesh_.cell_count());
    if (s.poly_local.size() != cells) s.poly_local.assign(cells, -1);
    if (s.poly_box_corners.size() != 2 * cells) s.poly_box_corners.assign(2 * cells, -2);
    // About 8 sub-elements a bin (at most 12^3 bins); one bin for small templates.
    m_ = points < 64 ? 1 : static_cast<int>(std::clamp(std::cbrt(double(points) / 8.0), 1.0, 12.0));
    h_ = 2 * half / m_;
    inv_h_ = m_ / (2 * half);
    margin_ = 1e-9 * h_ + mesh_.location_tolerance();
    lattice_ = build_lattice();
    last_ = centre_cell >= 0 ? enter(centre_cell) : -1;
  }

  /// Index in s.poly_cells of the cell holding x, or -1 outside the mesh. b: x's bin,
  /// computed here when needed and kNoBin (for nearest()).
  std::int32_t locate(const Eigen::Vector3d& x, std::int64_t& b) {
    if (lattice_) {
      std::size_t at = 0, stride = 1;
      bool plain = true;
      for (int d = 0; d < 3; ++d) {
        const double v = x[d];
        plain = plain && box_.min()[d] < v && v < box_.max()[d];
        std::size_t k = 0;
        for (const double node : s_.poly_nodes[d]) {
          plain = plain && v != node;
          k += v > node;
        }
        at += k * stride;
        stride *= s_.poly_nodes[d].size() + 1;
      }
      if (plain) return s_.poly_lattice[at];
    }
    return locate_general(x, b);
  }

  /// locate() without the lattice.
  std::int32_t locate_general(const Eigen::Vector3d& x, std::int64_t& b) {
    b = bin(x);
    if (b < 0) return fallback(x);
    if (!bins_) make_bins();
    Scratch::PolyBin* bin = &s_.poly_bins[static_cast<std::size_t>(b)];
    if (bin->whole >= 0) return bin->whole;
    if (bin->cells_count == 0) return -1;  // no cell reaches the bin
    const std::int32_t start = bin->hint >= 0 ? bin->hint : last_;
    std::int32_t at = start >= 0 ? walk(start, x) : -1;
    if (at < 0) {
      // The walk met the boundary (x outside, or beyond a concave part of it): the cells
      // whose bounds reach the bin are the only ones that can hold x.
      if (bin->cells_count < 0) {
        gather_bin_cells(static_cast<std::size_t>(b));
        bin = &s_.poly_bins[static_cast<std::size_t>(b)];
      }
      for (std::int32_t k = 0; k < bin->cells_count && at < 0; ++k) {
        const std::int64_t c = s_.poly_bin_cells[static_cast<std::size_t>(bin->cells_first + k)];
        if (cell_contains(mesh_, c, x)) at = enter(c);
      }
      if (at < 0) return -1;
    }
    bin = &s_.poly_bins[static_cast<std::size_t>(b)];
    bin->hint = at;
    if (bin->whole == -1) bin->whole = holds_bin(at, static_cast<std::size_t>(b)) ? at : -2;
    last_ = at;
    return at;
  }

  /// Index in s.poly_near of the cell whose centre is nearest to x (in bin b, or kNoBin),
  /// or -1 when another centre is as near to within 1e-9 (then
  /// KdTreeLocator::nearest_cell decides).
  std::int64_t nearest(const Eigen::Vector3d& x, std::int64_t b) {
    if (!near_) gather_near();
    if (b == kNoBin) b = bin(x);
    if (!bins_) make_bins();
    if (b < 0) return nearest_scan(x);
    if (s_.poly_bins[static_cast<std::size_t>(b)].near_count < 0) gather_bin_near(static_cast<std::size_t>(b));
    const Scratch::PolyBin& bin = s_.poly_bins[static_cast<std::size_t>(b)];
    const std::int32_t* items = s_.poly_bin_near.data() + bin.near_first;
    if (bin.near_count == 1) return items[0];  // a near tie would be listed too
    double best2 = std::numeric_limits<double>::infinity(), second2 = best2;
    std::int64_t best = -1;
    for (std::int32_t k = 0; k < bin.near_count; ++k) {
      const double d2 = distance2(x, s_.poly_near[static_cast<std::size_t>(items[k])].centre);
      if (d2 < best2) {
        second2 = best2;
        best2 = d2;
        best = items[k];
      } else if (d2 < second2) {
        second2 = d2;
      }
    }
    return best >= 0 && !(second2 <= best2 * (1 + 1e-9)) ? best : -1;
  }

  /// How deep visited cell i holds the ball of radius r about x (as far as the points of the
  /// particle's ball go). `inside`: whether the ball, grown by the margin that covers the
  /// rounding of the points' coordinates, lies in the cell's bounds. Returns the number of
  /// faces whose deep limit the grown ball reaches, copied into `crossed` (locating a point
  /// can grow the face cache), or -1 when more than kMostCrossed do or the cell takes no deep
  /// points. A point in the bounds and deeper than those faces' deep limits is deep in cell
  /// i: the walk accepts it there, so the locator gives cell i. With no such face and the
  /// ball inside, every point of the ball is one. The cached faces are enough: every point of
  /// the particle's ball lies deeper than the deep limit of a face left out (faces()).
  static constexpr int kMostCrossed = 3;
  int ball_depth(std::int32_t i, const Eigen::Vector3d& x, double r, Scratch::PolyFace crossed[kMostCrossed],
                 bool& inside) {
    if (!s_.poly_cells[static_cast<std::size_t>(i)].deep) return -1;
    const Scratch::PolyFace* list = faces(i);
    const Scratch::PolyCell& c = s_.poly_cells[static_cast<std::size_t>(i)];
    const double grown = r * (1 + 1e-9) + margin_;
    inside = (x.array() - grown >= c.lo.array()).all() && (x.array() + grown <= c.hi.array()).all();
    const double tol = mesh_.location_tolerance();
    int count = 0;
    for (std::int64_t k = 0; k < c.face_count; ++k) {
      const Scratch::PolyFace& f = list[k];
      if (!(f.normal.dot(x - f.centre) + grown < f.deep_limit - tol)) {
        if (count == kMostCrossed) return -1;
        crossed[count++] = f;
      }
    }
    return count;
  }

  /// Whether the particle's box takes the lattice (a point's cell by comparisons).
  bool lattice() const { return lattice_; }

  Scratch::PolyCell& cell(std::int32_t i) { return s_.poly_cells[static_cast<std::size_t>(i)]; }
  Scratch::PolyNear& near_entry(std::int64_t i) { return s_.poly_near[static_cast<std::size_t>(i)]; }

  /// The deposits: the cells that received sub-elements (distinct), merged with what the
  /// outside policy gave, if anything; then resets the scratch for the next particle.
  void finish() {
    const bool merge = !s_.deposits.empty();
    for (const Scratch::PolyCell& c : s_.poly_cells) {
      s_.poly_local[static_cast<std::size_t>(c.cell)] = -1;
      if (c.hits == 0) continue;
      if (merge)
        s_.add(c.cell, c.volume);
      else
        s_.deposits.push_back({c.cell, c.volume});
    }
    if (near_)
      for (const Scratch::PolyNear& e : s_.poly_near)
        if (e.hits > 0) s_.add(e.cell, e.volume);
    s_.poly_cells.clear();
    s_.poly_faces.clear();
  }

 private:
  static double distance2(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    // As the KD-tree sums them.
    const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
  }

  /// The bin of x, or -1 outside the particle's box (not expected: rounding beyond the
  /// margin), which the plain locator then takes.
  std::int64_t bin(const Eigen::Vector3d& x) const {
    if (!box_.contains(x)) return -1;
    if (m_ == 1) return 0;
    std::int64_t i[3];
    for (int d = 0; d < 3; ++d)
      i[d] = std::min<std::int64_t>(static_cast<std::int64_t>((x[d] - box_.min()[d]) * inv_h_), m_ - 1);
    return i[0] + m_ * (i[1] + m_ * i[2]);
  }

  /// The bins, none known yet (the lattice needs none).
  void make_bins() {
    bins_ = true;
    s_.poly_bins.assign(static_cast<std::size_t>(m_ * m_ * m_), Scratch::PolyBin{-1, -1, 0, -1, 0, -1});
    const std::size_t mc = static_cast<std::size_t>((m_ + 1) / 2);
    s_.poly_coarse_bins.assign(m_ >= 4 ? mc * mc * mc : 0, Scratch::PolyBin{-1, -1, 0, -1, 0, -1});
    s_.poly_bin_cells.clear();
    s_.poly_bin_near.clear();
  }

  /// Bin b's box, grown by the margin (covers the rounding of bin()).
  Eigen::AlignedBox3d bin_box(std::size_t b) const {
    const Eigen::Vector3d i(double(b % m_), double(b / m_ % m_), double(b / m_ / m_));
    const Eigen::Vector3d lo = box_.min() + h_ * i;
    return {lo - Eigen::Vector3d::Constant(margin_), lo + Eigen::Vector3d::Constant(h_ + margin_)};
  }

  /// The cells whose bounds overlap the particle's box (once), into s.candidate_cells:
  /// every cell that can hold a sub-element.
  void gather() {
    if (gathered_) return;
    ctx_.locator->hash().sorted_cells_in_box(box_, s_.candidate_cells);
    gathered_ = true;
  }

  /// Index of mesh cell c in s.poly_cells (entered on its first visit).
  std::int32_t enter(std::int64_t c) {
    std::int32_t& slot = s_.poly_local[static_cast<std::size_t>(c)];
    if (slot >= 0) return slot;
    slot = static_cast<std::int32_t>(s_.poly_cells.size());
    const Eigen::AlignedBox3d& box = mesh_.cell_bounds(c);
    s_.poly_cells.push_back({c, box.min(), box.max(), mesh_.cell_accepts_deep_points(c), -1, 0, 0, 0.0});
    return slot;
  }

  /// Visited cell i's face planes that the particle's ball reaches, cached on first use. A
  /// face whose plane every point of the ball lies deeper below than its deep limit can
  /// neither put a sub-element outside the cell nor keep it from being deep, nor be the
  /// face a walk crosses towards a point outside: leaving it out changes no answer (on the
  /// cylinder mesh a visited cell keeps 1.7 of its 6 faces on average).
  const Scratch::PolyFace* faces(std::int32_t i) {
    Scratch::PolyCell& cell = s_.poly_cells[static_cast<std::size_t>(i)];
    if (cell.first_face < 0) {
      const std::int64_t c = cell.cell;
      const auto list = mesh_.cell_faces(c);
      const auto base = mesh_.cell_face_offset(c);
      const double tol = mesh_.location_tolerance();
      cell.first_face = static_cast<std::int64_t>(s_.poly_faces.size());
      for (std::size_t k = 0; k < list.size(); ++k) {
        const auto f = list[k];
        const Eigen::Vector3d normal =
            mesh_.owner(f) == c ? Eigen::Vector3d(mesh_.face_normal(f)) : Eigen::Vector3d(-mesh_.face_normal(f));
        const Eigen::Vector3d& centre = mesh_.face_centre(f);
        const double deep_limit = -mesh_.face_warp(f) - tol;
        // The ball's highest point above the plane, with a bound on the rounding of the
        // walk's dot products (a few ulps of the lengths involved).
        const double offset = (p_.centre - centre).cwiseAbs().sum();  // >= the distance, no root
        if (normal.dot(p_.centre - centre) + half_ + 1e-12 * (offset + half_) < deep_limit) continue;
        s_.poly_faces.push_back(
            {normal, centre, mesh_.cell_face_reach(base + static_cast<std::int64_t>(k)) + tol, deep_limit,
             mesh_.across(f, c)});
      }
      cell.face_count = static_cast<std::int64_t>(s_.poly_faces.size()) - cell.first_face;
    }
    return s_.poly_faces.data() + cell.first_face;
  }

  /// Cell c's box when it is one (cached per thread), else false.
  bool cell_box(std::int64_t c, Eigen::AlignedBox3d& box) { return cached_cell_is_box(mesh_, s_, c, box); }

  /// The lattice of the particle's box when the candidate cells are all boxes (and not
  /// too many): per axis the cell bounds strictly inside the box, and for each lattice
  /// cell the candidate covering it (-1: none, outside the mesh). Candidates meet only on
  /// their faces, so each lattice cell has at most one.
  bool build_lattice() {
    Eigen::AlignedBox3d centre_box;  // the centre's cell is a candidate
    if (centre_cell_ >= 0 && !cell_box(centre_cell_, centre_box)) return false;
    gather();
    const auto& candidates = s_.candidate_cells;
    if (candidates.empty() || candidates.size() > kMaxLatticeCandidates) return false;
    auto& boxes = s_.poly_boxes;
    boxes.resize(candidates.size());
    for (std::size_t i = 0; i < candidates.size(); ++i)
      if (!cell_box(candidates[i], boxes[i])) return false;
    std::size_t dims[3], total = 1;
    for (int d = 0; d < 3; ++d) {
      auto& nodes = s_.poly_nodes[d];
      nodes.clear();
      const double lo = box_.min()[d], hi = box_.max()[d];
      for (const Eigen::AlignedBox3d& cell : boxes)
        for (const double v : {cell.min()[d], cell.max()[d]})
          if (lo < v && v < hi) nodes.push_back(v);
      std::sort(nodes.begin(), nodes.end());
      nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
      dims[d] = nodes.size() + 1;
      total *= dims[d];
    }
    if (total > kMaxLatticeCells) return false;
    s_.poly_lattice.assign(total, -1);
    for (std::size_t n = 0; n < candidates.size(); ++n) {
      // Lattice cells k along each axis with [lower_k, upper_k] within the cell's box.
      std::size_t first[3], last[3];
      bool covers = true;
      for (int d = 0; d < 3; ++d) {
        const auto& nodes = s_.poly_nodes[d];
        const double lo = boxes[n].min()[d], hi = boxes[n].max()[d];
        first[d] = dims[d];
        last[d] = 0;
        for (std::size_t k = 0; k < dims[d]; ++k) {
          const double lower = k == 0 ? box_.min()[d] : nodes[k - 1];
          const double upper = k + 1 == dims[d] ? box_.max()[d] : nodes[k];
          if (lo <= lower && upper <= hi) {
            first[d] = std::min(first[d], k);
            last[d] = k;
          }
        }
        covers = covers && first[d] <= last[d];
      }
      if (!covers) continue;  // touches the box on its boundary only
      const std::int32_t local = enter(candidates[n]);
      for (std::size_t k = first[2]; k <= last[2]; ++k)
        for (std::size_t j = first[1]; j <= last[1]; ++j)
          for (std::size_t i = first[0]; i <= last[0]; ++i) {
            std::int32_t& slot = s_.poly_lattice[i + dims[0] * (j + dims[1] * k)];
            if (slot >= 0) return false;  // overlapping cells: not a tiling
            slot = local;
          }
    }
    return true;
  }

  /// True when visited cell i holds all of bin b: the bin lies in the cell's bounds and
  /// deeper than every face's warp (with a margin), where cell_contains accepts every
  /// point (the deep region is convex: an intersection of half-spaces).
  bool holds_bin(std::int32_t i, std::size_t b) {
    if (!s_.poly_cells[static_cast<std::size_t>(i)].deep) return false;
    const Scratch::PolyFace* list = faces(i);
    const Scratch::PolyCell& c = s_.poly_cells[static_cast<std::size_t>(i)];
    const Eigen::AlignedBox3d bb = bin_box(b);
    if (!((bb.min().array() >= c.lo.array()).all() && (bb.max().array() <= c.hi.array()).all())) return false;
    const Eigen::Vector3d mid = bb.center(), hb = 0.5 * bb.sizes();
    const double tol = mesh_.location_tolerance();
    for (std::int64_t k = 0; k < c.face_count; ++k) {
      const Scratch::PolyFace& f = list[k];
      if (!(f.normal.dot(mid - f.centre) + f.normal.cwiseAbs().dot(hb) < f.deep_limit - tol)) return false;
    }
    return true;
  }

  /// Walks from visited cell `from` towards x across the face whose plane x lies furthest
  /// beyond (NeighbourWalk's rule, on the cached planes) until a cell holds x; -1 when the
  /// walk meets the boundary or its step limit. The planes settle most points as
  /// cell_contains's own first pass does (outside: beyond a face by more than the cell
  /// reaches; inside: deeper than every face's warp); cell_contains decides the rest.
  std::int32_t walk(std::int32_t from, const Eigen::Vector3d& x) {
    std::int32_t cur = from;
    for (int step = 0; step < kMaxWalkSteps; ++step) {
      const Scratch::PolyFace* list = faces(cur);
      const Scratch::PolyCell& c = s_.poly_cells[static_cast<std::size_t>(cur)];
      // Most points lie in the cell the walk tries first: the flags without branches, and
      // the face to cross only for a point that is not there.
      bool outside = false, deep = c.deep;
      for (std::int64_t k = 0; k < c.face_count; ++k) {
        const Scratch::PolyFace& f = list[k];
        const double out = f.normal.dot(x - f.centre);
        outside |= out > f.out_limit;
        deep &= out < f.deep_limit;
      }
      if (!outside) {
        const bool in_box = (x.array() >= c.lo.array()).all() && (x.array() <= c.hi.array()).all();
        if (in_box && (deep || cell_contains(mesh_, c.cell, x))) return cur;
      }
      double best = -std::numeric_limits<double>::infinity();
      std::int64_t next = -1;
      for (std::int64_t k = 0; k < c.face_count; ++k) {
        const Scratch::PolyFace& f = list[k];
        if (const double out = f.normal.dot(x - f.centre); out > best) {
          best = out;
          next = f.next;
        }
      }
      if (next < 0) return -1;
      cur = enter(next);
    }
    return -1;
  }

  /// Bin b's candidates: those whose bounds reach the bin.
  void gather_bin_cells(std::size_t b) {
    gather();
    const Eigen::AlignedBox3d bb = bin_box(b);
    Scratch::PolyBin& bin = s_.poly_bins[b];
    bin.cells_first = static_cast<std::int32_t>(s_.poly_bin_cells.size());
    for (const std::int64_t c : s_.candidate_cells)
      if (mesh_.cell_bounds(c).intersects(bb)) s_.poly_bin_cells.push_back(c);
    bin.cells_count = static_cast<std::int32_t>(s_.poly_bin_cells.size()) - bin.cells_first;
  }

  /// A point outside the particle's box (never, but for rounding): the locator.
  std::int32_t fallback(const Eigen::Vector3d& x) {
    const std::int64_t c = ctx_.locator->locate_from(x, centre_cell_);
    return c >= 0 ? enter(c) : -1;
  }

  /// The centres that can be nearest to a point of the particle's ball (radius half_),
  /// into s.poly_near by distance from its centre. No centre is nearer to such a point
  /// than the one nearest to the particle's centre, at d0: all lie within d0 + 2 half.
  void gather_near() {
    near_ = true;
    const Eigen::Vector3d& c = p_.centre;
    // The few centres nearest to c hold them all when the last is beyond that distance;
    // else the cells whose bounds reach the ball's box (a cell's centre lies in its bounds).
    constexpr std::size_t kFew = 16;
    std::uint32_t few[kFew];
    double few_d2[kFew];
    const std::size_t found = ctx_.locator->kdtree().nearest_cells(c, kFew, few, few_d2);
    const double rho = ((mesh_.cell_centre(few[0]) - c).norm() + 2 * half_) * (1 + 1e-8) + mesh_.location_tolerance();
    s_.poly_near_cells.clear();
    if (found == kFew && few_d2[kFew - 1] > rho * rho * (1 + 1e-6)) {
      s_.poly_near_cells.assign(few, few + kFew);
    } else {
      const Eigen::Vector3d r = Eigen::Vector3d::Constant(rho);
      ctx_.locator->hash().cells_in_box(Eigen::AlignedBox3d(c - r, c + r), s_.poly_near_cells);
    }
    s_.poly_near.clear();
    for (const std::int64_t cell : s_.poly_near_cells) {
      const Eigen::Vector3d& centre = mesh_.cell_centre(cell);
      const double d = (centre - c).norm();
      if (d <= rho) s_.poly_near.push_back({centre, d, cell, 0, 0.0});
    }
    std::sort(s_.poly_near.begin(), s_.poly_near.end(), [](const Scratch::PolyNear& a, const Scratch::PolyNear& b) {
      return a.distance < b.distance || (a.distance == b.distance && a.cell < b.cell);
    });
  }

  /// Bin b's nearest candidates, filtered from those of its coarse bin (2 x 2 x 2 bins)
  /// when there are many bins, else from all of s.poly_near.
  void gather_bin_near(std::size_t b) {
    std::int32_t first = 0, count = -1;
    if (m_ >= 4) {
      const std::size_t i = b % m_ / 2, j = b / m_ % m_ / 2, k = b / m_ / m_ / 2, mc = (m_ + 1) / 2;
      const std::size_t cb = i + mc * (j + mc * k);
      Scratch::PolyBin& coarse = s_.poly_coarse_bins[cb];
      if (coarse.near_count < 0) {
        const Eigen::Vector3d lo = box_.min() + 2 * h_ * Eigen::Vector3d(double(i), double(j), double(k));
        const Eigen::Vector3d margin = Eigen::Vector3d::Constant(margin_);
        const auto [f, n] = near_candidates(
            Eigen::AlignedBox3d(lo - margin, lo + margin + Eigen::Vector3d::Constant(2 * h_)), 0, -1);
        s_.poly_coarse_bins[cb].near_first = f;
        s_.poly_coarse_bins[cb].near_count = n;
      }
      first = s_.poly_coarse_bins[cb].near_first;
      count = s_.poly_coarse_bins[cb].near_count;
    }
    const auto [f, n] = near_candidates(bin_box(b), first, count);
    s_.poly_bins[b].near_first = f;
    s_.poly_bins[b].near_count = n;
  }

  /// The entries of s.poly_near that can be nearest to a point of box bb, among the list
  /// s.poly_bin_near[first, first + count) (all entries when count < 0), appended to
  /// s.poly_bin_near: its (first, count). With j the centre nearest to the box's middle
  /// m, a centre i can be nearest to a point x of the box only if x lies on i's side of
  /// their bisector, |x - c_i|^2 <= |x - c_j|^2, linear in x: its least value over the
  /// box, |a_i|^2 - |a_j|^2 - 2 sum_d h_d |c_j - c_i|_d with a = c - m and h the box's half
  /// sides, must not exceed 0 (up to a relative margin that also keeps near ties). Lists
  /// run by distance from the particle's centre: the scans stop where that distance rules
  /// the rest out (triangle inequality).
  std::pair<std::int32_t, std::int32_t> near_candidates(const Eigen::AlignedBox3d& bb, std::int32_t first,
                                                        std::int32_t count) {
    const Eigen::Vector3d mid = bb.center(), hb = 0.5 * bb.sizes();
    const double a = (mid - p_.centre).norm(), rb = hb.norm();
    const double tol = mesh_.location_tolerance();
    const auto& near = s_.poly_near;
    const std::size_t n = count < 0 ? near.size() : static_cast<std::size_t>(count);
    // (s.poly_bin_near grows below: index it afresh each time.)
    const auto item = [&](std::size_t k) {
      return count < 0 ? k : static_cast<std::size_t>(s_.poly_bin_near[static_cast<std::size_t>(first) + k]);
    };
    std::size_t j = item(0);
    double aj = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < n && near[item(k)].distance - a <= aj; ++k)
      if (const double ai = (near[item(k)].centre - mid).norm(); ai < aj) {
        aj = ai;
        j = item(k);
      }
    const auto out = static_cast<std::int32_t>(s_.poly_bin_near.size());
    const Eigen::Vector3d cj = near[j].centre;
    const double aj2 = (cj - mid).squaredNorm();
    // No centre beyond this distance from the middle is nearer to a point of the box than c_j.
    const double reach = (aj + 2 * rb) * (1 + 1e-6) + tol;
    for (std::size_t k = 0; k < n && near[item(k)].distance - a <= reach; ++k) {
      const std::size_t i = item(k);
      const Eigen::Vector3d& ci = near[i].centre;
      const double ai2 = (ci - mid).squaredNorm();
      const double least = ai2 - aj2 - 2 * hb.dot((cj - ci).cwiseAbs());
      // Rounding: relative to the squares, and the coordinates' (tol) times the lengths.
      if (i == j || least <= 1e-8 * (ai2 + aj2 + rb * rb) + 4 * tol * (near[i].distance + a + aj + rb))
        s_.poly_bin_near.push_back(static_cast<std::int32_t>(i));
    }
    return {out, static_cast<std::int32_t>(s_.poly_bin_near.size()) - out};
  }

  /// nearest() for a point outside the particle's box (never, but for rounding).
  std::int64_t nearest_scan(const Eigen::Vector3d& x) const {
    double best2 = std::numeric_limits<double>::infinity(), second2 = best2;
    std::int64_t best = -1;
    for (std::size_t i = 0; i < s_.poly_near.size(); ++i) {
      const double d2 = distance2(x, s_.poly_near[i].centre);
      if (d2 < best2) {
        second2 = best2;
        best2 = d2;
        best = static_cast<std::int64_t>(i);
      } else if (d2 < second2) {
        second2 = d2;
      }
    }
    // Complete only for points in the ball the entries were gathered for.
    const bool in_ball = (x - p_.centre).norm() <= half_;
    return in_ball && best >= 0 && !(second2 <= best2 * (1 + 1e-9)) ? best : -1;
  }

  const PolyContext& ctx_;
  const PolyMesh& mesh_;
  Scratch& s_;
  const Particle& p_;
  double half_;
  std::int64_t centre_cell_;
  Eigen::AlignedBox3d box_;
  int m_ = 1;
  double h_ = 0, inv_h_ = 0, margin_ = 0;
  std::int32_t last_ = -1;
  bool gathered_ = false, near_ = false, lattice_ = false, bins_ = false;
};

}  // namespace

bool cell_is_box(const PolyMesh& mesh, std::int64_t c, Eigen::AlignedBox3d& box) {
  const std::array<std::int32_t, 2> corners = box_corners(mesh, c);
  if (corners[0] < 0) return false;
  box = Eigen::AlignedBox3d(mesh.points()[static_cast<std::size_t>(corners[0])],
                            mesh.points()[static_cast<std::size_t>(corners[1])]);
  return true;
}

bool cached_cell_is_box(const PolyMesh& mesh, Scratch& s, std::int64_t c, Eigen::AlignedBox3d& box) {
  const auto cells = static_cast<std::size_t>(mesh.cell_count());
  if (s.poly_box_corners.size() != 2 * cells) s.poly_box_corners.assign(2 * cells, -2);
  std::int32_t* corners = s.poly_box_corners.data() + 2 * c;
  if (corners[0] == -2) {
    const auto found = box_corners(mesh, c);
    corners[0] = found[0];
    corners[1] = found[1];
  }
  if (corners[0] < 0) return false;
  const auto& points = mesh.points();
  box = Eigen::AlignedBox3d(points[static_cast<std::size_t>(corners[0])], points[static_cast<std::size_t>(corners[1])]);
  return true;
}

namespace {

// polymesh_points, built for x86-64-v3 beside the baseline, with every callee inlined so
// that the walks and the face tests take the build (internal: see v3_clones.hpp).
VFE_V3_CLONES_FLAT
void points_pass(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                 const Eigen::Matrix3d& rotation, Outside policy, std::int64_t centre_cell) {
  const PolyMesh& mesh = ctx.locator->mesh();
  const std::int64_t n = static_cast<std::int64_t>(t.size());
  s.count_grid(n);
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, p.centre, p.radius * t.reach)) {
    ++s.fast_path;
    s.add(centre_cell, p.volume);
    return;
  }
  s.sub_elements += n;
  bool flagged = false;
  // Every sub-element lies within reach of the centre (with a margin for rounding).
  const double half = p.radius * t.reach * (1 + 1e-9) + mesh.location_tolerance();
  SubElements cells(ctx, s, p, half, n, centre_cell);
  std::int64_t centre_or_nearest = centre_cell;  // outside=centre's cell
  const Eigen::Matrix3d transform = rotation * p.radius;
  // The sub-element at x (world coordinates) of this share of the volume, into its cell.
  const auto locate_point = [&](const Eigen::Vector3d& x, double fraction) {
    const double v = p.volume * fraction;
    std::int64_t b = SubElements::kNoBin;
    if (const std::int32_t at = cells.locate(x, b); at >= 0) {
      Scratch::PolyCell& c = cells.cell(at);
      c.volume += v;
      ++c.hits;
    } else if (policy == Outside::nearest) {
      if (!flagged) {
        flagged = true;
        ++s.outside_particles;
      }
      if (const std::int64_t e = cells.nearest(x, b); e >= 0) {
        Scratch::PolyNear& entry = cells.near_entry(e);
        entry.volume += v;
        ++entry.hits;
      } else {
        s.add(ctx.locator->nearest_cell(x), v);
      }
    } else {
      if (centre_or_nearest < 0 && policy == Outside::centre) centre_or_nearest = ctx.locator->nearest_cell(p.centre);
      outside_poly(ctx, s, p, v, x, centre_or_nearest, flagged, policy);
    }
  };
  if (t.tree.empty() || cells.lattice()) {
    for (std::size_t q = 0; q < t.size(); ++q) locate_point(p.centre + transform * t.points[q], t.fractions[q]);
  } else {
    // Depth first: a ball of points that one cell holds goes there whole; a leaf that no
    // cell holds, point by point.
    const auto& nodes = t.tree.nodes;
    for (std::size_t i = 0; i < nodes.size();) {
      const kernels::PointTree::Node& node = nodes[i];
      if (node.count >= kMostPointsTested) {
        ++i;
        continue;
      }
      const Eigen::Vector3d x = p.centre + transform * node.centre;
      std::int64_t b = SubElements::kNoBin;
      Scratch::PolyFace crossed[SubElements::kMostCrossed];
      bool inside = false;
      const std::int32_t at = cells.locate(x, b);
      const int depth = at >= 0 ? cells.ball_depth(at, x, p.radius * node.radius, crossed, inside) : -1;
      if (depth == 0 && inside) {
        Scratch::PolyCell& c = cells.cell(at);
        c.volume += p.volume * node.fraction;
        c.hits += node.count;
        i = node.skip;
      } else if (node.leaf()) {
        // A point in the cell's bounds and deeper than the faces the ball reaches is deep in
        // the cell, as the walk would find it there; the others are located.
        // (The cell's bounds copied: locating a point can grow the visited cells.)
        Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = lo;  // unused when depth < 0
        if (depth >= 0) lo = cells.cell(at).lo, hi = cells.cell(at).hi;
        for (std::uint32_t q = node.first; q < node.first + node.count; ++q) {
          const Eigen::Vector3d y = p.centre + transform * t.tree.points[q];
          bool deep = depth >= 0 && (inside || ((y.array() >= lo.array()).all() && (y.array() <= hi.array()).all()));
          for (int k = 0; k < depth; ++k)
            deep = deep && crossed[k].normal.dot(y - crossed[k].centre) < crossed[k].deep_limit;
          if (deep) {
            Scratch::PolyCell& c = cells.cell(at);
            c.volume += p.volume * t.tree.fractions[q];
            ++c.hits;
          } else {
            locate_point(y, t.tree.fractions[q]);
          }
        }
        i = node.skip;
      } else {
        ++i;
      }
    }
  }
  cells.finish();
}

}  // namespace

void polymesh_points(const PolyContext& ctx, Scratch& s, const Particle& p, const kernels::ParticleTemplate& t,
                     const Eigen::Matrix3d& rotation, Outside policy, std::int64_t centre_cell) {
  points_pass(ctx, s, p, t, rotation, policy, centre_cell);
}

void polymesh_direct(const PolyContext& ctx, Scratch& s, const Particle& p) {
  const std::int64_t centre_cell = ctx.locator->locate(p.centre);
  ++s.sub_elements;
  bool flagged = false;
  std::int64_t cell = centre_cell;
  Eigen::Vector3d at = p.centre;
  if (p.shaped) {  // everything at the body's centroid
    at = p.centre + p.radius * (particle_rotation(ctx.opts, p) * p.centroid);
    cell = ctx.locator->locate_from(at, centre_cell);
  }
  if (cell >= 0)
    s.add(cell, p.volume);
  else
    outside_poly(ctx, s, p, p.volume, at, centre_cell, flagged, p.outside);
}

void polymesh_pmm(const PolyContext& ctx, Scratch& s, const Particle& p) {
  polymesh_pmm_at(ctx, s, p, ctx.locator->locate(p.centre));
}

void polymesh_pmm_at(const PolyContext& ctx, Scratch& s, const Particle& p, std::int64_t centre_cell) {
  const kernels::ParticleTemplate* t = p.shape_template;
  if (!t) {  // auto sizes a sphere's template by the cell holding its centre
    const std::int64_t cell = centre_cell >= 0 ? centre_cell : ctx.locator->nearest_cell(p.centre);
    t = &ctx.bank.template_for(2 * p.radius, ctx.locator->mesh().cell_volume(cell), s.template_memo);
  }
  polymesh_points(ctx, s, p, *t, particle_rotation(ctx.opts, p), p.outside, centre_cell);
}

void polymesh_divided(const PolyContext& ctx, Scratch& s, const Particle& p) {
  // As in CFDEM: never rotated, and a point in no cell goes to the particle's own cell.
  const Outside policy = p.outside == Outside::nearest ? Outside::centre : p.outside;
  polymesh_points(ctx, s, p, ctx.divided, Eigen::Matrix3d::Identity(), policy, ctx.locator->locate(p.centre));
}

void polymesh_big_particle(const PolyContext& ctx, Scratch& s, const Particle& p) {
  const PolyMesh& mesh = ctx.locator->mesh();
  const Eigen::Vector3d& c = p.centre;
  const double r2 = p.radius * p.radius;
  const std::int64_t centre_cell = ctx.locator->locate(c);
  bool flagged = false;
  if (ctx.opts.fast_path && centre_cell >= 0 && ball_inside_cell(mesh, centre_cell, c, p.radius)) {
    ++s.fast_path;  // only this cell's centre can lie within the particle
    s.add(centre_cell, p.volume);
    return;
  }
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(p.radius);
  ctx.locator->hash().cells_in_box(Eigen::AlignedBox3d(c - half, c + half), s.candidate_cells);
  s.sub_elements += static_cast<std::int64_t>(s.candidate_cells.size());
  std::int64_t count = 0;
  for (const std::int64_t cell : s.candidate_cells) count += (mesh.cell_centre(cell) - c).squaredNorm() <= r2;
  if (count == 0) {  // no cell centre within the particle: its own cell
    if (centre_cell >= 0)
      s.add(centre_cell, p.volume);
    else
      outside_poly(ctx, s, p, p.volume, c, centre_cell, flagged, p.outside);
    return;
  }
  const double share = p.volume / double(count);
  for (const std::int64_t cell : s.candidate_cells)  // candidates are distinct: no merge needed
    if ((mesh.cell_centre(cell) - c).squaredNorm() <= r2) s.deposits.push_back({cell, share});
}

}  // namespace vfe::detail
