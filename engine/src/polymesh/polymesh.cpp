#include "polymesh/polymesh.hpp"

#include "polymesh/predicates.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace vfe {
namespace {

// OpenFOAM's VSMALL and ROOTVSMALL for double precision.
constexpr double kVSmall = 1.0e-300;
constexpr double kRootVSmall = 1.0e-150;

// OpenFOAM's vector operations, spelled out so that the order of operations is its own.
inline Eigen::Vector3d cross(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return {a.y() * b.z() - a.z() * b.y(), a.z() * b.x() - a.x() * b.z(), a.x() * b.y() - a.y() * b.x()};
}
inline double dot(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.x() * b.x() + a.y() * b.y() + a.z() * b.z();
}
inline double mag(const Eigen::Vector3d& a) { return std::sqrt(dot(a, a)); }

[[noreturn]] void invalid(const std::string& source, const std::string& what) {
  std::string msg = source.empty() ? std::string("polyMesh: ") : "polyMesh " + source + ": ";
  throw Error(VFE_ERROR_INVALID_ARGUMENT, msg + what);
}

}  // namespace

PolyMesh PolyMesh::read(const std::filesystem::path& dir) { return PolyMesh(read_polymesh(dir)); }

PolyMesh::PolyMesh(PolyMeshData data) : d_(std::move(data)) {
  validate_topology();
  compute_geometry();
  compute_location_data();
}

