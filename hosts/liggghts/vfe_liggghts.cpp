// Live CFD-DEM coupling without a CFD solver: LIGGGHTS runs in this process through its
// library interface; every N DEM steps vfe computes the void fraction of a Cartesian grid
// over the DEM box straight from LIGGGHTS's own atom arrays (no copy of positions or
// radii) with incremental=1, so only the particles that moved are redone.
//
//   vfe_liggghts --input in.pour_settle --every 500 --couplings 20 --cell 0.002 --csv out.csv
//
// Prints per coupling step the DEM time, vfe's compute time, the particles that moved
// and the change of eps since the previous coupling step; writes the same rows as CSV.
// --check also computes every step afresh (incremental=0) on a second engine and fails
// when the two fields differ or the deposited volume differs from the particles' volume.
// --dump FILE writes each coupling step's particles as a LAMMPS text dump frame (id type
// x y z radius vx vy vz); --dump - writes them to standard output, one flushed frame per
// coupling step (the table then goes to standard error), so that `vfe run` can take the
// running DEM as its particle source: particles: {command: "vfe_liggghts ... --dump -"}.
#include <mpi.h>
#include <liggghts/library.h>
#include <vfe/vfe.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

/// One engine, destroyed with its owner.
using EnginePtr = std::unique_ptr<vfe_engine, decltype(&vfe_destroy)>;

EnginePtr make_grid(const double lo[3], const double hi[3], double cell, const std::string& options) {
  double spacing[3];
  int64_t cells[3];
  for (int d = 0; d < 3; ++d) {
    cells[d] = std::max<int64_t>(1, std::llround((hi[d] - lo[d]) / cell));
    spacing[d] = (hi[d] - lo[d]) / static_cast<double>(cells[d]);
  }
  vfe_engine* e = nullptr;
  if (vfe_create_cartesian(lo, spacing, cells, &e) != VFE_OK)
    throw std::runtime_error(std::string("vfe_create_cartesian: ") + vfe_last_error(nullptr));
  EnginePtr owned(e, &vfe_destroy);
  if (vfe_configure(e, options.c_str()) != VFE_OK)
    throw std::runtime_error(std::string("vfe_configure: ") + vfe_last_error(e));
  return owned;
}

void check(vfe_status s, const vfe_engine* e, const char* call) {
  if (s != VFE_OK) throw std::runtime_error(std::string(call) + ": " + vfe_last_error(e));
}

template <class T>
T* extract_global(void* lmp, const char* name) {
  auto* p = static_cast<T*>(lammps_extract_global(lmp, const_cast<char*>(name)));
  if (!p) throw std::runtime_error(std::string("LIGGGHTS has no global '") + name + "'");
  return p;
}

/// LIGGGHTS's arrays of this moment: they move when LIGGGHTS grows or sorts them, so they
/// are fetched anew at every coupling step.
struct LiveAtoms {
  int n = 0;
  const double* x = nullptr;       // x[0] of LIGGGHTS's double** x: 3 per atom, contiguous
  const double* radius = nullptr;
  const int* tag = nullptr;        // LIGGGHTS's ids are int; vfe's are int64
  const double* v = nullptr;       // v[0]: 3 per atom (only for --dump)
  const int* type = nullptr;       // (only for --dump)
};

LiveAtoms live_atoms(void* lmp) {
  LiveAtoms a;
  a.n = *extract_global<int>(lmp, "nlocal");
  if (a.n == 0) return a;
  auto** x = static_cast<double**>(lammps_extract_atom(lmp, const_cast<char*>("x")));
  a.x = x ? x[0] : nullptr;
  a.radius = static_cast<const double*>(lammps_extract_atom(lmp, const_cast<char*>("radius")));
  a.tag = static_cast<const int*>(lammps_extract_atom(lmp, const_cast<char*>("id")));
  if (!a.x || !a.radius || !a.tag)
    throw std::runtime_error("LIGGGHTS gave no x, radius or id arrays: the input needs atom_style granular");
  auto** v = static_cast<double**>(lammps_extract_atom(lmp, const_cast<char*>("v")));
  a.v = v ? v[0] : nullptr;
  a.type = static_cast<const int*>(lammps_extract_atom(lmp, const_cast<char*>("type")));
  return a;
}

