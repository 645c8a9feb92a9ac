#include <vfe/kernels/shape.hpp>

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <numeric>
#include <random>
#include <sstream>
#include <stdexcept>

namespace vfe::kernels {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2 * std::numbers::pi;

double beta(double x, double y) { return std::exp(std::lgamma(x) + std::lgamma(y) - std::lgamma(x + y)); }

/// Most slices (integrand evaluations) a clump's volume integration may take.
constexpr std::int64_t kClumpIntegrandBudget = std::int64_t(1) << 20;

/// Second moment of the sampled body about `centre`, scaled to `volume`.
Eigen::Matrix3d sampled_second_moment(const SampledBody& s, const Eigen::Vector3d& centre, double volume) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  for (const auto& p : s.points) m += (p - centre) * (p - centre).transpose();
  return s.points.empty() ? m : m * (volume / double(s.points.size()));
}

/// Adaptive Simpson on a vector-valued integrand, to an absolute tolerance, within a
/// budget of integrand evaluations shared by every call on one shape (the depth limit
/// alone would allow 2^40): an integrand too noisy to meet the tolerance is refused, not
/// integrated for hours.
using Vec4 = Eigen::Vector4d;
void spend_slices(std::int64_t& budget, int evaluations) {
  if ((budget -= evaluations) < 0)
    throw std::invalid_argument("the clump's volume integration did not converge within " +
                                std::to_string(kClumpIntegrandBudget) +
                                " slices; its spheres may lie too far apart for their sizes");
}
Vec4 simpson(const std::function<Vec4(double)>& f, double a, double b, const Vec4& fa, const Vec4& fm, const Vec4& fb,
             const Vec4& whole, double tol, int depth, std::int64_t& budget) {
  spend_slices(budget, 2);
  const double m = 0.5 * (a + b), lm = 0.5 * (a + m), rm = 0.5 * (m + b);
  const Vec4 flm = f(lm), frm = f(rm);
  const Vec4 left = (m - a) / 6 * (fa + 4 * flm + fm), right = (b - m) / 6 * (fm + 4 * frm + fb);
  const Vec4 delta = left + right - whole;
  if (depth <= 0 || delta.cwiseAbs().maxCoeff() <= 15 * tol) return left + right + delta / 15;
  return simpson(f, a, m, fa, flm, fm, left, tol / 2, depth - 1, budget) +
         simpson(f, m, b, fm, frm, fb, right, tol / 2, depth - 1, budget);
}

Vec4 integrate(const std::function<Vec4(double)>& f, double a, double b, double tol, std::int64_t& budget) {
  spend_slices(budget, 3);
  const Vec4 fa = f(a), fb = f(b), fm = f(0.5 * (a + b));
  return simpson(f, a, b, fa, fm, fb, (b - a) / 6 * (fa + 4 * fm + fb), tol, 40, budget);
}

/// Bounding box of the vertices the triangles use (a stray unused vertex would otherwise
/// stretch the box, and with it the sampling cost, without bound).
Eigen::AlignedBox3d used_vertex_bounds(const TriangleMesh& mesh) {
  Eigen::AlignedBox3d box;
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) box.extend(mesh.vertices[static_cast<std::size_t>(t[k])]);
  return box;
}

void merge_intervals(std::vector<std::pair<double, double>>& v);

/// The indices 0 .. n-1 as a range (every part of a shape).
struct AllParts {
  std::size_t n;
  struct Iterator {
    std::size_t i;
    std::size_t operator*() const { return i; }
    Iterator& operator++() {
      ++i;
      return *this;
    }
    bool operator!=(const Iterator& o) const { return i != o.i; }
  };
  Iterator begin() const { return {0}; }
  Iterator end() const { return {n}; }
};

/// Column intervals of a clump from the spheres `parts` (indices into spheres).
template <class Parts>
void clump_column(const std::vector<Eigen::Vector4d>& spheres, const Parts& parts, double x, double y,
                  std::vector<std::pair<double, double>>& out) {
  out.clear();
  for (const auto i : parts) {
    const Eigen::Vector4d& q = spheres[static_cast<std::size_t>(i)];
    const double h2 = q[3] * q[3] - (x - q[0]) * (x - q[0]) - (y - q[1]) * (y - q[1]);
    if (h2 > 0) out.emplace_back(q[2] - std::sqrt(h2), q[2] + std::sqrt(h2));
  }
  merge_intervals(out);
}

