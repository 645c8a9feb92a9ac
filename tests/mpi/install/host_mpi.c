/* A C host of an installed libvfe_mpi: slabs of a 4x2x2 grid, one sphere on the slab
   boundary given on its owner, through vfe.h's ordinary calls on the distributed engine.
   The summed solid volume and the report's particle volume must be the sphere's, the void
   fraction 1 - Vs/V per owned cell; a bad option fails on every rank with a message naming
   it, and vfe_mpi_owner refuses an engine that is not distributed. */
#include <vfe/vfe_mpi.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

static int fail(const char* what, const char* message) {
  fprintf(stderr, "host_mpi: %s: %s\n", what, message);
  return 1;
}

/* The checks on a distributed engine e whose cells have unit volume; 0 when all pass. */
static int check(vfe_engine* e, int rank, const double centre[3], double radius) {
  const double sphere = 4.0 / 3.0 * 3.14159265358979323846 * radius * radius * radius;
  double solid[16], eps[16], mine = 0, total = 0, particle_volume = 0;
  int owner = -1;
  int64_t i, n = vfe_cell_count(e);
  if (n < 1 || n > 16) return fail("vfe_cell_count", "not the rank's slab");
  if (vfe_configure(e, "method=exact") != VFE_OK) return fail("vfe_configure", vfe_last_error(e));
  if (vfe_mpi_owner(e, centre, &owner) != VFE_OK) return fail("vfe_mpi_owner", vfe_last_error(e));
  if (vfe_compute(e, rank == owner ? 1 : 0, centre, &radius, NULL, solid) != VFE_OK)
    return fail("vfe_compute", vfe_last_error(e));
  if (vfe_void_fraction(e, eps) != VFE_OK) return fail("vfe_void_fraction", vfe_last_error(e));
  for (i = 0; i < n; ++i) {
    mine += solid[i];
    if (fabs(eps[i] - (1.0 - solid[i])) > 1e-15) return fail("vfe_void_fraction", "not 1 - Vs/V");
  }
  MPI_Allreduce(&mine, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  if (fabs(total - sphere) > 1e-12) return fail("vfe_compute", "the summed solid volume is not the sphere's");
  if (vfe_last_report_value(e, "particle_volume", &particle_volume) != VFE_OK)
    return fail("vfe_last_report_value", vfe_last_error(e));
  if (fabs(particle_volume - sphere) > 1e-12) return fail("vfe_last_report_value", "particle_volume over ranks");
  /* A bad option: the same status on every rank, a message naming the key. */
  if (vfe_configure(e, "method=nonsense") != VFE_ERROR_INVALID_ARGUMENT)
    return fail("vfe_configure", "method=nonsense was accepted");
  if (!strstr(vfe_last_error(e), "method")) return fail("vfe_last_error", vfe_last_error(e));
  return 0;
}

int main(int argc, char** argv) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1}, centre[3] = {1.9, 1, 1}, radius = 0.5;
  const int64_t cells[3] = {4, 2, 2};
  int64_t lo[3] = {0, 0, 0}, hi[3] = {4, 2, 2};
  int rank = 0, size = 1, owner = -1, status = 1, worst = 1;
  vfe_engine *e = NULL, *serial = NULL;
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  lo[0] = 4 * rank / size;
  hi[0] = 4 * (rank + 1) / size;
  if (vfe_mpi_create_cartesian(MPI_COMM_WORLD, origin, spacing, cells, lo, hi, &e) != VFE_OK)
    status = fail("vfe_mpi_create_cartesian", vfe_last_error(NULL));
  else
    status = check(e, rank, centre, radius);
  vfe_destroy(e);
  /* An engine on one mesh is not distributed. */
  if (status == 0 && vfe_create_cartesian(origin, spacing, cells, &serial) != VFE_OK)
    status = fail("vfe_create_cartesian", vfe_last_error(NULL));
  else if (status == 0 && (vfe_mpi_owner(serial, centre, &owner) != VFE_ERROR_INVALID_ARGUMENT || owner != -1 ||
                           !strstr(vfe_last_error(serial), "not distributed")))
    status = fail("vfe_mpi_owner on an engine of one mesh", vfe_last_error(serial));
  vfe_destroy(serial);
  MPI_Allreduce(&status, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return worst;
}