/// One LAMMPS text dump frame of the atoms, every value to 17 digits (lossless), flushed so
/// a reader at the other end of a pipe gets it whole at once.
void write_dump_frame(std::FILE* out, long long step, const double lo[3], const double hi[3], const LiveAtoms& a) {
  if (!a.v || !a.type) throw std::runtime_error("LIGGGHTS gave no v or type arrays: the input needs atom_style granular");
  std::fprintf(out, "ITEM: TIMESTEP\n%lld\nITEM: NUMBER OF ATOMS\n%d\nITEM: BOX BOUNDS\n", step, a.n);
  for (int d = 0; d < 3; ++d) std::fprintf(out, "%.17g %.17g\n", lo[d], hi[d]);
  std::fputs("ITEM: ATOMS id type x y z radius vx vy vz\n", out);
  for (int i = 0; i < a.n; ++i) {
    const double* x = a.x + 3 * i;
    const double* v = a.v + 3 * i;
    std::fprintf(out, "%d %d %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", a.tag[i], a.type[i], x[0], x[1], x[2],
                 a.radius[i], v[0], v[1], v[2]);
  }
  if (std::fflush(out) != 0 || std::ferror(out))
    throw std::runtime_error("cannot write the dump frame of step " + std::to_string(step) +
                             " (the reader of --dump stopped?)");
}

struct Change {
  double max = 0, mean = 0;
};

Change field_change(const std::vector<double>& now, const std::vector<double>& before) {
  Change c;
  for (std::size_t i = 0; i < now.size(); ++i) {
    const double d = std::abs(now[i] - before[i]);
    c.max = std::max(c.max, d);
    c.mean += d;
  }
  c.mean /= static_cast<double>(now.size());
  return c;
}

