// The cost model of method=auto (engine/src/methods/hybrid.hpp): times pmm's and exact's
// drivers sphere by sphere on each mesh kind and fits each path's time per particle to its
// work (sub-elements, cells, face points) by least squares. Prints the fitted constants in
// the order of GridCosts / PolyCosts, for hybrid.cpp, and how well the model ranks the two
// paths (the share of spheres it sends the cheaper way, and the time that choice costs
// against the faster path per sphere). One thread; a benchmark of engine internals.
//   build/release/vfe_bench_auto_costs [particles per scene]

#include "engine_mesh.hpp"
#include "methods/hybrid.hpp"
#include "particle_grid.hpp"
#include "polymesh/polymesh.hpp"

#include <vfe/kernels/divided.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#ifndef VFE_SOURCE_DIR
#error "VFE_SOURCE_DIR must be defined (the project's source folder)"
#endif

namespace {

using namespace vfe;
using namespace vfe::detail;

constexpr double kRadius = 0.0005;  // spheres of 1 mm, the study's beds
const std::int64_t kGrids[] = {35, 300, 2000, 8000};

/// Nanoseconds of one call of f: the least of a few rounds of a few calls.
double time_ns(const std::function<void()>& f) {
  double best = 1e300;
  for (int round = 0; round < 3; ++round) {
    constexpr int kCalls = 3;
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < kCalls; ++i) f();
    best = std::min(best, std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() / kCalls);
  }
  return best;
}

/// One sphere's times and work for one template size.
struct Sample {
  PathCosts work;
  double pmm_ns, exact_ns;
};

/// Least squares time = features . x in relative terms (each row over its time, so small
/// spheres weigh as much as large ones) with x >= 0 (a column whose coefficient comes out
/// negative, a work measure that others already explain, is dropped and the rest refitted);
/// prints x and the relative residual.
Eigen::VectorXd fit(const char* what, const std::vector<std::vector<double>>& rows, const std::vector<double>& times) {
  const auto n = static_cast<Eigen::Index>(rows.size()), k = static_cast<Eigen::Index>(rows.front().size());
  Eigen::MatrixXd a(n, k);
  Eigen::VectorXd b(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < k; ++j) a(i, j) = rows[i][j] / times[i];
    b[i] = 1.0;
  }
  std::vector<bool> kept(static_cast<std::size_t>(k), true);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(k);
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<Eigen::Index> cols;
    for (Eigen::Index j = 0; j < k; ++j)
      if (kept[static_cast<std::size_t>(j)]) cols.push_back(j);
    Eigen::MatrixXd sub(n, static_cast<Eigen::Index>(cols.size()));
    for (std::size_t j = 0; j < cols.size(); ++j) sub.col(static_cast<Eigen::Index>(j)) = a.col(cols[j]);
    const Eigen::VectorXd y = sub.colPivHouseholderQr().solve(b);
    x.setZero();
    for (std::size_t j = 0; j < cols.size(); ++j) x[cols[j]] = y[static_cast<Eigen::Index>(j)];
    Eigen::Index worst = -1;
    for (const Eigen::Index j : cols)
      if (x[j] < 0 && (worst < 0 || x[j] < x[worst])) worst = j;
    if (worst >= 0) {
      kept[static_cast<std::size_t>(worst)] = false;
      changed = true;
    }
  }
  std::printf("  %-50s", what);
  for (Eigen::Index j = 0; j < k; ++j) std::printf(" %8.3g", x[j]);
  std::printf("   (%lld spheres, rms relative residual %.0f %%)\n", static_cast<long long>(n),
              100 * std::sqrt((a * x - b).squaredNorm() / double(n)));
  return x;
}

/// How the constants now in hybrid.cpp rank the paths on these samples.
void report_choice(const std::vector<Sample>& samples) {
  std::int64_t right = 0, taken = 0;
  double chosen = 0, best = 0;
  for (const Sample& s : samples) {
    if (s.work.fast) continue;
    ++taken;
    const bool pmm = s.work.pmm < s.work.exact;
    right += pmm == (s.pmm_ns < s.exact_ns);
    chosen += pmm ? s.pmm_ns : s.exact_ns;
    best += std::min(s.pmm_ns, s.exact_ns);
  }
  if (taken)
    std::printf("  the constants in hybrid.cpp send %.0f %% of %lld spheres the cheaper way; their time is %.2f x the "
                "cheaper path's\n",
                100.0 * double(right) / double(taken), static_cast<long long>(taken), chosen / best);
}

std::vector<Eigen::Vector3d> centres_in(const Eigen::AlignedBox3d& box, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Eigen::Vector3d> c;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d x;
    for (int d = 0; d < 3; ++d)
      x[d] = std::uniform_real_distribution<double>(box.min()[d] + kRadius, box.max()[d] - kRadius)(rng);
    c.push_back(x);
  }
  return c;
}

