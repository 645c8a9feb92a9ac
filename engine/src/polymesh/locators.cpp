#include "polymesh/locators.hpp"

#include "polymesh/predicates.hpp"

#include <vfe/error.hpp>

#include <nanoflann.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace vfe {

bool cell_contains(const PolyMesh& mesh, std::int64_t c, const Eigen::Vector3d& p) {
  if (!mesh.cell_bounds(c).contains(p)) return false;
  // Plane distances first (floating point, decisive only beyond the rounding bound):
  // beyond a face plane by more than the cell reaches: outside; deeper than every face's
  // warp, in a cell whose centre is deeper too: inside (the ray from the centre through p
  // leaves the cell beyond p). Exact signs only for points near a face.
  {
    const auto faces = mesh.cell_faces(c);
    const auto base = mesh.cell_face_offset(c);
    const double tol = mesh.location_tolerance();
    bool deep = mesh.cell_accepts_deep_points(c);
    for (std::size_t k = 0; k < faces.size(); ++k) {
      const auto f = faces[k];
      const double d = mesh.face_normal(f).dot(p - mesh.face_centre(f));
      const double out = mesh.owner(f) == c ? d : -d;
      if (out > mesh.cell_face_reach(base + static_cast<std::int64_t>(k)) + tol) return false;
      deep = deep && out < -mesh.face_warp(f) - tol;
    }
    if (deep) return true;
  }
  const auto& pts = mesh.points();
  if (mesh.cell_is_convex(c)) {
    // The cell is the intersection of the inner sides of its fan triangles (one triangle
    // per exactly planar face): for a point displaced by (e, e^2, e^3) the same answer as
    // the tetrahedra below, so convex and general cells agree on shared faces.
    for (const auto f : mesh.cell_faces(c)) {
      const bool owned = mesh.owner(f) == c;
      const auto face = mesh.face(f);
      const std::size_t n = face.size();
      const Eigen::Vector3d& fc = mesh.face_apex(f);
      const std::int32_t ref = mesh.face_plane_triangle(f);
      const std::size_t first = ref >= 0 ? static_cast<std::size_t>(ref) : 0;
      const std::size_t last = ref >= 0 ? first + 1 : n;
      for (std::size_t i = first; i < last; ++i) {
        const int s = geom::orient3d_sos(fc, pts[static_cast<std::size_t>(face[i])],
                                         pts[static_cast<std::size_t>(face[i + 1 == n ? 0 : i + 1])], p);
        if (owned ? s >= 0 : s <= 0) return false;
      }
    }
    return true;
  }
  const Eigen::Vector3d& centre = mesh.cell_centre(c);
  for (const auto f : mesh.cell_faces(c)) {
    const bool owned = mesh.owner(f) == c;
    const auto face = mesh.face(f);
    const std::size_t n = face.size();
    const Eigen::Vector3d& fc = mesh.face_apex(f);
    // Tetrahedron (centre, fc, a, b) for consecutive points a = P_i, b = P_j of the face.
    // With the spoke signs w_i = orient(fc, P_i, centre, p), p is inside it when
    //   owner:     w_i > 0, w_j < 0, orient(b, a, centre, p) < 0, orient(fc, a, b, p) < 0
    //   neighbour: w_j > 0, w_i < 0, orient(a, b, centre, p) < 0, orient(fc, a, b, p) > 0
    // (the four barycentric signs of the positively oriented tetrahedron).
    const Eigen::Vector3d& p0 = pts[static_cast<std::size_t>(face[0])];
    const int w0 = geom::orient3d_sos(fc, p0, centre, p);
    int wi = w0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t j = i + 1 == n ? 0 : i + 1;
      const Eigen::Vector3d& b = pts[static_cast<std::size_t>(face[j])];
      const int wj = j == 0 ? w0 : geom::orient3d_sos(fc, b, centre, p);
      const bool spokes = owned ? (wi > 0 && wj < 0) : (wj > 0 && wi < 0);
      if (spokes) {
        const Eigen::Vector3d& a = pts[static_cast<std::size_t>(face[i])];
        if ((owned ? geom::orient3d_sos(b, a, centre, p) : geom::orient3d_sos(a, b, centre, p)) < 0) {
          const int s = geom::orient3d_sos(fc, a, b, p);
          if (owned ? s < 0 : s > 0) return true;
        }
      }
      wi = wj;
    }
  }
  return false;
}