int run(int argc, char** argv) {
  CLI::App app{"LIGGGHTS in-process with vfe's void fraction every N DEM steps"};
  std::string input, csv = "vfe_liggghts.csv", options = "method=pmm", screen = "liggghts.screen", dump;
  long every = 500;
  int couplings = 10;
  double cell = 0.002;
  bool verify = false;
  app.add_option("--input", input, "LIGGGHTS input that sets up the run (no run command needed)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--every", every, "DEM steps per coupling step")->check(CLI::PositiveNumber);
  app.add_option("--couplings", couplings, "coupling steps")->check(CLI::PositiveNumber);
  app.add_option("--cell", cell, "cell size of the Cartesian grid over the DEM box (length units)")
      ->check(CLI::PositiveNumber);
  app.add_option("--options", options, "vfe_configure string (incremental=1 is added)");
  app.add_option("--csv", csv, "series output");
  app.add_option("--screen", screen, "file for LIGGGHTS's screen output (its log goes next to it)");
  app.add_flag("--check", verify, "also compute afresh each step and fail on any difference");
  app.add_option("--dump", dump,
                 "write each coupling step's particles as a LAMMPS text dump frame to this file, or with '-' to "
                 "standard output (the table goes to standard error)");
  CLI11_PARSE(app, argc, argv);

  const std::string log = screen + ".log";
  const char* largs[] = {"liggghts", "-screen", screen.c_str(), "-log", log.c_str()};
  void* lmp = nullptr;
  lammps_open(5, const_cast<char**>(largs), MPI_COMM_WORLD, &lmp);
  struct Closer {
    void* p;
    ~Closer() { lammps_close(p); }
  } closer{lmp};
  lammps_file(lmp, input.c_str());

  const double lo[3] = {*extract_global<double>(lmp, "boxxlo"), *extract_global<double>(lmp, "boxylo"),
                        *extract_global<double>(lmp, "boxzlo")};
  const double hi[3] = {*extract_global<double>(lmp, "boxxhi"), *extract_global<double>(lmp, "boxyhi"),
                        *extract_global<double>(lmp, "boxzhi")};
  const double dt = *extract_global<double>(lmp, "dt");
  EnginePtr engine = make_grid(lo, hi, cell, options + " incremental=1");
  EnginePtr fresh = verify ? make_grid(lo, hi, cell, options + " incremental=0") : EnginePtr(nullptr, &vfe_destroy);
  const std::size_t n_cells = static_cast<std::size_t>(vfe_cell_count(engine.get()));
  std::vector<double> solid(n_cells), eps(n_cells), eps_before(n_cells, 1.0), eps_fresh(n_cells);
  std::vector<int64_t> ids;

  std::ofstream out(csv);
  if (!out) throw std::runtime_error(csv + ": cannot write the series");
  // The dump frames; on standard output they take its place, and the table moves to stderr.
  std::FILE* table = dump == "-" ? stderr : stdout;
  std::unique_ptr<std::FILE, decltype(&std::fclose)> dump_file(nullptr, &std::fclose);
  if (!dump.empty() && dump != "-") {
    dump_file.reset(std::fopen(dump.c_str(), "w"));
    if (!dump_file) throw std::runtime_error(dump + ": cannot write the dump frames");
  }
  std::FILE* dump_out = dump == "-" ? stdout : dump_file.get();
  out << "step,dem_time,particles,moved,vfe_ms,max_abs_deps,mean_abs_deps,mean_eps,particle_volume,"
         "deposited_volume\n";
  std::fprintf(table, "%8s %10s %9s %7s %9s %12s %12s %9s\n", "step", "DEM t [s]", "particles", "moved", "vfe [ms]",
              "max|deps|", "mean|deps|", "mean eps");

  int failures = 0;
  for (int k = 0; k < couplings; ++k) {
    const std::string cmd = "run " + std::to_string(every) + (k == 0 ? "" : " pre no") + " post no";
    lammps_command(lmp, const_cast<char*>(cmd.c_str()));
    const auto step = *extract_global<int64_t>(lmp, "ntimestep");
    const LiveAtoms atoms = live_atoms(lmp);

    ids.assign(atoms.tag, atoms.tag + atoms.n);  // the one copy: int ids to int64
    vfe_particles p{};
    p.n = atoms.n;
    p.centres = atoms.x;
    p.radii = atoms.radius;
    p.ids = ids.data();
    const auto t0 = std::chrono::steady_clock::now();
    check(vfe_compute_particles(engine.get(), &p, solid.data()), engine.get(), "vfe_compute_particles");
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    check(vfe_void_fraction(engine.get(), eps.data()), engine.get(), "vfe_void_fraction");
    double moved = 0;
    check(vfe_last_report_value(engine.get(), "moved_particles", &moved), engine.get(), "vfe_last_report_value");
    vfe_report rep{};
    check(vfe_last_report(engine.get(), &rep), engine.get(), "vfe_last_report");

    double mean_eps = 0;
    for (double v : eps) mean_eps += v;
    mean_eps /= static_cast<double>(n_cells);
    const Change c = field_change(eps, eps_before);
    eps_before = eps;
    std::fprintf(table, "%8lld %10.4f %9d %7.0f %9.3f %12.3e %12.3e %9.5f\n", static_cast<long long>(step),
                static_cast<double>(step) * dt, atoms.n, moved, ms, c.max, c.mean, mean_eps);
    out << step << ',' << static_cast<double>(step) * dt << ',' << atoms.n << ',' << moved << ',' << ms << ','
        << c.max << ',' << c.mean << ',' << mean_eps << ',' << rep.particle_volume << ',' << rep.deposited_volume
        << '\n';
    if (dump_out) write_dump_frame(dump_out, static_cast<long long>(step), lo, hi, atoms);

    if (verify) {
      // The particles' volume from LIGGGHTS's radii, and the same field computed afresh.
      double volume = 0;
      for (int i = 0; i < atoms.n; ++i) volume += 4.0 / 3.0 * M_PI * std::pow(atoms.radius[i], 3);
      check(vfe_compute_particles(fresh.get(), &p, solid.data()), fresh.get(), "vfe_compute_particles");
      check(vfe_void_fraction(fresh.get(), eps_fresh.data()), fresh.get(), "vfe_void_fraction");
      const double diff = field_change(eps, eps_fresh).max;
      const double verr = std::abs(rep.deposited_volume - volume) / std::max(volume, 1e-300);
      if (diff > 1e-12 || verr > 1e-12 || moved > atoms.n) {
        std::fprintf(stderr, "check failed at step %lld: |eps - eps_fresh| = %.3e, volume error %.3e, moved %g of %d\n",
                     static_cast<long long>(step), diff, verr, moved, atoms.n);
        ++failures;
      }
    }
  }
  if (verify && failures == 0) std::fprintf(table, "check: incremental equals a fresh compute and conserves volume\n");
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rc = 1;
  try {
    rc = run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vfe_liggghts: %s\n", e.what());
  }
  MPI_Finalize();
  return rc;
}