/// Column intervals of a mesh from the triangles `parts`: the crossings of the vertical
/// line with them, paired in order (a closed surface is crossed an even number of times).
/// `parts` must hold every triangle whose xy box holds (x, y).
template <class Parts>
void mesh_column(const TriangleMesh& mesh, const Parts& parts, double x, double y,
                 std::vector<std::pair<double, double>>& out, std::vector<double>& z) {
  out.clear();
  z.clear();
  for (const auto ti : parts) {
    const Eigen::Vector3i& t = mesh.triangles[static_cast<std::size_t>(ti)];
    const Eigen::Vector3d &a = mesh.vertices[t[0]], &b = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
    const double w0 = (b[0] - x) * (c[1] - y) - (c[0] - x) * (b[1] - y);
    const double w1 = (c[0] - x) * (a[1] - y) - (a[0] - x) * (c[1] - y);
    const double w2 = (a[0] - x) * (b[1] - y) - (b[0] - x) * (a[1] - y);
    const double sum = w0 + w1 + w2;
    if (sum == 0) continue;  // vertical triangle
    // Half-open rule so a line through a shared edge counts once.
    const bool pos = (w0 > 0 || (w0 == 0 && sum > 0)) && (w1 > 0 || (w1 == 0 && sum > 0)) &&
                     (w2 > 0 || (w2 == 0 && sum > 0));
    const bool neg = (w0 < 0 || (w0 == 0 && sum < 0)) && (w1 < 0 || (w1 == 0 && sum < 0)) &&
                     (w2 < 0 || (w2 == 0 && sum < 0));
    if (!pos && !neg) continue;
    z.push_back((w0 * a[2] + w1 * b[2] + w2 * c[2]) / sum);
  }
  std::sort(z.begin(), z.end());
  for (std::size_t i = 0; i + 1 < z.size(); i += 2) out.emplace_back(z[i], z[i + 1]);
}

void merge_intervals(std::vector<std::pair<double, double>>& v) {
  std::sort(v.begin(), v.end());
  std::size_t w = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (w > 0 && v[i].first <= v[w - 1].second)
      v[w - 1].second = std::max(v[w - 1].second, v[i].second);
    else
      v[w++] = v[i];
  }
  v.resize(w);
}

/// The z-intervals where the vertical line through (x, y) lies inside the closed mesh.
void mesh_column(const TriangleMesh& mesh, double x, double y, std::vector<std::pair<double, double>>& out) {
  std::vector<double> z;
  mesh_column(mesh, AllParts{mesh.triangles.size()}, x, y, out, z);
}

}  // namespace

std::string check_closed_mesh(const TriangleMesh& mesh) {
  std::ostringstream msg;
  if (mesh.triangles.size() < 4) {
    msg << "mesh has " << mesh.triangles.size() << " triangles; a closed surface needs at least 4";
    return msg.str();
  }
  const int nv = static_cast<int>(mesh.vertices.size());
  std::map<std::pair<int, int>, int> directed;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= nv) {
        msg << "triangle " << t << " refers to vertex " << tri[k] << " but the mesh has " << nv << " vertices";
        return msg.str();
      }
    }
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0]) {
      msg << "triangle " << t << " repeats a vertex; remove degenerate triangles";
      return msg.str();
    }
    for (int k = 0; k < 3; ++k)
      if (++directed[{tri[k], tri[(k + 1) % 3]}] > 1) {
        msg << "edge " << tri[k] << "-" << tri[(k + 1) % 3]
            << " is used twice in the same direction (triangle " << t
            << "): the triangles are not consistently oriented or the surface is not manifold";
        return msg.str();
      }
  }
  for (const auto& [edge, count] : directed)
    if (!directed.count({edge.second, edge.first})) {
      msg << "edge " << edge.first << "-" << edge.second
          << " belongs to one triangle only: the surface is open (has a hole); close it";
      return msg.str();
    }
  for (const auto& v : mesh.vertices)
    if (!v.allFinite()) return "a vertex coordinate is not finite";
  if (!(mesh_mass_properties(mesh).volume > 0))
    return "the enclosed volume is not positive: the triangles' normals point inward; reverse their vertex order";
  return "";
}

MassProperties mesh_mass_properties(const TriangleMesh& mesh) {
  // Signed tetrahedra from a reference point inside the bounding box (less round-off).
  const Eigen::AlignedBox3d box = used_vertex_bounds(mesh);
  const Eigen::Vector3d o = box.isEmpty() ? Eigen::Vector3d(Eigen::Vector3d::Zero()) : Eigen::Vector3d(box.center());
  double vol = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]] - o, b = mesh.vertices[t[1]] - o, c = mesh.vertices[t[2]] - o;
    const double v = a.dot(b.cross(c)) / 6.0;
    const Eigen::Vector3d s = a + b + c;
    vol += v;
    first += v * s / 4.0;
    // Tetrahedron (0, a, b, c): integral of x x^T = V/20 (sum p p^T + (sum p)(sum p)^T).
    second += v / 20.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
  MassProperties m;
  m.volume = vol;
  if (vol != 0) {
    const Eigen::Vector3d c = first / vol;
    m.centroid = c + o;
    m.second_moment = second - vol * c * c.transpose();
  }
  return m;
}