std::int64_t locate_brute_force(const PolyMesh& mesh, const Eigen::Vector3d& p) {
  for (std::int64_t c = 0; c < mesh.cell_count(); ++c)
    if (cell_contains(mesh, c, p)) return c;
  return -1;
}

// ---------------------------------------------------------------------------------------
// Spatial hash

SpatialHash::SpatialHash(const PolyMesh& mesh, double bins_per_cell) : mesh_(&mesh) {
  if (!(bins_per_cell > 0) || !std::isfinite(bins_per_cell))
    throw Error(VFE_ERROR_INVALID_ARGUMENT, "spatial hash: bins_per_cell is " + std::to_string(bins_per_cell) +
                                                "; give a finite number > 0 (1 is a good default)");
  const auto n_cells = mesh.cell_count();
  if (n_cells > std::int64_t(std::numeric_limits<std::uint32_t>::max()))
    throw Error(VFE_ERROR_UNSUPPORTED, "spatial hash: more than 2^32 cells; split the mesh");
  Eigen::AlignedBox3d box = mesh.cell_bounds(0);
  for (std::int64_t c = 1; c < n_cells; ++c) box.extend(mesh.cell_bounds(c));
  lo_ = box.min();
  hi_ = box.max();
  Eigen::Vector3d extent = hi_ - lo_;
  const double tiny = 1e-300;
  for (int d = 0; d < 3; ++d) extent[d] = std::max(extent[d], tiny);
  // Bins of equal size in every direction (as far as the box allows), about
  // bins_per_cell * cells of them.
  // A mesh much thinner than a bin in one direction (a 2D case one cell thick) would get
  // far more bins than asked for in the others: grow the bins until the count fits.
  const double target = std::max(1.0, bins_per_cell * double(n_cells));
  double h = std::cbrt(extent.prod() / target);
  for (;;) {
    double total = 1;
    for (int d = 0; d < 3; ++d) {
      const double n = std::clamp(std::ceil(extent[d] / h), 1.0, std::min(target, 1048576.0));
      nb_[static_cast<std::size_t>(d)] = static_cast<std::int64_t>(n);
      total *= n;
    }
    if (total <= 2 * target + 64) break;
    h *= 1.25;
  }
  for (int d = 0; d < 3; ++d) inv_h_[d] = double(nb_[static_cast<std::size_t>(d)]) / extent[d];
  const auto n_bins = nb_[0] * nb_[1] * nb_[2];

  // Counting sort of (bin, cell): count, scan, fill; then each bin's cells in locate()'s order.
  offsets_.assign(static_cast<std::size_t>(n_bins) + 1, 0);
  const auto for_each_bin = [&](std::int64_t c, auto&& f) {
    const auto& b = mesh.cell_bounds(c);
    const std::int64_t i0 = bin(0, b.min().x()), i1 = bin(0, b.max().x());
    const std::int64_t j0 = bin(1, b.min().y()), j1 = bin(1, b.max().y());
    const std::int64_t k0 = bin(2, b.min().z()), k1 = bin(2, b.max().z());
    for (std::int64_t k = k0; k <= k1; ++k)
      for (std::int64_t j = j0; j <= j1; ++j)
        for (std::int64_t i = i0; i <= i1; ++i) f(i + nb_[0] * (j + nb_[1] * k));
  };
  for (std::int64_t c = 0; c < n_cells; ++c) for_each_bin(c, [&](std::int64_t b) { ++offsets_[static_cast<std::size_t>(b) + 1]; });
  for (std::int64_t b = 0; b < n_bins; ++b) offsets_[static_cast<std::size_t>(b) + 1] += offsets_[static_cast<std::size_t>(b)];
  cells_.resize(static_cast<std::size_t>(offsets_.back()));
  std::vector<std::int64_t> fill(offsets_.begin(), offsets_.end() - 1);
  for (std::int64_t c = 0; c < n_cells; ++c)
    for_each_bin(c, [&](std::int64_t b) {
      cells_[static_cast<std::size_t>(fill[static_cast<std::size_t>(b)]++)] = static_cast<std::uint32_t>(c);
    });
  // Within a bin, the cells whose bounds cover more of it first (ties by cell): locate()
  // tests them in this order and stops at the one holding the point, most often the first.
  std::vector<std::pair<double, std::uint32_t>> order;
  const Eigen::Vector3d bin_size = inv_h_.cwiseInverse();
  for (std::int64_t b = 0; b < n_bins; ++b) {
    const auto begin = static_cast<std::size_t>(offsets_[static_cast<std::size_t>(b)]);
    const auto end = static_cast<std::size_t>(offsets_[static_cast<std::size_t>(b) + 1]);
    if (end - begin < 2) continue;
    const std::int64_t i = b % nb_[0], j = b / nb_[0] % nb_[1], k = b / nb_[0] / nb_[1];
    const Eigen::Vector3d bin_lo = lo_ + bin_size.cwiseProduct(Eigen::Vector3d(double(i), double(j), double(k)));
    const Eigen::AlignedBox3d bin_box(bin_lo, bin_lo + bin_size);
    order.clear();
    for (std::size_t e = begin; e < end; ++e) {
      const Eigen::AlignedBox3d cover = mesh.cell_bounds(cells_[e]).intersection(bin_box);
      order.emplace_back(cover.isEmpty() ? 0.0 : cover.volume(), cells_[e]);
    }
    std::sort(order.begin(), order.end(), [](const auto& x, const auto& y) {
      return x.first > y.first || (x.first == y.first && x.second < y.second);
    });
    for (std::size_t e = begin; e < end; ++e) cells_[e] = order[e - begin].second;
  }
}

