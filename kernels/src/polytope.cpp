#include <vfe/kernels/polytope.hpp>

#include <algorithm>

namespace vfe::kernels {

namespace {

TetrahedronRule make_rule(int degree) {
  TetrahedronRule r;
  r.degree = degree;
  const auto add = [&r](double w, std::array<double, 4> p) {
    r.points[static_cast<std::size_t>(r.size)] = p;
    r.weights[static_cast<std::size_t>(r.size)] = w;
    ++r.size;
  };
  // Every permutation of (a, a, a, 1 - 3a) and of (b, b, 1/2 - b, 1/2 - b).
  const auto class31 = [&](double w, double a) {
    for (int k = 0; k < 4; ++k) {
      std::array<double, 4> p{a, a, a, a};
      p[static_cast<std::size_t>(k)] = 1 - 3 * a;
      add(w, p);
    }
  };
  const auto class22 = [&](double w, double b) {
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        std::array<double, 4> p{0.5 - b, 0.5 - b, 0.5 - b, 0.5 - b};
        p[static_cast<std::size_t>(i)] = b;
        p[static_cast<std::size_t>(j)] = b;
        add(w, p);
      }
  };
  switch (degree) {
    case 1: add(1.0, {0.25, 0.25, 0.25, 0.25}); break;
    case 2: class31(0.25, 0.1381966011250105151795413); break;
    default:
      class31(0.1126879257180158507991856, 0.3108859192633006097973457);
      class31(0.0734930431163619495437102, 0.0927352503108912264023239);
      class22(0.0425460207770814664380694, 0.0455037041256496494918805);
      break;
  }
  return r;
}

}  // namespace

const TetrahedronRule& tetrahedron_rule(int degree) {
  static const TetrahedronRule rules[3] = {make_rule(1), make_rule(2), make_rule(5)};
  return degree <= 1 ? rules[0] : degree == 2 ? rules[1] : rules[2];
}

ConvexPolytope ConvexPolytope::tetrahedron(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                           const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  ConvexPolytope p;
  const double orientation = (b - a).dot((c - a).cross(d - a));
  if (!(orientation != 0) || !std::isfinite(orientation)) return p;
  p.n_ = 4;
  // Neighbours counter-clockwise seen from outside for a positive (a, b, c, d); a
  // negative one swaps c and d.
  p.v_[0] = {a, {1, 3, 2}};
  p.v_[1] = {b, {2, 3, 0}};
  p.v_[2] = {orientation > 0 ? c : d, {0, 3, 1}};
  p.v_[3] = {orientation > 0 ? d : c, {1, 2, 0}};
  return p;
}

ConvexPolytope ConvexPolytope::box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  ConvexPolytope p;
  if (!((hi - lo).minCoeff() > 0)) return p;
  p.n_ = 8;
  p.v_[0] = {{lo[0], lo[1], lo[2]}, {1, 4, 3}};
  p.v_[1] = {{hi[0], lo[1], lo[2]}, {2, 5, 0}};
  p.v_[2] = {{hi[0], hi[1], lo[2]}, {3, 6, 1}};
  p.v_[3] = {{lo[0], hi[1], lo[2]}, {0, 7, 2}};
  p.v_[4] = {{lo[0], lo[1], hi[2]}, {7, 0, 5}};
  p.v_[5] = {{hi[0], lo[1], hi[2]}, {4, 1, 6}};
  p.v_[6] = {{hi[0], hi[1], hi[2]}, {5, 2, 7}};
  p.v_[7] = {{lo[0], hi[1], hi[2]}, {6, 3, 4}};
  return p;
}

bool ConvexPolytope::clip(const Eigen::Vector3d& normal, double offset) {
  if (n_ == 0) return !overflow_;
  // Signed distance inside (>= 0 kept), as r3d: vertices on the plane stay.
  std::array<double, kCapacity> inside;
  std::array<std::int16_t, kCapacity> index;  // clipped flag, then the new index
  int n_clipped = 0;
  for (int i = 0; i < n_; ++i) {
    inside[static_cast<std::size_t>(i)] = offset - normal.dot(v_[static_cast<std::size_t>(i)].pos);
    const bool out = inside[static_cast<std::size_t>(i)] < 0;
    index[static_cast<std::size_t>(i)] = out ? 1 : 0;
    n_clipped += out;
  }
  if (n_clipped == 0) return true;
  if (n_clipped == n_) {
    n_ = 0;
    return true;
  }
  const int old = n_;
  // A new vertex on every edge from a kept vertex to a clipped one.
  for (int cur = 0; cur < old; ++cur) {
    if (index[static_cast<std::size_t>(cur)]) continue;
    for (int slot = 0; slot < 3; ++slot) {
      const int next = v_[static_cast<std::size_t>(cur)].nbr[static_cast<std::size_t>(slot)];
      if (!index[static_cast<std::size_t>(next)]) continue;
      if (n_ >= kCapacity) {
        n_ = 0;
        overflow_ = true;
        return false;
      }
      const double si = inside[static_cast<std::size_t>(cur)], so = inside[static_cast<std::size_t>(next)];
      Vertex& nv = v_[static_cast<std::size_t>(n_)];
      nv.pos = (v_[static_cast<std::size_t>(cur)].pos * (-so) + v_[static_cast<std::size_t>(next)].pos * si) / (si - so);
      nv.nbr[0] = static_cast<std::int16_t>(cur);
      v_[static_cast<std::size_t>(cur)].nbr[static_cast<std::size_t>(slot)] = static_cast<std::int16_t>(n_);
      index[static_cast<std::size_t>(n_)] = 0;
      ++n_;
    }
  }
  // Link the new vertices around the new face: from each, walk its old face (kept
  // vertices) until the next new vertex.
  for (int start = old; start < n_; ++start) {
    int cur = start, next = v_[static_cast<std::size_t>(cur)].nbr[0];
    do {
      const auto& nb = v_[static_cast<std::size_t>(next)].nbr;
      const int back = nb[0] == cur ? 0 : nb[1] == cur ? 1 : 2;
      cur = next;
      next = v_[static_cast<std::size_t>(cur)].nbr[static_cast<std::size_t>((back + 1) % 3)];
    } while (cur < old);
    v_[static_cast<std::size_t>(start)].nbr[2] = static_cast<std::int16_t>(cur);
    v_[static_cast<std::size_t>(cur)].nbr[1] = static_cast<std::int16_t>(start);
  }
  // Compact the kept vertices and renumber their neighbours.
  int kept = 0;
  for (int i = 0; i < n_; ++i) {
    if (index[static_cast<std::size_t>(i)]) continue;
    v_[static_cast<std::size_t>(kept)] = v_[static_cast<std::size_t>(i)];
    index[static_cast<std::size_t>(i)] = static_cast<std::int16_t>(kept++);
  }
  n_ = kept;
  for (int i = 0; i < n_; ++i)
    for (auto& nb : v_[static_cast<std::size_t>(i)].nbr) nb = index[static_cast<std::size_t>(nb)];
  return true;
}