DiskUnion disk_union(const std::vector<Eigen::Vector3d>& disks) {
  DiskUnion u;
  // Each group of overlapping disks is integrated about its first disk's centre: Green's
  // terms about a far origin are large and cancel, and their round-off (a unit disk 1e90
  // from the origin has none of its area left) would keep the adaptive rule from ever
  // meeting its tolerance. A group's boundary is closed, so its area needs no common origin
  // with the other groups.
  std::vector<std::size_t> group(disks.size());
  for (std::size_t i = 0; i < disks.size(); ++i) group[i] = i;
  auto root = [&](std::size_t i) {
    while (group[i] != i) i = group[i] = group[group[i]];
    return i;
  };
  for (std::size_t i = 0; i < disks.size(); ++i)
    for (std::size_t j = i + 1; j < disks.size(); ++j)
      if (std::hypot(disks[j][0] - disks[i][0], disks[j][1] - disks[i][1]) < disks[i][2] + disks[j][2])
        group[root(j)] = root(i);
  std::vector<std::pair<double, double>> covered;
  for (std::size_t i = 0; i < disks.size(); ++i) {
    const std::size_t origin = root(i);
    const double ox = disks[origin][0], oy = disks[origin][1];
    const double cx = disks[i][0], cy = disks[i][1], r = disks[i][2];
    if (!(r > 0)) continue;
    covered.clear();
    bool hidden = false;
    for (std::size_t j = 0; j < disks.size() && !hidden; ++j) {
      if (j == i || !(disks[j][2] > 0)) continue;
      const double dx = disks[j][0] - cx, dy = disks[j][1] - cy, rj = disks[j][2];
      const double d = std::hypot(dx, dy);
      // Inside another disk (an identical disk hides only the later copy).
      if (d + r < rj || (d + r == rj && (r < rj || j < i))) {
        hidden = true;
        break;
      }
      if (d >= r + rj || d + rj <= r) continue;
      const double alpha = std::atan2(dy, dx);
      const double beta = std::acos(std::clamp((r * r + d * d - rj * rj) / (2 * r * d), -1.0, 1.0));
      double lo = alpha - beta, hi = alpha + beta;
      lo -= kTwoPi * std::floor(lo / kTwoPi);
      hi = lo + 2 * beta;
      if (hi > kTwoPi) {
        covered.emplace_back(lo, kTwoPi);
        covered.emplace_back(0.0, hi - kTwoPi);
      } else {
        covered.emplace_back(lo, hi);
      }
    }
    if (hidden) continue;
    merge_intervals(covered);
    // Exposed arcs: Green's theorem, area = 1/2 closed integral of (x dy - y dx),
    // integral of x dA = closed integral of x^2/2 dy, integral of y dA = -closed integral of y^2/2 dx.
    const double lx = cx - ox, ly = cy - oy;  // the centre about the group's origin
    DiskUnion local;
    auto arc = [&](double t0, double t1) {
      const double s0 = std::sin(t0), s1 = std::sin(t1), c0 = std::cos(t0), c1 = std::cos(t1);
      local.area += 0.5 * (r * lx * (s1 - s0) - r * ly * (c1 - c0) + r * r * (t1 - t0));
      const double icos = s1 - s0;
      const double icos2 = 0.5 * (t1 - t0) + 0.25 * (std::sin(2 * t1) - std::sin(2 * t0));
      const double icos3 = (s1 - s1 * s1 * s1 / 3) - (s0 - s0 * s0 * s0 / 3);
      local.moment_x += 0.5 * r * (lx * lx * icos + 2 * lx * r * icos2 + r * r * icos3);
      const double isin = -(c1 - c0);
      const double isin2 = 0.5 * (t1 - t0) - 0.25 * (std::sin(2 * t1) - std::sin(2 * t0));
      const double isin3 = (-c1 + c1 * c1 * c1 / 3) - (-c0 + c0 * c0 * c0 / 3);
      local.moment_y += 0.5 * r * (ly * ly * isin + 2 * ly * r * isin2 + r * r * isin3);
    };
    double t = 0;
    for (const auto& [lo, hi] : covered) {
      if (lo > t) arc(t, lo);
      t = std::max(t, hi);
    }
    if (t < kTwoPi) arc(t, kTwoPi);
    u.area += local.area;
    u.moment_x += local.moment_x + ox * local.area;
    u.moment_y += local.moment_y + oy * local.area;
  }
  return u;
}

Shape Shape::sphere() {
  Shape s;
  s.kind_ = Kind::sphere;
  s.props_.volume = 4.0 / 3.0 * kPi;
  s.props_.second_moment = Eigen::Matrix3d::Identity() * (s.props_.volume / 5.0);
  s.bounds_ = Eigen::AlignedBox3d(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1));
  return s;
}