/// Samples of every sphere at every template size on one mesh; `driver_pmm` and
/// `driver_exact` compute one sphere, `work` gives the model's view of it.
template <class MeshContext>
void sample_mesh(const EngineMesh& mesh, const std::function<MeshContext(const MethodContext&)>& make,
                 void (*pmm)(const MeshContext&, Scratch&, const Particle&),
                 void (*exact)(const MeshContext&, Scratch&, const Particle&),
                 const std::function<PathCosts(const MeshContext&, Scratch&, const Particle&)>& work,
                 const std::vector<Eigen::Vector3d>& centres, std::vector<Sample>& out) {
  TemplateCache cache;
  const kernels::ParticleTemplate divided = kernels::make_divided_template();
  Options opts;
  Scratch s;
  for (const std::int64_t n : kGrids) {
    const kernels::ParticleTemplate* t = &cache.get(opts, n);
    TemplateBank bank;
    bank.templates = std::span<const kernels::ParticleTemplate* const>(&t, 1);
    bank.fixed = true;
    const MeshContext ctx = make(MethodContext{opts, bank, divided});
    for (std::size_t i = 0; i < centres.size(); ++i) {
      Particle p{static_cast<std::int64_t>(i), centres[i], kRadius, 4.0 / 3.0 * std::numbers::pi * kRadius * kRadius * kRadius,
                 nullptr, static_cast<std::uint64_t>(i)};
      Sample smp{work(ctx, s, p), 0, 0};
      if (smp.work.fast || smp.work.pmm == 0) continue;
      smp.pmm_ns = time_ns([&] { s.deposits.clear(); pmm(ctx, s, p); });
      smp.exact_ns = time_ns([&] { s.deposits.clear(); exact(ctx, s, p); });
      out.push_back(smp);
    }
  }
  (void)mesh;
}

void grid_fit(const char* name, const std::vector<Sample>& samples) {
  std::printf("%s: GridCosts {pmm_particle, pmm_point, pmm_counted, exact_particle, exact_cell} in ns\n", name);
  std::vector<std::vector<double>> rows;
  std::vector<double> t;
  for (const Sample& s : samples) {
    rows.push_back({1.0, s.work.counted ? 0.0 : double(s.work.pmm_points), s.work.counted ? double(s.work.pmm_points) : 0.0});
    t.push_back(s.pmm_ns);
  }
  // A kind without counted spheres (the rectilinear grid) has a zero column: drop it.
  const bool any_counted = std::any_of(samples.begin(), samples.end(), [](const Sample& s) { return s.work.counted; });
  if (!any_counted)
    for (auto& r : rows) r.pop_back();
  fit(any_counted ? "pmm: particle, point, counted point" : "pmm: particle, point", rows, t);
  rows.clear();
  t.clear();
  for (const Sample& s : samples) {
    rows.push_back({1.0, double(s.work.exact_cells)});
    t.push_back(s.exact_ns);
  }
  fit("exact: particle, cell", rows, t);
  report_choice(samples);
}

}  // namespace

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::max(10, std::atoi(argv[1])) : 400;
  const std::string data = std::string(VFE_SOURCE_DIR) + "/data/openfoam/";

  std::vector<Sample> grid_samples;
  for (const double h : {0.0004, 0.00075, 0.001, 0.002}) {  // chi = 0.4 to 2
    const std::int64_t cells = static_cast<std::int64_t>(std::ceil(0.012 / h));
    EngineMesh mesh(CartesianGridSpec{{0, 0, 0}, {h, h, h}, {cells, cells, cells}});
    sample_mesh<Context>(
        mesh, [&](const MethodContext& m) { return Context{m, *mesh.cartesian()}; }, grid_pmm, exact_particle,
        [](const Context& c, Scratch& s, const Particle& p) { return path_costs(c, s, p); }, centres_in(mesh.bounds(), n, 1),
        grid_samples);
  }
  grid_fit("cartesian", grid_samples);

  std::vector<Sample> graded_samples;
  for (const double h : {0.0004, 0.001}) {  // graded 1:4 along every axis
    std::array<std::vector<double>, 3> nodes;
    for (auto& x : nodes) {
      x = {0};
      for (double dx = h; x.back() < 0.012; dx *= 1.04) x.push_back(x.back() + dx);
    }
    EngineMesh mesh{RectilinearGrid(nodes)};
    sample_mesh<RectilinearContext>(
        mesh, [&](const MethodContext& m) { return RectilinearContext{m, *mesh.rectilinear()}; }, rectilinear_pmm,
        rectilinear_exact, [](const RectilinearContext& c, Scratch& s, const Particle& p) { return path_costs(c, s, p); },
        centres_in(mesh.bounds(), n, 2), graded_samples);
  }
  grid_fit("rectilinear", graded_samples);

  std::vector<Sample> poly_samples;
  for (const char* name : {"snappy_obstacle", "cylinder_ogrid_coarse"}) {
    EngineMesh mesh(std::make_unique<PolyMesh>(PolyMesh::read(data + name)));
    std::vector<Eigen::Vector3d> centres;
    for (const Eigen::Vector3d& c : centres_in(mesh.bounds(), 4 * n, 3))
      if (mesh.locator()->locate(c) >= 0 && centres.size() < static_cast<std::size_t>(n)) centres.push_back(c);
    sample_mesh<PolyContext>(
        mesh, [&](const MethodContext& m) { return PolyContext{m, mesh.locator()}; }, polymesh_pmm, polymesh_exact,
        [](const PolyContext& c, Scratch& s, const Particle& p) { return path_costs(c, s, p, true); }, centres,
        poly_samples);
  }
  std::printf("polyhedral: PolyCosts {pmm_particle, pmm_point, pmm_candidate, exact_particle, exact_candidate, "
              "exact_box_cell, exact_face_point} in ns\n");
  std::vector<std::vector<double>> rows;
  std::vector<double> t;
  for (const Sample& s : poly_samples) {
    rows.push_back({1.0, double(s.work.pmm_points), double(s.work.exact_cells)});
    t.push_back(s.pmm_ns);
  }
  fit("pmm: particle, point, candidate", rows, t);
  rows.clear();
  t.clear();
  for (const Sample& s : poly_samples) {
    rows.push_back({1.0, double(s.work.exact_cells), double(s.work.box_cells), double(s.work.face_points)});
    t.push_back(s.exact_ns);
  }
  fit("exact: particle, candidate, box cell, face point", rows, t);
  report_choice(poly_samples);
  return 0;
}
