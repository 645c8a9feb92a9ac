// The cost model of method=auto (engine/src/methods/hybrid.hpp): times whole computes of
// pmm (fixed particle grids) and exact on groups of random spheres over each mesh kind, and
// fits each path's time per sphere (less direct's, the cost every method shares) to the
// group's mean work as the model sees it (sub-elements, counted or located; cells; on a
// polyMesh candidates, cut box cells and face points) by least squares in relative terms,
// every constant >= 0. Prints the constants in the order of GridCosts / PolyCosts (for
// hybrid.cpp) and each group's measured and fitted times. One thread.
//   build/release/vfe_bench_auto_costs [spheres per group]

#include "engine_mesh.hpp"
#include "methods/hybrid.hpp"
#include "particle_grid.hpp"
#include "polymesh/polymesh.hpp"

#include <vfe/engine.hpp>
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

const std::int64_t kGrids[] = {35, 300, 815, 2000};

/// One group: its mean work per sphere (the model's features) and its time per sphere.
struct Group {
  std::string what;
  std::vector<double> features;
  double ns;
};

/// Nanoseconds per sphere of a compute with these options: the least of 3 after a warm-up.
double compute_ns(Engine& e, const std::string& options, const std::vector<double>& centres, const std::vector<double>& radii) {
  e.configure(options + " threads=1");
  ParticleView v;
  v.n = static_cast<std::int64_t>(radii.size());
  v.centres = centres.data();
  v.radii = radii.data();
  std::vector<double> out(e.cell_count());
  e.compute(v, out);
  double best = 1e300;
  for (int i = 0; i < 3; ++i) {
    const auto start = std::chrono::steady_clock::now();
    e.compute(v, out);
    best = std::min(best, std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count());
  }
  return best / double(v.n);
}

/// Least squares 1 = (features / time) . x (relative terms: every group weighs alike), x >= 0:
/// a column whose coefficient comes out negative is dropped and the rest refitted.
Eigen::VectorXd fit(const char* what, const char* names, const std::vector<Group>& groups) {
  const auto n = static_cast<Eigen::Index>(groups.size()), k = static_cast<Eigen::Index>(groups.front().features.size());
  Eigen::MatrixXd a(n, k);
  for (Eigen::Index i = 0; i < n; ++i)
    for (Eigen::Index j = 0; j < k; ++j) a(i, j) = groups[i].features[j] / groups[i].ns;
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
  std::vector<bool> kept(static_cast<std::size_t>(k), true);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(k);
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<Eigen::Index> cols;
    for (Eigen::Index j = 0; j < k; ++j)
      if (kept[static_cast<std::size_t>(j)] && a.col(j).cwiseAbs().maxCoeff() > 0) cols.push_back(j);
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
  std::printf("  %s {%s}:", what, names);
  for (Eigen::Index j = 0; j < k; ++j) std::printf(" %.3g", x[j]);
  std::printf("   (%lld groups, rms relative residual %.0f %%)\n", static_cast<long long>(n),
              100 * std::sqrt((a * x - b).squaredNorm() / double(n)));
  for (Eigen::Index i = 0; i < n; ++i)
    std::printf("    %-44s measured %8.0f ns, fitted %8.0f ns\n", groups[i].what.c_str(), groups[i].ns,
                groups[i].ns * (a.row(i) * x)(0));
  return x;
}

std::vector<double> centres_in(const Eigen::AlignedBox3d& box, double r, int n, std::uint64_t seed,
                               const std::function<bool(const Eigen::Vector3d&)>& keep) {
  std::mt19937_64 rng(seed);
  std::vector<double> c;
  while (static_cast<int>(c.size()) < 3 * n) {
    Eigen::Vector3d x;
    for (int d = 0; d < 3; ++d) x[d] = std::uniform_real_distribution<double>(box.min()[d] + r, box.max()[d] - r)(rng);
    if (keep(x)) c.insert(c.end(), {x[0], x[1], x[2]});
  }
  return c;
}