Shape Shape::ellipsoid(double a, double b, double c) {
  if (!(a > 0 && b > 0 && c > 0) || !std::isfinite(a * b * c))
    throw std::invalid_argument("ellipsoid semi-axes must be finite and > 0");
  Shape s;
  s.kind_ = Kind::ellipsoid;
  s.axes_ = Eigen::Vector3d(a, b, c);
  s.props_.volume = 4.0 / 3.0 * kPi * a * b * c;
  s.props_.second_moment = (s.axes_.cwiseProduct(s.axes_) * (s.props_.volume / 5.0)).asDiagonal();
  s.bounds_ = Eigen::AlignedBox3d(-s.axes_, s.axes_);
  return s;
}

Shape Shape::superquadric(double a, double b, double c, double e1, double e2) {
  if (!(a > 0 && b > 0 && c > 0) || !std::isfinite(a * b * c))
    throw std::invalid_argument("superquadric semi-axes must be finite and > 0");
  if (!(e1 >= 0.1 && e1 <= 2 && e2 >= 0.1 && e2 <= 2))
    throw std::invalid_argument("superquadric exponents e1, e2 must lie in [0.1, 2]");
  Shape s;
  s.kind_ = Kind::superquadric;
  s.axes_ = Eigen::Vector3d(a, b, c);
  s.e1_ = e1;
  s.e2_ = e2;
  // Jaklic et al. (2000): V = 2 a b c e1 e2 B(e1/2 + 1, e1) B(e2/2, e2/2).
  s.props_.volume = 2 * a * b * c * e1 * e2 * beta(e1 / 2 + 1, e1) * beta(e2 / 2, e2 / 2);
  s.bounds_ = Eigen::AlignedBox3d(-s.axes_, s.axes_);
  check_sampling_cost(s, kMaxShapeSamples);
  s.props_.second_moment = sampled_second_moment(sample_shape(s, 400000), Eigen::Vector3d::Zero(), s.props_.volume);
  return s;
}

Shape Shape::clump(std::vector<Eigen::Vector4d> spheres) {
  if (spheres.empty()) throw std::invalid_argument("a clump needs at least one sphere");
  Shape s;
  s.kind_ = Kind::clump;
  for (const auto& q : spheres) {
    if (!q.allFinite() || !(q[3] > 0)) throw std::invalid_argument("clump spheres need finite x y z and r > 0");
    s.bounds_.extend(Eigen::Vector3d(q[0] - q[3], q[1] - q[3], q[2] - q[3]));
    s.bounds_.extend(Eigen::Vector3d(q[0] + q[3], q[1] + q[3], q[2] + q[3]));
  }
  s.spheres_ = std::move(spheres);
  // Exact slice areas and moments (union of disks) integrated over z between the
  // spheres' poles and centres, where the slice topology changes.
  // Integrated in units of the largest radius about the bounding box's centre c0, with the
  // moments divided by `spread` (1 unless the spheres lie more than 1000 radii apart): the
  // moments' round-off then stays within the tolerance whatever the clump's size and unit,
  // which otherwise drove the adaptive rule to its full depth (minutes for two spheres 1e15
  // apart, or for spheres of radius 1e4: their moments carry one more length than the
  // volume the tolerance was scaled to).
  const Eigen::Vector3d c0 = s.bounds_.center();
  double scale = 0;
  for (const auto& q : s.spheres_) scale = std::max(scale, q[3]);
  const double spread = std::max(1.0, s.bounds_.sizes().maxCoeff() / (1000 * scale));
  std::vector<Eigen::Vector4d> unit;  // x y z r about c0, in units of scale
  unit.reserve(s.spheres_.size());
  for (const auto& q : s.spheres_)
    unit.emplace_back((q[0] - c0[0]) / scale, (q[1] - c0[1]) / scale, (q[2] - c0[2]) / scale, q[3] / scale);
  std::vector<double> breaks;
  for (const auto& q : unit) breaks.insert(breaks.end(), {q[2] - q[3], q[2], q[2] + q[3]});
  std::sort(breaks.begin(), breaks.end());
  breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());
  std::vector<Eigen::Vector3d> disks;
  auto slice = [&](double z) {
    disks.clear();
    for (const auto& q : unit) {
      const double dz = z - q[2];
      const double h2 = q[3] * q[3] - dz * dz;
      if (h2 > 0) disks.emplace_back(q[0], q[1], std::sqrt(h2));
    }
    const DiskUnion u = disk_union(disks);
    return Vec4(u.area, u.moment_x / spread, u.moment_y / spread, z * u.area / spread);
  };
  Vec4 total = Vec4::Zero();
  std::int64_t budget = kClumpIntegrandBudget;
  for (std::size_t i = 0; i + 1 < breaks.size(); ++i) total += integrate(slice, breaks[i], breaks[i + 1], 1e-13, budget);
  s.props_.volume = total[0] * scale * scale * scale;
  s.props_.centroid = c0 + Eigen::Vector3d(total[1], total[2], total[3]) * (spread * scale / total[0]);
  check_sampling_cost(s, kMaxShapeSamples);
  s.props_.second_moment = sampled_second_moment(sample_shape(s, 400000), s.props_.centroid, s.props_.volume);
  return s;
}