std::int64_t SpatialHash::bin(int d, double x) const {
  // Monotone in x, so a point inside a cell's bounds is in one of the cell's bins.
  const double t = std::floor((x - lo_[d]) * inv_h_[d]);
  const auto n = nb_[static_cast<std::size_t>(d)];
  return t < 0 ? 0 : (t >= double(n) ? n - 1 : static_cast<std::int64_t>(t));
}

std::span<const std::uint32_t> SpatialHash::candidates(const Eigen::Vector3d& p) const {
  if (!in_box(p)) return {};
  const std::int64_t b = bin(0, p.x()) + nb_[0] * (bin(1, p.y()) + nb_[1] * bin(2, p.z()));
  const auto begin = offsets_[static_cast<std::size_t>(b)], end = offsets_[static_cast<std::size_t>(b) + 1];
  return {cells_.data() + begin, static_cast<std::size_t>(end - begin)};
}

bool SpatialHash::bin_range(const Eigen::AlignedBox3d& box, std::int64_t lo[3], std::int64_t hi[3]) const {
  if (!(box.min().array() <= hi_.array()).all() || !(box.max().array() >= lo_.array()).all()) return false;
  for (int d = 0; d < 3; ++d) {
    lo[d] = bin(d, box.min()[d]);
    hi[d] = bin(d, box.max()[d]);
  }
  return true;
}

void SpatialHash::cells_in_box(const Eigen::AlignedBox3d& box, std::vector<std::int64_t>& out) const {
  out.clear();
  std::int64_t lo[3], hi[3];
  if (!bin_range(box, lo, hi)) return;
  const std::int64_t i0 = lo[0], i1 = hi[0], j0 = lo[1], j1 = hi[1], k0 = lo[2], k1 = hi[2];
  for (std::int64_t k = k0; k <= k1; ++k)
    for (std::int64_t j = j0; j <= j1; ++j)
      for (std::int64_t i = i0; i <= i1; ++i) {
        const auto b = static_cast<std::size_t>(i + nb_[0] * (j + nb_[1] * k));
        for (auto e = offsets_[b]; e < offsets_[b + 1]; ++e) {
          const std::uint32_t c = cells_[static_cast<std::size_t>(e)];
          const Eigen::AlignedBox3d& cb = mesh_->cell_bounds(c);
          // A cell is listed in every bin its box overlaps: take it in the first of those
          // that the query visits.
          if (cb.intersects(box) && i == std::max(i0, bin(0, cb.min().x())) && j == std::max(j0, bin(1, cb.min().y())) &&
              k == std::max(k0, bin(2, cb.min().z())))
            out.push_back(c);
        }
      }
}