bool ConvexPolytope::clip_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  for (int d = 0; d < 3 && n_ > 0; ++d) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(d);
    if (!clip(e, hi[d]) || !clip(-e, -lo[d])) return false;
  }
  return true;
}

bool ConvexPolytope::clip_halfspaces(std::span<const Eigen::Vector4d> planes) {
  for (const Eigen::Vector4d& p : planes) {
    if (n_ == 0) break;
    if (!clip(p.head<3>(), p[3])) return false;
  }
  return true;
}

Eigen::AlignedBox3d ConvexPolytope::bounds() const {
  Eigen::AlignedBox3d b;
  for (int i = 0; i < n_; ++i) b.extend(v_[static_cast<std::size_t>(i)].pos);
  return b;
}

VolumeMoments ConvexPolytope::moments() const {
  VolumeMoments m;
  if (n_ < 4) return m;
  const Eigen::Vector3d o = v_[0].pos;
  double six_volume = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  for_each_tetrahedron([&](const Eigen::Vector3d&, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                           const Eigen::Vector3d& c) {
    const Eigen::Vector3d pa = a - o, pb = b - o, pc = c - o;
    const double six = pa.dot(pb.cross(pc));
    six_volume += six;
    first += six * (pa + pb + pc);
  });
  m.volume = std::max(six_volume / 6.0, 0.0);
  // Tetrahedron (0, a, b, c): integral of x is V (a + b + c) / 4.
  m.first = m.volume > 0 ? Eigen::Vector3d(first / 24.0 + m.volume * o) : Eigen::Vector3d(Eigen::Vector3d::Zero());
  return m;
}

double tetrahedron_box_overlap(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& d, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d tlo = a.cwiseMin(b).cwiseMin(c.cwiseMin(d)), thi = a.cwiseMax(b).cwiseMax(c.cwiseMax(d));
  if ((tlo.cwiseMax(lo).array() >= thi.cwiseMin(hi).array()).any()) return 0;
  const double six = (b - a).dot((c - a).cross(d - a));
  if (six == 0) return 0;
  const double sign = six > 0 ? 1.0 : -1.0;
  // A tetrahedron inside the box is itself.
  if ((tlo.array() >= lo.array()).all() && (thi.array() <= hi.array()).all()) return six / 6.0;
  ConvexPolytope p = ConvexPolytope::tetrahedron(a, b, c, d);
  // Only the box faces the tetrahedron crosses.
  for (int k = 0; k < 3 && !p.empty(); ++k) {
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k);
    if (thi[k] > hi[k]) p.clip(e, hi[k]);
    if (tlo[k] < lo[k]) p.clip(-e, -lo[k]);
  }
  return sign * p.volume();
}

double tetrahedron_halfspaces_overlap(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                      const Eigen::Vector3d& d, std::span<const Eigen::Vector4d> planes) {
  const double six = (b - a).dot((c - a).cross(d - a));
  if (six == 0) return 0;
  ConvexPolytope p = ConvexPolytope::tetrahedron(a, b, c, d);
  p.clip_halfspaces(planes);
  return (six > 0 ? 1.0 : -1.0) * p.volume();
}

double box_polyhedron_overlap(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, TetrahedraView tets) {
  double v = 0;
  for (std::size_t t = 0; t + 3 < tets.size(); t += 4) v += tetrahedron_box_overlap(tets[t], tets[t + 1], tets[t + 2], tets[t + 3], lo, hi);
  return v;
}

double box_polyhedron_overlap(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                              std::span<const Eigen::Vector3d> vertices, std::span<const std::int32_t> face_offsets,
                              std::span<const std::int32_t> face_vertices) {
  double v = 0;
  for_each_face_tetrahedron(vertices, face_offsets, face_vertices,
                            [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                const Eigen::Vector3d& d) { v += tetrahedron_box_overlap(a, b, c, d, lo, hi); });
  return v;
}

}  // namespace vfe::kernels