Shape Shape::mesh(TriangleMesh mesh) {
  if (mesh.triangles.size() > kMaxMeshTriangles)
    throw std::invalid_argument("mesh has " + std::to_string(mesh.triangles.size()) + " triangles, more than the limit of " +
                                std::to_string(kMaxMeshTriangles) + " a shape may have; simplify the surface");
  if (const std::string problem = check_closed_mesh(mesh); !problem.empty()) throw std::invalid_argument(problem);
  Shape s;
  s.kind_ = Kind::mesh;
  s.bounds_ = used_vertex_bounds(mesh);
  s.props_ = mesh_mass_properties(mesh);
  s.mesh_ = std::move(mesh);
  check_sampling_cost(s, kMaxShapeSamples);  // refuse now what the first compute could not sample
  return s;
}

std::string Shape::description() const {
  std::ostringstream o;
  switch (kind_) {
    case Kind::sphere: o << "sphere"; break;
    case Kind::ellipsoid: o << "ellipsoid " << axes_.transpose(); break;
    case Kind::superquadric: o << "superquadric " << axes_.transpose() << " " << e1_ << " " << e2_; break;
    case Kind::clump: o << "clump of " << spheres_.size() << " spheres"; break;
    case Kind::mesh: o << "mesh of " << mesh_.triangles.size() << " triangles"; break;
  }
  return o.str();
}

void Shape::column(double x, double y, std::vector<std::pair<double, double>>& out) const {
  out.clear();
  switch (kind_) {
    case Kind::sphere:
    case Kind::ellipsoid: {
      const double g = (x / axes_[0]) * (x / axes_[0]) + (y / axes_[1]) * (y / axes_[1]);
      if (g < 1) {
        const double h = axes_[2] * std::sqrt(1 - g);
        out.emplace_back(-h, h);
      }
      break;
    }
    case Kind::superquadric: {
      const double g = std::pow(std::pow(std::abs(x / axes_[0]), 2 / e2_) + std::pow(std::abs(y / axes_[1]), 2 / e2_),
                                e2_ / e1_);
      if (g < 1) {
        const double h = axes_[2] * std::pow(1 - g, e1_ / 2);
        out.emplace_back(-h, h);
      }
      break;
    }
    case Kind::clump:
      clump_column(spheres_, AllParts{spheres_.size()}, x, y, out);
      break;
    case Kind::mesh: {
      mesh_column(mesh_, x, y, out);
      break;
    }
  }
}

bool Shape::contains(const Eigen::Vector3d& p) const {
  std::vector<std::pair<double, double>> col;
  column(p[0], p[1], col);
  for (const auto& [lo, hi] : col)
    if (p[2] >= lo && p[2] <= hi) return true;
  return false;
}