void PolyMesh::validate_topology() {
  const std::string& src = d_.source;
  const auto n_points = point_count();
  if (n_points < 4) invalid(src, "the mesh has " + std::to_string(n_points) + " points; a cell needs at least 4");
  for (std::int64_t i = 0; i < n_points; ++i)
    if (!d_.points[static_cast<std::size_t>(i)].allFinite())
      invalid(src, "point " + std::to_string(i) + " has a coordinate that is not a finite number; fix the points");
  if (d_.face_offsets.empty() || d_.face_offsets.front() != 0)
    invalid(src, "face offsets must start with 0 (one more offset than faces)");
  const auto n_faces = static_cast<std::int64_t>(d_.face_offsets.size()) - 1;
  if (d_.face_offsets.back() != static_cast<std::int64_t>(d_.face_points.size()))
    invalid(src, "the last face offset (" + std::to_string(d_.face_offsets.back()) + ") must equal the number of face " +
                     "point labels (" + std::to_string(d_.face_points.size()) + ")");
  for (std::int64_t f = 0; f < n_faces; ++f) {
    // Non-decreasing offsets from 0 to the label count stay in range (and their difference cannot overflow).
    if (d_.face_offsets[static_cast<std::size_t>(f) + 1] < d_.face_offsets[static_cast<std::size_t>(f)])
      invalid(src, "face offset " + std::to_string(f + 1) + " is smaller than the one before; offsets must not decrease");
    const auto size = d_.face_offsets[static_cast<std::size_t>(f) + 1] - d_.face_offsets[static_cast<std::size_t>(f)];
    if (size < 3) invalid(src, "face " + std::to_string(f) + " has " + std::to_string(size) + " points; a face needs at least 3");
    for (const auto p : face(f))
      if (p < 0 || p >= n_points)
        invalid(src, "face " + std::to_string(f) + " refers to point " + std::to_string(p) + " but there are " +
                         std::to_string(n_points) + " points");
  }
  if (static_cast<std::int64_t>(d_.owner.size()) != n_faces)
    invalid(src, "there are " + std::to_string(d_.owner.size()) + " owners for " + std::to_string(n_faces) +
                     " faces; every face needs exactly one owner cell");
  if (d_.neighbour.size() > d_.owner.size())
    invalid(src, "there are " + std::to_string(d_.neighbour.size()) + " neighbours for " + std::to_string(n_faces) +
                     " faces; only internal faces (the first ones) have a neighbour");
  n_cells_ = 0;
  for (std::size_t f = 0; f < d_.owner.size(); ++f) {
    // A cell has at least 4 faces, so labels >= n_faces are corrupt (and label + 1 could overflow).
    if (d_.owner[f] < 0 || d_.owner[f] >= n_faces)
      invalid(src, "owner of face " + std::to_string(f) + " is " + std::to_string(d_.owner[f]) + "; cell labels of a " +
                       "mesh of " + std::to_string(n_faces) + " faces lie in 0.." + std::to_string(n_faces - 1));
    n_cells_ = std::max(n_cells_, d_.owner[f] + 1);
  }
  for (std::size_t f = 0; f < d_.neighbour.size(); ++f) {
    if (d_.neighbour[f] < 0 || d_.neighbour[f] >= n_faces)
      invalid(src, "neighbour of face " + std::to_string(f) + " is " + std::to_string(d_.neighbour[f]) + "; cell " +
                       "labels of a mesh of " + std::to_string(n_faces) + " faces lie in 0.." + std::to_string(n_faces - 1));
    if (d_.neighbour[f] == d_.owner[f])
      invalid(src, "face " + std::to_string(f) + " has cell " + std::to_string(d_.owner[f]) + " as owner and neighbour");
    n_cells_ = std::max(n_cells_, d_.neighbour[f] + 1);
  }

  // Cell -> faces, in OpenFOAM's order: owned faces, then neighboured faces.
  cell_offsets_.assign(static_cast<std::size_t>(n_cells_) + 1, 0);
  for (const auto c : d_.owner) ++cell_offsets_[static_cast<std::size_t>(c) + 1];
  for (const auto c : d_.neighbour) ++cell_offsets_[static_cast<std::size_t>(c) + 1];
  for (std::int64_t c = 0; c < n_cells_; ++c) {
    const auto k = cell_offsets_[static_cast<std::size_t>(c) + 1];
    if (k < 4)
      invalid(src, "cell " + std::to_string(c) + " has " + std::to_string(k) + " faces; a closed cell needs at least 4 " +
                       "(owner and neighbour skip or barely use this label: they do not match the faces)");
    cell_offsets_[static_cast<std::size_t>(c) + 1] += cell_offsets_[static_cast<std::size_t>(c)];
  }
  cell_faces_.resize(static_cast<std::size_t>(cell_offsets_.back()));
  std::vector<std::int64_t> fill(cell_offsets_.begin(), cell_offsets_.end() - 1);
  for (std::size_t f = 0; f < d_.owner.size(); ++f)
    cell_faces_[static_cast<std::size_t>(fill[static_cast<std::size_t>(d_.owner[f])]++)] = static_cast<std::int64_t>(f);
  for (std::size_t f = 0; f < d_.neighbour.size(); ++f)
    cell_faces_[static_cast<std::size_t>(fill[static_cast<std::size_t>(d_.neighbour[f])]++)] = static_cast<std::int64_t>(f);

  if (!d_.patches.empty()) {
    std::int64_t expected = internal_face_count();
    for (const auto& p : d_.patches) {
      if (p.start_face != expected || p.n_faces < 0)
        invalid(src, "patch '" + p.name + "' covers faces " + std::to_string(p.start_face) + ".." +
                         std::to_string(p.start_face + p.n_faces - 1) + " but should start at face " + std::to_string(expected));
      expected += p.n_faces;
    }
    if (expected != n_faces)
      invalid(src, "the patches end at face " + std::to_string(expected) + " but there are " + std::to_string(n_faces) + " faces");
  }
}

