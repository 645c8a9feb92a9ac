// Strong and weak scaling of libvfe_mpi: a bed of random spheres on a Cartesian grid split
// into slabs along z, one engine thread per rank. Prints one line per method: the compute's
// wall time (slowest rank; min and median over repeats), the local engine's CPU time (median
// of the slowest rank, and the mean sum over ranks: the work, whatever shares the cores), the
// longest halo exchange, and the halo against the owned field.
//   mpiexec -np P bench_mpi [--weak] [--cells NX NY NZ] [--particles N] [--repeats K] [--periodic AXES]
// --weak: every rank gets NX x NY x NZ cells and N particles (the grid grows along z);
// otherwise the whole grid has NX x NY x NZ cells and N particles.
#include <vfe/vfe_mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  bool weak = false;
  std::array<int64_t, 3> cells{20, 20, 60};
  int64_t particles = 20000;
  int repeats = 10;
  std::string periodic = "none";
  for (int a = 1; a < argc; ++a) {
    if (!std::strcmp(argv[a], "--weak")) weak = true;
    else if (!std::strcmp(argv[a], "--cells") && a + 3 < argc)
      for (int d = 0; d < 3; ++d) cells[d] = std::atoll(argv[++a]);
    else if (!std::strcmp(argv[a], "--particles") && a + 1 < argc) particles = std::atoll(argv[++a]);
    else if (!std::strcmp(argv[a], "--repeats") && a + 1 < argc) repeats = std::atoi(argv[++a]);
    else if (!std::strcmp(argv[a], "--periodic") && a + 1 < argc) periodic = argv[++a];
  }
  if (weak) {
    cells[2] *= size;
    particles *= size;
  }
  const double h = 0.002, radius = 0.0005;  // 2 mm cells, 1 mm spheres: chi = 2
  const double origin[3] = {0, 0, 0}, spacing[3] = {h, h, h};
  const int64_t lo[3] = {0, 0, cells[2] * rank / size}, hi[3] = {cells[0], cells[1], cells[2] * (rank + 1) / size};
  // Every rank draws the same bed and keeps the particles whose centre's cell it owns.
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> centres, radii;
  std::vector<int64_t> ids;
  for (int64_t i = 0; i < particles; ++i) {
    const double x[3] = {u(rng) * h * double(cells[0]), u(rng) * h * double(cells[1]), u(rng) * h * double(cells[2])};
    const int64_t k = int64_t(std::floor(x[2] / h));
    if (k < lo[2] || k >= hi[2]) continue;
    centres.insert(centres.end(), x, x + 3);
    radii.push_back(radius);
    ids.push_back(i);
  }
  vfe_engine* e = nullptr;
  if (vfe_mpi_create_cartesian(MPI_COMM_WORLD, origin, spacing, cells.data(), lo, hi, &e) != VFE_OK) {
    std::fprintf(stderr, "bench_mpi: %s\n", vfe_last_error(nullptr));
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  std::vector<double> solid(size_t(vfe_cell_count(e)));
  vfe_particles p{};
  p.n = int64_t(radii.size());
  p.centres = centres.data();
  p.radii = radii.data();
  p.ids = ids.data();
  if (rank == 0)
    std::printf("%s: %d ranks, grid %lldx%lldx%lld, %lld particles, periodic=%s\n", weak ? "weak" : "strong", size,
                (long long)cells[0], (long long)cells[1], (long long)cells[2], (long long)particles, periodic.c_str());
  for (const char* method : {"pmm", "exact", "gaussian"}) {
    const std::string options = std::string("method=") + method + " threads=1 periodic=" + periodic;
    if (vfe_configure(e, options.c_str()) != VFE_OK ||
        vfe_compute_particles(e, &p, solid.data()) != VFE_OK) {  // warm-up: templates, ghost width
      std::fprintf(stderr, "bench_mpi: %s\n", vfe_last_error(e));
      MPI_Abort(MPI_COMM_WORLD, 1);
    }
    std::vector<double> times, cpu;
    double cpu_sum = 0, exchange_max = 0;
    for (int r = 0; r < repeats; ++r) {
      MPI_Barrier(MPI_COMM_WORLD);
      const double t0 = MPI_Wtime();
      vfe_compute_particles(e, &p, solid.data());
      double t = MPI_Wtime() - t0, slowest = 0, c = 0, x = 0, c_max = 0, c_sum = 0, x_max = 0;
      vfe_last_report_value(e, "local_cpu_seconds", &c);
      vfe_last_report_value(e, "exchange_seconds", &x);
      MPI_Allreduce(&t, &slowest, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
      MPI_Allreduce(&c, &c_max, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
      MPI_Allreduce(&c, &c_sum, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
      MPI_Allreduce(&x, &x_max, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
      times.push_back(slowest);
      cpu.push_back(c_max);
      cpu_sum += c_sum / repeats;
      exchange_max = std::max(exchange_max, x_max);
    }
    std::sort(cpu.begin(), cpu.end());
    std::sort(times.begin(), times.end());
    double ghost = 0, halo_bytes = 0, neighbours = 0, local_cells = 0;
    vfe_last_report_value(e, "ghost_width", &ghost);
    vfe_last_report_value(e, "halo_bytes", &halo_bytes);
    vfe_last_report_value(e, "neighbours", &neighbours);
    vfe_last_report_value(e, "local_cells", &local_cells);
    double max_halo = 0, sum_halo = 0;
    MPI_Allreduce(&halo_bytes, &max_halo, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    MPI_Allreduce(&halo_bytes, &sum_halo, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    const double owned_bytes = double(solid.size()) * sizeof(double);
    if (rank == 0)
      std::printf("  %-9s wall min %6.2f median %6.2f ms | local CPU: slowest rank %6.2f ms, all ranks %6.2f ms | "
                  "exchange max %5.2f ms | ghost %g, neighbours %g, local/owned %.2f, halo %.0f B/rank (max), "
                  "%.0f B total = %.2f x the rank-0 owned field\n",
                  method, 1e3 * times.front(), 1e3 * times[times.size() / 2], 1e3 * cpu[cpu.size() / 2],
                  1e3 * cpu_sum, 1e3 * exchange_max, ghost, neighbours, local_cells / double(solid.size()),
                  max_halo, sum_halo, max_halo / owned_bytes);
  }
  vfe_destroy(e);
  MPI_Finalize();
  return 0;
}