namespace {

/// sample_shape's grid: columns at x = lo0 + (i + 1/2) hx, y = lo1 + (j + 1/2) hy, i < nx,
/// j < ny, and layers of thickness h anchored at lo2.
struct SampleGrid {
  Eigen::Vector3d lo;
  double h = 0, hx = 0, hy = 0;
  std::int64_t nx = 1, ny = 1;
};

[[noreturn]] void too_costly(const Shape& shape, std::size_t target, const std::string& what) {
  const double size = shape.bounds().sizes().maxCoeff();
  std::ostringstream msg;
  msg << shape.description() << ": sampling it with " << target << " points " << what
      << "; the shape is too thin, or its parts too far apart, for its volume (largest extent / volume^(1/3) = "
      << size / std::cbrt(shape.volume())
      << "): make it more compact, drop distant parts, or register them as separate shapes";
  throw std::invalid_argument(msg.str());
}

SampleGrid sample_grid(const Shape& shape, std::size_t target) {
  SampleGrid g;
  g.lo = shape.bounds().min();
  const Eigen::Vector3d ext = shape.bounds().sizes();
  g.h = std::cbrt(shape.volume() / double(std::max<std::size_t>(target, 1)));
  const double span = ext.maxCoeff() / g.h;
  if (!(g.h > 0) || !(span <= kMaxSampleSpan)) {
    std::ostringstream what;
    what << "spans " << span << " sample spacings, more than the limit " << kMaxSampleSpan;
    too_costly(shape, target, what.str());
  }
  g.nx = std::max<std::int64_t>(1, std::int64_t(std::ceil(ext[0] / g.h)));
  g.ny = std::max<std::int64_t>(1, std::int64_t(std::ceil(ext[1] / g.h)));
  g.hx = ext[0] / double(g.nx);
  g.hy = ext[1] / double(g.ny);
  return g;
}

/// Indices [first, last] of the columns whose centres lo + (i + 1/2) step lie in [a, b],
/// within [0, n); empty when first > last.
std::pair<std::int64_t, std::int64_t> column_range(double a, double b, double lo, double step, std::int64_t n) {
  if (!(step > 0)) return {0, n - 1};  // a flat axis has one column
  // One column more on each side, so round-off in the division cannot miss a column
  // whose centre lies on the box's edge.
  const double first = std::max(0.0, std::ceil((a - lo) / step - 0.5) - 1);
  const double last = std::min(double(n - 1), std::floor((b - lo) / step - 0.5) + 1);
  if (!(first <= last)) return {1, 0};
  return {std::int64_t(first), std::int64_t(last)};
}

/// Calls f(first_i, last_i, first_j, last_j, part) for each part of a clump (its spheres)
/// or a mesh (its triangles); one of the two is empty.
template <class F>
void for_each_part_columns(const std::vector<Eigen::Vector4d>& spheres, const TriangleMesh& mesh, const SampleGrid& g,
                           F&& f) {
  const auto cover = [&](double x0, double x1, double y0, double y1, std::int64_t part) {
    const auto [i0, i1] = column_range(x0, x1, g.lo[0], g.hx, g.nx);
    const auto [j0, j1] = column_range(y0, y1, g.lo[1], g.hy, g.ny);
    if (i0 <= i1 && j0 <= j1) f(i0, i1, j0, j1, part);
  };
  for (std::size_t s = 0; s < spheres.size(); ++s) {
    const Eigen::Vector4d& q = spheres[s];
    cover(q[0] - q[3], q[0] + q[3], q[1] - q[3], q[1] + q[3], std::int64_t(s));
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d &a = mesh.vertices[tri[0]], &b = mesh.vertices[tri[1]], &c = mesh.vertices[tri[2]];
    cover(std::min({a[0], b[0], c[0]}), std::max({a[0], b[0], c[0]}), std::min({a[1], b[1], c[1]}),
          std::max({a[1], b[1], c[1]}), std::int64_t(t));
  }
}

void add_column_samples(const SampleGrid& g, double x, double y, const std::vector<std::pair<double, double>>& col,
                        SampledBody& s);

/// Samples of a clump's spheres or a mesh's triangles on grid g, walking only the columns
/// a part covers, each with only the parts that cover it: the cost is bounded by the
/// covered columns (check_sampling_cost), not by the bounding box or the parts.
void sample_by_parts(const std::vector<Eigen::Vector4d>& spheres, const TriangleMesh& mesh, const SampleGrid& g,
                     SampledBody& s) {
  struct Cover {
    std::int64_t column;
    std::int64_t part;
    bool operator<(const Cover& o) const { return column < o.column || (column == o.column && part < o.part); }
  };
  std::vector<Cover> covers;
  for_each_part_columns(spheres, mesh, g, [&](std::int64_t i0, std::int64_t i1, std::int64_t j0, std::int64_t j1, std::int64_t part) {
    for (std::int64_t j = j0; j <= j1; ++j)
      for (std::int64_t i = i0; i <= i1; ++i) covers.push_back({i + g.nx * j, part});
  });
  std::sort(covers.begin(), covers.end());  // columns in the full walk's order (j, then i)
  std::vector<std::int64_t> parts;
  std::vector<double> z;
  std::vector<std::pair<double, double>> col;
  for (std::size_t b = 0; b < covers.size();) {
    std::size_t e = b;
    parts.clear();
    while (e < covers.size() && covers[e].column == covers[b].column) parts.push_back(covers[e++].part);
    const std::int64_t i = covers[b].column % g.nx, j = covers[b].column / g.nx;
    const double x = g.lo[0] + (double(i) + 0.5) * g.hx, y = g.lo[1] + (double(j) + 0.5) * g.hy;
    if (!spheres.empty())
      clump_column(spheres, parts, x, y, col);
    else
      mesh_column(mesh, parts, x, y, col, z);
    add_column_samples(g, x, y, col, s);
    b = e;
  }
}

bool sampled_by_parts(const Shape& shape) {
  return shape.kind() == Shape::Kind::clump || shape.kind() == Shape::Kind::mesh;
}

/// Appends the samples of the column at (x, y) with intervals col.
void add_column_samples(const SampleGrid& g, double x, double y, const std::vector<std::pair<double, double>>& col,
                        SampledBody& s) {
  for (const auto& [zlo, zhi] : col) {
    // Midpoints of the z-grid anchored at the bounding box lie inside [zlo, zhi].
    const auto k0 = std::int64_t(std::ceil((zlo - g.lo[2]) / g.h - 0.5)), k1 = std::int64_t(std::floor((zhi - g.lo[2]) / g.h - 0.5));
    for (std::int64_t k = k0; k <= k1; ++k) s.points.emplace_back(x, y, g.lo[2] + (double(k) + 0.5) * g.h);
  }
}

}  // namespace