void PolyMesh::compute_geometry() {
  const auto n_faces = face_count();
  const auto& p = d_.points;
  face_centres_.resize(static_cast<std::size_t>(n_faces));
  face_areas_.resize(static_cast<std::size_t>(n_faces));
  for (std::int64_t f = 0; f < n_faces; ++f) {
    const auto pts = face(f);
    const std::size_t n = pts.size();
    Eigen::Vector3d& fc = face_centres_[static_cast<std::size_t>(f)];
    Eigen::Vector3d& fa = face_areas_[static_cast<std::size_t>(f)];
    if (n == 3) {
      const Eigen::Vector3d& a = p[static_cast<std::size_t>(pts[0])];
      const Eigen::Vector3d& b = p[static_cast<std::size_t>(pts[1])];
      const Eigen::Vector3d& c = p[static_cast<std::size_t>(pts[2])];
      fc = (1.0 / 3.0) * ((a + b) + c);
      fa = 0.5 * cross(b - a, c - a);
      continue;
    }
    Eigen::Vector3d centre = p[static_cast<std::size_t>(pts[0])];
    for (std::size_t i = 1; i < n; ++i) centre += p[static_cast<std::size_t>(pts[i])];
    centre /= static_cast<double>(n);
    Eigen::Vector3d sum_n = Eigen::Vector3d::Zero(), sum_ac = Eigen::Vector3d::Zero();
    double sum_a = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& here = p[static_cast<std::size_t>(pts[i])];
      const Eigen::Vector3d& next = p[static_cast<std::size_t>(pts[i + 1 == n ? 0 : i + 1])];
      const Eigen::Vector3d c = (here + next) + centre;
      const Eigen::Vector3d nv = cross(next - here, centre - here);
      const double a = mag(nv);
      sum_n += nv;
      sum_a += a;
      sum_ac += a * c;
    }
    if (sum_a < kRootVSmall) {
      fc = centre;
      fa.setZero();
    } else {
      fc = ((1.0 / 3.0) * sum_ac) / sum_a;
      fa = 0.5 * sum_n;
    }
  }

  face_apexes_ = face_centres_;
  for (std::int64_t f = 0; f < n_faces; ++f) {
    const auto pts = face(f);
    const Eigen::Vector3d& first = p[static_cast<std::size_t>(pts[0])];
    for (int d = 0; d < 3; ++d) {
      bool shared = true;
      for (const auto q : pts) shared = shared && p[static_cast<std::size_t>(q)][d] == first[d];
      if (shared) face_apexes_[static_cast<std::size_t>(f)][d] = first[d];
    }
  }

  cell_centres_.assign(static_cast<std::size_t>(n_cells_), Eigen::Vector3d::Zero());
  cell_volumes_.assign(static_cast<std::size_t>(n_cells_), 0.0);
  cell_bounds_.resize(static_cast<std::size_t>(n_cells_));
  total_volume_ = 0;
  for (std::int64_t c = 0; c < n_cells_; ++c) {
    const auto faces = cell_faces(c);
    Eigen::Vector3d est = Eigen::Vector3d::Zero();
    for (const auto f : faces) est += face_centres_[static_cast<std::size_t>(f)];
    est /= static_cast<double>(faces.size());
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    double vol3 = 0;
    Eigen::Vector3d closed = Eigen::Vector3d::Zero();
    double area_sum = 0;
    for (const auto f : faces) {
      const Eigen::Vector3d& fc = face_centres_[static_cast<std::size_t>(f)];
      const Eigen::Vector3d& fa = face_areas_[static_cast<std::size_t>(f)];
      const bool owned = owner(f) == c;
      const double pyr3 = owned ? dot(fa, fc - est) : dot(fa, est - fc);
      const Eigen::Vector3d pc = (3.0 / 4.0) * fc + (1.0 / 4.0) * est;
      centre += pyr3 * pc;
      vol3 += pyr3;
      closed += owned ? fa : Eigen::Vector3d(-fa);
      area_sum += mag(fa);
    }
    if (std::fabs(vol3) > kVSmall) {
      centre /= vol3;
    } else {
      centre = est;
    }
    const double vol = vol3 * (1.0 / 3.0);
    // checkMesh's closedness test: the outward area vectors of a closed cell sum to zero.
    if (!(mag(closed) <= 1e-6 * area_sum)) {
      std::ostringstream msg;
      msg << "cell " << c << " is not closed (its outward face area vectors sum to " << mag(closed) << ", "
          << mag(closed) / area_sum << " of its face area): a face is missing or listed with the wrong owner; "
          << "check the mesh with checkMesh";
      invalid(d_.source, msg.str());
    }
    if (!(vol > 0)) {
      std::ostringstream msg;
      msg << "cell " << c << " has volume " << vol << " (centre near " << est.transpose()
          << "): its faces are oriented inwards or it is degenerate; a face's points must be ordered so that its "
          << "normal points from the owner to the neighbour; check the mesh with checkMesh";
      invalid(d_.source, msg.str());
    }
    cell_centres_[static_cast<std::size_t>(c)] = centre;
    cell_volumes_[static_cast<std::size_t>(c)] = vol;
    total_volume_ += vol;

    // Bounds of the tetrahedra (centre, face apex and centre, face points).
    Eigen::AlignedBox3d box(centre);
    for (const auto f : faces) {
      const Eigen::Vector3d& fc = face_apexes_[static_cast<std::size_t>(f)];
      box.extend(fc);
      box.extend(face_centres_[static_cast<std::size_t>(f)]);
      for (const auto q : face(f)) box.extend(p[static_cast<std::size_t>(q)]);
    }
    cell_bounds_[static_cast<std::size_t>(c)] = box;
  }

  bounds_ = Eigen::AlignedBox3d(p.front());
  for (const auto& x : p) bounds_.extend(x);
}