/// The groups of one mesh: per radius, exact and pmm at each grid, with the model's mean
/// work per sphere (work(ctx, scratch, particle) with a bank of that grid).
template <class MeshContext>
void groups_of(const char* name, const EngineMesh& mesh, Engine& engine,
               const std::function<MeshContext(const MethodContext&)>& make,
               const std::function<PathCosts(const MeshContext&, Scratch&, const Particle&)>& work, int n,
               std::initializer_list<double> radii, std::vector<Group>& pmm, std::vector<Group>& exact, bool grid) {
  TemplateCache cache;
  const kernels::ParticleTemplate divided = kernels::make_divided_template();
  Options opts;
  Scratch s;
  for (const double r : radii) {
    const std::vector<double> centres = centres_in(mesh.bounds(), r, n, 7, [&](const Eigen::Vector3d& x) {
      return mesh.locator() ? mesh.locator()->locate(x) >= 0 : true;
    });
    const std::vector<double> rs(static_cast<std::size_t>(n), r);
    const double base = compute_ns(engine, "method=direct", centres, rs);
    bool exact_done = false;
    for (const std::int64_t g : kGrids) {
      const kernels::ParticleTemplate* t = &cache.get(opts, g);
      TemplateBank bank;
      bank.templates = std::span<const kernels::ParticleTemplate* const>(&t, 1);
      bank.fixed = true;
      const MeshContext ctx = make(MethodContext{opts, bank, divided});
      double slow = 0, located = 0, counted = 0, cells = 0, boxes = 0, points = 0, cand = 0;
      double octant_slow = 0, octant_cells = 0;  // Cartesian: the spheres exact takes by one octant call
      for (int i = 0; i < n; ++i) {
        const Particle p{i, Eigen::Vector3d(centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]), r,
                         4.0 / 3.0 * std::numbers::pi * r * r * r, nullptr, static_cast<std::uint64_t>(i)};
        const PathCosts w = work(ctx, s, p);
        if (w.fast) continue;
        slow += 1;
        (w.counted ? counted : located) += double(w.pmm_points);
        (w.exact_octants ? octant_cells : cells) += double(w.exact_cells);
        octant_slow += w.exact_octants;
        cand += double(w.exact_cells);
        boxes += double(w.box_cells);
        points += double(w.face_points);
      }
      const std::string what = std::string(name) + " r=" + std::to_string(r * 1e3).substr(0, 4) + " mm";
      const double pmm_ns = compute_ns(engine, "method=pmm particle_grid=" + std::to_string(g), centres, rs) - base;
      if (grid)
        pmm.push_back({what + " n=" + std::to_string(g), {slow / n, located / n, counted / n}, pmm_ns});
      else
        pmm.push_back({what + " n=" + std::to_string(g), {slow / n, located / n, cand / n}, pmm_ns});
      if (exact_done) continue;
      exact_done = true;
      const double exact_ns = compute_ns(engine, "method=exact", centres, rs) - base;
      if (grid)
        exact.push_back({what, {(slow - octant_slow) / n, cells / n, octant_slow / n, octant_cells / n}, exact_ns});
      else
        exact.push_back({what, {slow / n, cand / n, boxes / n, points / n}, exact_ns});
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const int n = argc > 1 ? std::max(100, std::atoi(argv[1])) : 3000;
  const std::string data = std::string(VFE_SOURCE_DIR) + "/data/openfoam/";
  const auto grid_work = [](const Context& c, Scratch& s, const Particle& p) { return path_costs(c, s, p); };
  const auto graded_work = [](const RectilinearContext& c, Scratch& s, const Particle& p) { return path_costs(c, s, p); };
  const auto poly_work = [](const PolyContext& c, Scratch& s, const Particle& p) { return path_costs(c, s, p, true); };

  std::vector<Group> pmm, exact;
  for (const double h : {0.0004, 0.00075, 0.001, 0.002}) {  // chi = 0.4 to 2 for spheres of 1 mm
    const std::int64_t cells = static_cast<std::int64_t>(std::ceil(0.012 / h));
    const CartesianGridSpec spec{{0, 0, 0}, {h, h, h}, {cells, cells, cells}};
    EngineMesh mesh(spec);
    Engine engine(spec);
    groups_of<Context>(("h=" + std::to_string(h * 1e3).substr(0, 4) + " mm").c_str(), mesh, engine,
                       [&](const MethodContext& m) { return Context{m, *mesh.cartesian()}; }, grid_work, n, {0.0003, 0.0005},
                       pmm, exact, true);
  }
  std::printf("cartesian: GridCosts in ns\n");
  const Eigen::VectorXd cp = fit("pmm", "pmm_particle, pmm_point, pmm_counted", pmm);
  const Eigen::VectorXd ce =
      fit("exact", "exact_particle, exact_cell, exact_octant_particle, exact_octant_cell", exact);
  std::printf("  GridCosts{%.3g, %.3g, %.3g, %.3g, %.3g, %.3g, %.3g}\n", cp[0], cp[1], cp[2], ce[0], ce[1], ce[2],
              ce[3]);

  pmm.clear();
  exact.clear();
  for (const double h : {0.0004, 0.001}) {  // graded by 4 % a cell along every axis
    std::array<std::vector<double>, 3> nodes;
    for (auto& x : nodes) {
      x = {0};
      for (double dx = h; x.back() < 0.012; dx *= 1.04) x.push_back(x.back() + dx);
    }
    EngineMesh mesh{RectilinearGrid(nodes)};
    Engine engine(RectilinearGridSpec{nodes});
    groups_of<RectilinearContext>(("h0=" + std::to_string(h * 1e3).substr(0, 4) + " mm").c_str(), mesh, engine,
                                  [&](const MethodContext& m) { return RectilinearContext{m, *mesh.rectilinear()}; },
                                  graded_work, n, {0.0003, 0.0005}, pmm, exact, true);
  }
  std::printf("rectilinear: GridCosts in ns (no octant count on a graded grid)\n");
  const Eigen::VectorXd rp = fit("pmm", "pmm_particle, pmm_point, -", pmm);
  const Eigen::VectorXd re = fit("exact", "exact_particle, exact_cell, -, -", exact);
  std::printf("  GridCosts{%.3g, %.3g, %.3g, %.3g, %.3g, 0, 0}\n", rp[0], rp[1], rp[1], re[0], re[1]);

  pmm.clear();
  exact.clear();
  for (const char* name : {"snappy_obstacle", "cylinder_ogrid_coarse"}) {
    EngineMesh mesh(std::make_unique<PolyMesh>(PolyMesh::read(data + name)));
    Engine engine(PolyMeshSpec{data + name});
    groups_of<PolyContext>(name, mesh, engine, [&](const MethodContext& m) { return PolyContext{m, mesh.locator()}; },
                           poly_work, n / 3, {0.0003, 0.0005, 0.0008}, pmm, exact, false);
  }
  std::printf("polyhedral: PolyCosts in ns\n");
  const Eigen::VectorXd pp = fit("pmm", "pmm_particle, pmm_point, pmm_candidate", pmm);
  const Eigen::VectorXd pe = fit("exact", "exact_particle, exact_candidate, exact_box_cell, exact_face_point", exact);
  std::printf("  PolyCosts{%.3g, %.3g, %.3g, %.3g, %.3g, %.3g, %.3g}\n", pp[0], pp[1], pp[2], pe[0], pe[1], pe[2], pe[3]);
  return 0;
}
