/* A C host of an installed libvfe_mpi: two slabs of a 4x2x2 grid, one sphere on the slab
   boundary given on its owner; the summed solid volume must be the sphere's. */
#include <vfe/vfe_mpi.h>

#include <math.h>
#include <stdio.h>

int main(int argc, char** argv) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1}, centre[3] = {1.9, 1, 1}, radius = 0.5;
  const int64_t cells[3] = {4, 2, 2};
  int64_t lo[3] = {0, 0, 0}, hi[3] = {4, 2, 2};
  double solid[16], mine = 0, total = 0;
  int rank = 0, size = 1, owner = -1, status = 1, i;
  vfe_mpi_engine* e = NULL;
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  lo[0] = 4 * rank / size;
  hi[0] = 4 * (rank + 1) / size;
  if (vfe_mpi_create_cartesian(MPI_COMM_WORLD, origin, spacing, cells, lo, hi, &e) != VFE_OK) {
    fprintf(stderr, "host_mpi: %s\n", vfe_mpi_last_error(NULL));
  } else if (vfe_mpi_configure(e, "method=exact") == VFE_OK && vfe_mpi_owner(e, centre, &owner) == VFE_OK &&
             vfe_mpi_compute(e, rank == owner ? 1 : 0, centre, &radius, NULL, solid) == VFE_OK) {
    for (i = 0; i < vfe_mpi_cell_count(e); ++i) mine += solid[i];
    MPI_Allreduce(&mine, &total, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    status = fabs(total - 4.0 / 3.0 * 3.14159265358979323846 * radius * radius * radius) < 1e-12 ? 0 : 1;
    if (status) fprintf(stderr, "host_mpi: solid volume %.17g is not the sphere's\n", total);
  } else {
    fprintf(stderr, "host_mpi: %s\n", vfe_mpi_last_error(e));
  }
  vfe_mpi_destroy(e);
  MPI_Finalize();
  return status;
}