void PolyMesh::compute_location_data() {
  const auto& p = d_.points;
  const auto n_faces = face_count();
  const auto point = [&](std::int64_t label) -> const Eigen::Vector3d& { return p[static_cast<std::size_t>(label)]; };

  // Faces in a plane x_d = const (all points share coordinate d exactly; the apex does too)
  // are decided by comparisons; other faces by exact orientation signs.
  face_axis_.assign(static_cast<std::size_t>(n_faces), -1);
  face_plane_.assign(static_cast<std::size_t>(n_faces), -1);
  face_normals_.resize(static_cast<std::size_t>(n_faces));
  face_warps_.resize(static_cast<std::size_t>(n_faces));
  for (std::int64_t f = 0; f < n_faces; ++f) {
    const auto pts = face(f);
    const std::size_t n = pts.size();
    const Eigen::Vector3d& apex = face_apex(f);
    for (int d = 0; d < 3 && face_axis_[static_cast<std::size_t>(f)] < 0; ++d) {
      bool shared = face_area(f)[d] != 0;
      for (const auto q : pts) shared = shared && point(q)[d] == point(pts[0])[d];
      if (shared) face_axis_[static_cast<std::size_t>(f)] = static_cast<std::int8_t>(d);
    }
    // The largest fan triangle as reference; the face is planar when every point lies
    // exactly in its plane (the apex is one of its corners).
    std::size_t best = 0;
    double best_area = -1;
    for (std::size_t i = 0; i < n; ++i) {
      const double area = (point(pts[i]) - apex).cross(point(pts[i + 1 == n ? 0 : i + 1]) - apex).squaredNorm();
      if (area > best_area) {
        best_area = area;
        best = i;
      }
    }
    const std::size_t next = best + 1 == n ? 0 : best + 1;
    bool planar = best_area > 0;
    if (face_axis_[static_cast<std::size_t>(f)] < 0)
      for (std::size_t i = 0; i < n && planar; ++i)
        if (i != best && i != next) planar = geom::orient3d_exact(apex, point(pts[best]), point(pts[next]), point(pts[i])) == 0;
    if (planar) face_plane_[static_cast<std::size_t>(f)] = static_cast<std::int32_t>(best);

    const Eigen::Vector3d& a = face_area(f);
    const double m = a.norm();
    const Eigen::Vector3d normal = m > 0 ? Eigen::Vector3d(a / m) : Eigen::Vector3d::Zero();
    const Eigen::Vector3d& o = face_centre(f);
    double warp = std::fabs(normal.dot(apex - o));
    for (const auto q : pts) warp = std::max(warp, std::fabs(normal.dot(point(q) - o)));
    face_normals_[static_cast<std::size_t>(f)] = normal;
    face_warps_[static_cast<std::size_t>(f)] = warp;
  }
  // Plane distances are evaluated in floating point: their error stays below a few ulps of
  // the coordinates involved; this bound is far above it and far below any cell size.
  tolerance_ = 64 * std::numeric_limits<double>::epsilon() *
               (bounds_.max().cwiseAbs().cwiseMax(bounds_.min().cwiseAbs()).maxCoeff() + bounds_.diagonal().norm());

  // Per cell: reach beyond each face plane; positive tetrahedra; convexity (exact: no
  // vertex of its tetrahedra outside any fan triangle's plane); deep-point acceptance.
  reach_.assign(cell_faces_.size(), 0.0);
  cell_flags_.assign(static_cast<std::size_t>(n_cells_), 0);
  inverted_tets_ = 0;
  std::vector<std::int64_t> labels;  // vertex k: point label, or -1 - face for an apex, or
  std::vector<Eigen::Vector3d> vertices;  // the centre (label kCentre)
  constexpr std::int64_t kCentre = std::numeric_limits<std::int64_t>::min();
  for (std::int64_t c = 0; c < n_cells_; ++c) {
    const auto faces = cell_faces(c);
    labels.clear();
    for (const auto f : faces) labels.insert(labels.end(), face(f).begin(), face(f).end());
    std::sort(labels.begin(), labels.end());
    labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
    for (const auto f : faces) labels.push_back(-1 - f);
    labels.push_back(kCentre);
    vertices.clear();
    const Eigen::Vector3d& centre = cell_centre(c);
    for (const auto l : labels) vertices.push_back(l == kCentre ? centre : l < 0 ? face_apex(-1 - l) : point(l));

    bool positive = true, deep = true;
    for (std::size_t k = 0; k < faces.size(); ++k) {
      const auto f = faces[k];
      const bool owned = owner(f) == c;
      const Eigen::Vector3d& n = face_normal(f);
      const Eigen::Vector3d& o = face_centre(f);
      double reach = -std::numeric_limits<double>::infinity();
      for (const auto& v : vertices) reach = std::max(reach, (owned ? 1.0 : -1.0) * n.dot(v - o));
      reach_[static_cast<std::size_t>(cell_face_offset(c)) + k] = reach;
      deep = deep && (owned ? 1.0 : -1.0) * n.dot(centre - o) < -face_warp(f) - 2 * tolerance_;
      const auto pts = face(f);
      for (std::size_t i = 0; i < pts.size(); ++i) {
        // orient(apex, a, b, x) < 0 on the owner's side of a fan triangle.
        const int s = geom::orient3d_exact(face_apex(f), point(pts[i]), point(pts[i + 1 == pts.size() ? 0 : i + 1]), centre);
        if (owned ? s >= 0 : s <= 0) {
          positive = false;
          ++inverted_tets_;
        }
      }
    }

    bool convex = positive;
    for (std::size_t k = 0; k < faces.size() && convex; ++k) {
      const auto f = faces[k];
      const int outward = owner(f) == c ? 1 : -1;
      const auto pts = face(f);
      const std::size_t n = pts.size();
      const auto on_face = [&](std::int64_t label) {
        return label == -1 - f || std::find(pts.begin(), pts.end(), label) != pts.end();
      };
      if (const int d = face_axis_[static_cast<std::size_t>(f)]; d >= 0) {
        // Plane x_d = x0 with normal +-e_d: the sign of a vertex is that of x_d - x0.
        const double x0 = point(pts[0])[d];
        const int up = outward * (face_area(f)[d] > 0 ? 1 : -1);
        for (std::size_t v = 0; v < vertices.size() && convex; ++v)
          convex = up * ((vertices[v][d] > x0) - (vertices[v][d] < x0)) <= 0;
        continue;
      }
      const std::int32_t ref = face_plane_triangle(f);
      for (std::size_t i = 0; i < n && convex; ++i) {
        // A planar face has one plane: checking its reference triangle is enough, and its
        // own points lie in it.
        if (ref >= 0 && static_cast<std::size_t>(ref) != i) continue;
        const std::int64_t la = pts[i], lb = pts[i + 1 == n ? 0 : i + 1];
        for (std::size_t v = 0; v < vertices.size() && convex; ++v) {
          const std::int64_t l = labels[v];
          if (l == la || l == lb || l == -1 - f || (ref >= 0 && on_face(l))) continue;
          convex = outward * geom::orient3d_exact(face_apex(f), point(la), point(lb), vertices[v]) <= 0;
        }
      }
    }
    cell_flags_[static_cast<std::size_t>(c)] =
        static_cast<std::uint8_t>((convex ? kConvex : 0) | (positive && deep ? kDeepAccept : 0));
  }
}

}  // namespace vfe