double check_sampling_cost(const Shape& shape, std::size_t target) {
  const SampleGrid g = sample_grid(shape, target);
  double columns = 0;
  if (sampled_by_parts(shape))
    for_each_part_columns(shape.spheres(), shape.mesh(), g,
                          [&](std::int64_t i0, std::int64_t i1, std::int64_t j0, std::int64_t j1, std::int64_t) {
                            columns += double(i1 - i0 + 1) * double(j1 - j0 + 1);
                          });
  else
    columns = double(g.nx) * double(g.ny);
  if (columns > kMaxSampleColumns) {
    std::ostringstream what;
    what << "walks " << columns << " columns of its sampling grid, more than the limit " << kMaxSampleColumns;
    too_costly(shape, target, what.str());
  }
  return columns;
}

SampledBody sample_shape(const Shape& shape, std::size_t target) {
  check_sampling_cost(shape, target);
  const SampleGrid g = sample_grid(shape, target);
  SampledBody s;
  s.cell_volume = g.hx * g.hy * g.h;
  s.points.reserve(target + target / 4);
  std::vector<std::pair<double, double>> col;
  const auto x_of = [&](std::int64_t i) { return g.lo[0] + (double(i) + 0.5) * g.hx; };
  const auto y_of = [&](std::int64_t j) { return g.lo[1] + (double(j) + 0.5) * g.hy; };
  if (!sampled_by_parts(shape)) {
    for (std::int64_t j = 0; j < g.ny; ++j)
      for (std::int64_t i = 0; i < g.nx; ++i) {
        shape.column(x_of(i), y_of(j), col);
        add_column_samples(g, x_of(i), y_of(j), col, s);
      }
    return s;
  }
  sample_by_parts(shape.spheres(), shape.mesh(), g, s);
  return s;
}

namespace {

/// Cuts points[b, e) into n parts of (nearly) equal count by recursive bisection along
/// the widest axis; appends each part's centroid and share.
void bisect(std::vector<Eigen::Vector3d>& pts, std::size_t b, std::size_t e, int n, double total,
            ParticleTemplate& t) {
  if (n <= 1 || e - b <= 1) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::size_t i = b; i < e; ++i) c += pts[i];
    t.points.push_back(c / double(e - b));
    t.fractions.push_back(double(e - b) / total);
    return;
  }
  Eigen::AlignedBox3d box;
  for (std::size_t i = b; i < e; ++i) box.extend(pts[i]);
  int axis = 0;
  box.sizes().maxCoeff(&axis);
  const int n1 = n / 2;
  const std::size_t mid = b + static_cast<std::size_t>(std::llround(double(e - b) * n1 / n));
  std::nth_element(pts.begin() + b, pts.begin() + mid, pts.begin() + e,
                   [axis](const Eigen::Vector3d& p, const Eigen::Vector3d& q) { return p[axis] < q[axis]; });
  bisect(pts, b, mid, n1, total, t);
  bisect(pts, mid, e, n - n1, total, t);
}

/// Moves the template's centre of volume onto the shape's exact centroid; sets its reach.
void centre_on_centroid(const Shape& shape, ParticleTemplate& t) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < t.size(); ++i) mean += t.fractions[i] * t.points[i];
  const Eigen::Vector3d shift = shape.centroid() - mean;
  t.reach = 0;
  for (auto& p : t.points) {
    p += shift;
    t.reach = std::max(t.reach, p.norm());
  }
}

/// Cuts the samples into n parts by bisection (at most a twentieth of the samples), one
/// sub-element at each part's centroid; the template's centre goes onto the exact
/// centroid. With `turn` the samples are in a turned lattice's frame (body = turn * q)
/// and every part gets exactly 1/n; without, its share of the samples.
ParticleTemplate partition_samples(const Shape& shape, std::vector<Eigen::Vector3d>& samples, int n,
                                   const Eigen::Matrix3d* turn) {
  ParticleTemplate t;
  t.family = "shape";
  if (samples.empty()) {
    t.points.push_back(shape.centroid());
    t.fractions.push_back(1.0);
  } else {
    const int parts = static_cast<int>(std::min<std::size_t>(std::size_t(n), std::max<std::size_t>(1, samples.size() / 20)));
    bisect(samples, 0, samples.size(), parts, double(samples.size()), t);
    if (turn) {
      for (auto& p : t.points) p = *turn * p;
      for (auto& f : t.fractions) f = 1.0 / double(t.size());
    }
  }
  centre_on_centroid(shape, t);
  return t;
}

}  // namespace

