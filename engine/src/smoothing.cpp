#include "smoothing.hpp"

#include <cmath>

namespace vfe::detail {

FaceGraph face_graph(const EngineMesh& mesh) {
  FaceGraph g;
  auto add = [&](std::int64_t a, std::int64_t b, double k) {
    g.a.push_back(a);
    g.b.push_back(b);
    g.k.push_back(k);
  };
  if (const PolyMesh* m = mesh.polyhedral()) {
    for (std::int64_t f = 0; f < m->internal_face_count(); ++f) {
      const std::int64_t o = m->owner(f), n = m->neighbour(f);
      add(o, n, m->face_area(f).norm() / (m->cell_centre(n) - m->cell_centre(o)).norm());
    }
    return g;
  }
  // Grids: the neighbours along each axis (across a periodic axis too).
  std::array<std::int64_t, 3> n{};
  std::array<std::vector<double>, 3> nodes;
  if (const CartesianGrid* c = mesh.cartesian()) {
    n = c->cells();
    for (int d = 0; d < 3; ++d)
      for (std::int64_t i = 0; i <= n[d]; ++i) nodes[d].push_back(c->node(d, i));
  } else {
    const RectilinearGrid& r = *mesh.rectilinear();
    n = r.cells();
    for (int d = 0; d < 3; ++d) nodes[d] = r.nodes(d);
  }
  auto width = [&](int d, std::int64_t i) { return nodes[d][i + 1] - nodes[d][i]; };
  auto index = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return i + n[0] * (j + n[1] * k); };
  for (std::int64_t k = 0; k < n[2]; ++k)
    for (std::int64_t j = 0; j < n[1]; ++j)
      for (std::int64_t i = 0; i < n[0]; ++i) {
        const std::int64_t g3[3] = {i, j, k};
        for (int d = 0; d < 3; ++d) {
          std::int64_t h[3] = {i, j, k};
          h[d] += 1;
          if (h[d] == n[d]) {
            if (!((mesh.periodic() >> d) & 1u) || n[d] < 2) continue;
            h[d] = 0;
          }
          const int e = (d + 1) % 3, f = (d + 2) % 3;
          const double area = width(e, g3[e]) * width(f, g3[f]);
          const double dist = 0.5 * (width(d, g3[d]) + width(d, h[d]));
          add(index(i, j, k), index(h[0], h[1], h[2]), area / dist);
        }
      }
  return g;
}

int smooth_solid(const FaceGraph& g, const EngineMesh& mesh, double length, const std::vector<double>& solid,
                 std::vector<double>& out) {
  const std::size_t n = solid.size();
  const double l2 = length * length;
  std::vector<double> volume(n), diag(n), x(n), r(n), z(n), p(n), q(n);
  for (std::size_t c = 0; c < n; ++c) diag[c] = volume[c] = mesh.cell_volume(static_cast<std::int64_t>(c));
  for (std::size_t f = 0; f < g.k.size(); ++f) {
    diag[g.a[f]] += l2 * g.k[f];
    diag[g.b[f]] += l2 * g.k[f];
  }
  auto laplacian = [&](const std::vector<double>& v, std::vector<double>& kv) {  // kv = K v
    std::fill(kv.begin(), kv.end(), 0.0);
    for (std::size_t f = 0; f < g.k.size(); ++f) {
      const double flux = g.k[f] * (v[g.a[f]] - v[g.b[f]]);
      kv[g.a[f]] += flux;
      kv[g.b[f]] -= flux;
    }
  };
  auto apply = [&](const std::vector<double>& v, std::vector<double>& mv) {  // mv = (V + L^2 K) v
    laplacian(v, mv);
    for (std::size_t c = 0; c < n; ++c) mv[c] = volume[c] * v[c] + l2 * mv[c];
  };
  double bnorm = 0;
  for (std::size_t c = 0; c < n; ++c) {
    x[c] = solid[c] / volume[c];  // the unsmoothed fraction as the first guess
    bnorm += solid[c] * solid[c];
  }
  bnorm = std::sqrt(bnorm);
  apply(x, q);
  for (std::size_t c = 0; c < n; ++c) r[c] = solid[c] - q[c];
  double rz = 0;
  for (std::size_t c = 0; c < n; ++c) {
    z[c] = r[c] / diag[c];
    p[c] = z[c];
    rz += r[c] * z[c];
  }
  int it = 0;
  for (; it < 2000 && bnorm > 0; ++it) {
    double rn = 0;
    for (std::size_t c = 0; c < n; ++c) rn += r[c] * r[c];
    if (std::sqrt(rn) <= 1e-12 * bnorm) break;
    apply(p, q);
    double pq = 0;
    for (std::size_t c = 0; c < n; ++c) pq += p[c] * q[c];
    const double alpha = rz / pq;
    double rz_next = 0;
    for (std::size_t c = 0; c < n; ++c) {
      x[c] += alpha * p[c];
      r[c] -= alpha * q[c];
      z[c] = r[c] / diag[c];
      rz_next += r[c] * z[c];
    }
    const double beta = rz_next / rz;
    rz = rz_next;
    for (std::size_t c = 0; c < n; ++c) p[c] = z[c] + beta * p[c];
  }
  laplacian(x, q);
  out.resize(n);
  for (std::size_t c = 0; c < n; ++c) out[c] = solid[c] - l2 * q[c];
  return it;
}

}  // namespace vfe::detail