void SpatialHash::sorted_cells_in_box(const Eigen::AlignedBox3d& box, std::vector<std::int64_t>& out) const {
  out.clear();
  std::int64_t lo[3], hi[3];
  if (!bin_range(box, lo, hi)) return;
  const std::int64_t i0 = lo[0], i1 = hi[0], j0 = lo[1], j1 = hi[1], k0 = lo[2], k1 = hi[2];
  for (std::int64_t k = k0; k <= k1; ++k)
    for (std::int64_t j = j0; j <= j1; ++j)
      for (std::int64_t i = i0; i <= i1; ++i) {
        const auto b = static_cast<std::size_t>(i + nb_[0] * (j + nb_[1] * k));
        for (auto e = offsets_[b]; e < offsets_[b + 1]; ++e) {
          const std::uint32_t c = cells_[static_cast<std::size_t>(e)];
          if (mesh_->cell_bounds(c).intersects(box)) out.push_back(c);
        }
      }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

std::int64_t SpatialHash::locate(const Eigen::Vector3d& p) const {
  for (const auto c : candidates(p))
    if (cell_contains(*mesh_, c, p)) return c;
  return -1;
}

// ---------------------------------------------------------------------------------------
// KD-tree

namespace {

/// nanoflann dataset adaptor over the mesh's cell centres (owned by the mesh).
struct CentreCloud {
  const std::vector<Eigen::Vector3d>* centres;
  std::size_t kdtree_get_point_count() const { return centres->size(); }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return (*centres)[i][static_cast<Eigen::Index>(d)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using CentreTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, CentreCloud>, CentreCloud, 3, std::uint32_t>;

constexpr int kMaxK = 64;

}  // namespace

struct KdTreeLocator::Impl {
  const PolyMesh* mesh;
  const SpatialHash* hash;
  int k;
  CentreCloud cloud;
  CentreTree tree;  // built in the constructor; refers to cloud, which lives beside it

  Impl(const PolyMesh& m, const SpatialHash& h, int k_, int leaf)
      : mesh(&m), hash(&h), k(k_), cloud{&m.cell_centres()},
        tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(static_cast<std::size_t>(leaf))) {}
};

KdTreeLocator::KdTreeLocator(const PolyMesh& mesh, const SpatialHash& fallback, int k, int leaf_max_size) {
  if (k < 1 || k > kMaxK)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "KD-tree locator: k is " + std::to_string(k) + "; give 1 .. " + std::to_string(kMaxK) + " (8 is a good default)");
  if (leaf_max_size < 1)
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "KD-tree locator: leaf_max_size is " + std::to_string(leaf_max_size) + "; give >= 1 (10 is a good default)");
  if (mesh.cell_count() > std::int64_t(std::numeric_limits<std::uint32_t>::max()))
    throw Error(VFE_ERROR_UNSUPPORTED, "KD-tree locator: more than 2^32 cells; split the mesh");
  impl_ = std::make_unique<Impl>(mesh, fallback, k, leaf_max_size);
}

KdTreeLocator::~KdTreeLocator() = default;
KdTreeLocator::KdTreeLocator(KdTreeLocator&&) noexcept = default;
KdTreeLocator& KdTreeLocator::operator=(KdTreeLocator&&) noexcept = default;