ParticleTemplate make_shape_template(const Shape& shape, int n) {
  n = std::max(n, 1);
  if (shape.kind() == Shape::Kind::sphere) return make_spherical_template(n);
  if (shape.kind() == Shape::Kind::ellipsoid) {
    ParticleTemplate t = make_spherical_template(n);
    t.reach = 0;
    for (auto& p : t.points) {
      p = p.cwiseProduct(shape.axes());  // an affine map keeps equal volumes and maps centroids to centroids
      t.reach = std::max(t.reach, p.norm());
    }
    t.family = "ellipsoid";
    return t;
  }
  // At least ~400 samples per sub-element, 200k to 4M in all.
  const std::size_t target = std::clamp<std::size_t>(std::size_t(400) * std::size_t(n), 200000, 4000000);
  return make_shape_template(shape, n, sample_shape(shape, target).points);
}

ParticleTemplate make_shape_template(const Shape& shape, int n, std::vector<Eigen::Vector3d> samples) {
  n = std::max(n, 1);
  if (shape.kind() == Shape::Kind::sphere || shape.kind() == Shape::Kind::ellipsoid) return make_shape_template(shape, n);
  return partition_samples(shape, samples, n, nullptr);
}

ParticleTemplate make_shape_template_variant(const Shape& shape, int n, std::uint32_t variant,
                                             std::size_t samples_per_element) {
  n = std::max(n, 1);
  if (variant == 0) return make_shape_template(shape, n);
  // Fixed per variant: a rotation of the partition about the shape's own axes, and a
  // shift of the sampling lattice by a fraction of its spacing.
  constexpr std::uint64_t kSalt = 0x5eed5a3b1e5ULL;
  const Eigen::Matrix3d turn = random_rotation(variant, kSalt);
  if (shape.kind() == Shape::Kind::sphere || shape.kind() == Shape::Kind::ellipsoid) {
    ParticleTemplate t = make_fibonacci_template(n);
    t.family = shape.kind() == Shape::Kind::sphere ? "fibonacci" : "ellipsoid";
    for (auto& p : t.points) p = (turn * p).cwiseProduct(shape.axes());
    for (auto& f : t.fractions) f = 1.0 / double(n);
    centre_on_centroid(shape, t);
    return t;
  }
  const std::size_t target = std::clamp<std::size_t>(samples_per_element * std::size_t(n), 200000, 4000000);
  std::mt19937_64 rng(variant ^ kSalt);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Vector3d shift(unit(rng), unit(rng), unit(rng));
  // Samples in the lattice's frame q (the body point is turn * q).
  Eigen::AlignedBox3d frame_box;
  for (int k = 0; k < 8; ++k)
    frame_box.extend(Eigen::Vector3d(turn.transpose() * shape.bounds().corner(static_cast<Eigen::AlignedBox3d::CornerType>(k))));
  const double h = std::cbrt(shape.volume() / double(target));
  const Eigen::Vector3d lo = frame_box.min() - h * shift;
  const Eigen::Vector3i count = ((frame_box.max() - lo) / h).array().ceil().cast<int>().max(1);
  std::vector<Eigen::Vector3d> samples;
  samples.reserve(target + target / 4);
  if (shape.kind() == Shape::Kind::mesh || shape.kind() == Shape::Kind::clump) {
    // The parts turned into the lattice's frame, sampled column by covered column.
    TriangleMesh turned = shape.mesh();
    for (auto& v : turned.vertices) v = turn.transpose() * v;
    std::vector<Eigen::Vector4d> spheres = shape.spheres();
    for (auto& q : spheres) q.head<3>() = turn.transpose() * q.head<3>();
    SampleGrid g;
    g.lo = lo;
    g.h = g.hx = g.hy = h;
    g.nx = count[0];
    g.ny = count[1];
    SampledBody body;
    body.points = std::move(samples);
    sample_by_parts(spheres, turned, g, body);
    samples = std::move(body.points);
  } else {
    for (int j = 0; j < count[1]; ++j)
      for (int i = 0; i < count[0]; ++i)
        for (int k = 0; k < count[2]; ++k) {
          const Eigen::Vector3d q(lo[0] + (i + 0.5) * h, lo[1] + (j + 0.5) * h, lo[2] + (k + 0.5) * h);
          if (shape.contains(turn * q)) samples.push_back(q);
        }
  }
  return partition_samples(shape, samples, n, &turn);
}

}  // namespace vfe::kernels