std::int64_t KdTreeLocator::locate(const Eigen::Vector3d& p) const {
  if (!impl_->hash->in_box(p)) return -1;
  // The nearest centre's cell holds most points; a query for k is dearer than for one.
  std::uint32_t idx[kMaxK];
  double d2[kMaxK];
  impl_->tree.knnSearch(p.data(), 1, idx, d2);
  if (cell_contains(*impl_->mesh, idx[0], p)) return idx[0];
  const std::uint32_t first = idx[0];
  if (impl_->k > 1) {
    const std::size_t found = impl_->tree.knnSearch(p.data(), static_cast<std::size_t>(impl_->k), idx, d2);
    for (std::size_t i = 0; i < found; ++i)
      if (idx[i] != first && cell_contains(*impl_->mesh, idx[i], p)) return idx[i];
  }
  return impl_->hash->locate(p);
}

std::int64_t KdTreeLocator::nearest_cell(const Eigen::Vector3d& p) const {
  if (!p.allFinite()) return 0;
  std::uint32_t idx = 0;
  double d2 = 0;
  impl_->tree.knnSearch(p.data(), 1, &idx, &d2);
  return idx;
}

std::size_t KdTreeLocator::nearest_cells(const Eigen::Vector3d& p, std::size_t k, std::uint32_t* cells,
                                         double* d2) const {
  k = std::clamp<std::size_t>(k, 1, kMaxK);
  return impl_->tree.knnSearch(p.data(), k, cells, d2);
}

// ---------------------------------------------------------------------------------------
// Neighbour walk

NeighbourWalk::NeighbourWalk(const PolyMesh& mesh, const SpatialHash& fallback, std::int64_t max_steps)
    : mesh_(&mesh), hash_(&fallback), max_steps_(max_steps) {
  const auto& b = mesh.bounds();
  const Eigen::Vector3d extent = b.max() - b.min();
  if (max_steps_ <= 0) {
    const double h = std::cbrt(mesh.total_volume() / double(mesh.cell_count()));
    const double across = h > 0 ? extent.sum() / h : 0.0;
    max_steps_ = static_cast<std::int64_t>(std::min(4.0 * across + 32.0, 1e9));
  }
}

NeighbourWalk::Result NeighbourWalk::walk(const Eigen::Vector3d& p, std::int64_t start) const {
  Result r;
  if (start < 0 || start >= mesh_->cell_count() || !p.allFinite()) return r;
  const PolyMesh& mesh = *mesh_;
  std::int64_t c = start;
  for (r.steps = 0; r.steps <= max_steps_; ++r.steps) {
    // The face whose plane p lies furthest beyond (cell_contains repeats these distances,
    // but only for the cell that is not obviously left behind).
    const auto faces = mesh.cell_faces(c);
    const auto base = mesh.cell_face_offset(c);
    double best = -std::numeric_limits<double>::infinity();
    std::int64_t best_face = -1;
    bool outside = false;
    for (std::size_t k = 0; k < faces.size(); ++k) {
      const auto f = faces[k];
      const double d = mesh.face_normal(f).dot(p - mesh.face_centre(f));
      const double out = mesh.owner(f) == c ? d : -d;
      if (out > mesh.cell_face_reach(base + static_cast<std::int64_t>(k)) + mesh.location_tolerance()) outside = true;
      if (out > best) {
        best = out;
        best_face = f;
      }
    }
    if (!outside && cell_contains(mesh, c, p)) {
      r.cell = c;
      r.stop = Stop::kInside;
      return r;
    }
    const std::int64_t next = mesh.across(best_face, c);
    if (next < 0) {
      r.stop = Stop::kBoundary;
      return r;
    }
    c = next;
  }
  r.steps = max_steps_;
  r.stop = Stop::kStepLimit;
  return r;
}

std::int64_t NeighbourWalk::locate(const Eigen::Vector3d& p, std::int64_t start) const {
  if (!hash_->in_box(p)) return -1;
  const Result r = walk(p, start);
  return r.stop == Stop::kInside ? r.cell : hash_->locate(p);
}

// ---------------------------------------------------------------------------------------

CellLocator::CellLocator(const PolyMesh& mesh) : hash_(mesh), kdtree_(mesh, hash_), walk_(mesh, hash_) {}

}  // namespace vfe
