/* vfe_mpi: the vfe engine on a Cartesian grid or an OpenFOAM polyMesh decomposed over MPI
 * ranks. C99 API.
 *
 * Each rank owns a block of cells of one global grid (or its processor mesh of a
 * decomposed polyMesh) and is given the particles whose centres lie in its cells. The rank
 * keeps an ordinary vfe engine on its block plus a ghost layer as wide as the largest
 * particle footprint needs; after the local compute the ghost cells' deposits are summed
 * into their owners (a reverse halo sum among the actual neighbours only). Owned-cell
 * fields then equal the serial engine's on the undecomposed grid given the same particles
 * with the same ids.
 *
 * The creators below return an ordinary vfe_engine: every function of vfe.h works on it.
 * Collective (every rank of the communicator calls it, in the same order, with the same
 * options): vfe_configure, vfe_compute, vfe_compute_particles, vfe_compute_shapes,
 * vfe_add_shape, vfe_deposit, vfe_interpolate, vfe_destroy, and here the creators and
 * vfe_mpi_route_particles. A collective call has the same status on every rank: a failure
 * on one rank (a bad argument, a particle on the wrong rank) fails it everywhere, and
 * vfe_last_error gives that rank's message, prefixed "rank N: " when there are several
 * ranks. The other calls are local to the rank and need no partner:
 *   vfe_cell_count, vfe_cell_volumes, vfe_void_fraction: the rank's owned cells, in local
 *     order (below);
 *   vfe_weights_size, vfe_weights: with weights=1, per particle of this rank's last compute
 *     its cells as global cell indices i + nx*(j + ny*k) (periodic images wrapped; on a
 *     polyMesh the undecomposed mesh's cell, cellProcAddressing) and fractions (CSR);
 *   vfe_last_report: the last compute over all ranks (sums; particle_grid_min/max over
 *     ranks);
 *   vfe_last_report_value: the vfe_report fields (over all ranks) and, for this rank,
 *     "ghost_width" (cells, largest over axes; on a polyMesh the width as a length),
 *     "ghost_bytes" (polyMesh: bytes of ghost geometry received at the last rebuild of the
 *     layer), "neighbours" (ranks exchanged with, itself included when it is its own
 *     periodic neighbour), "local_cells" (owned + ghost), "halo_values" (doubles this rank
 *     sends in one reverse halo sum), "halo_bytes" (bytes sent in it), and of the last
 *     compute on this rank "local_seconds" (wall time of the local engine's compute),
 *     "local_cpu_seconds" (its CPU time on the calling thread; with threads=1 its whole
 *     cost) and "exchange_seconds" (wall time of the halo sum and the report's allreduce);
 *     other keys answer VFE_ERROR_INVALID_ARGUMENT;
 *   vfe_set_log_callback, vfe_last_error.
 * Differences from an engine on one mesh: vfe_configure takes periodic= for the global grid
 * (a polyMesh refuses it, as the serial engine does) and answers VFE_ERROR_UNSUPPORTED for
 * smoothing_length > 0 (a diffusion over the whole mesh); vfe_deposit and vfe_interpolate
 * sum and fetch across ranks (values are this rank's particles of the last compute,
 * cell_field and out its owned cells); vfe_add_shape registers the shape on every rank
 * (a spec refused on one rank registers it on none, so ids agree), and a shaped particle's
 * ghost reach is its scale times the shape's farthest bounding-box corner; method=pmm on
 * shapes needs particle_grid=N (auto sizes a shape's template from the largest particle of
 * the compute, which differs per rank: VFE_ERROR_UNSUPPORTED). The ghost layer is widened
 * (on every rank) when a particle's footprint needs it.
 *
 * Particle contract: a particle is given on exactly one rank, the one whose block holds
 * the cell floor((centre - origin) / spacing) of its centre, after wrapping periodic axes
 * into the grid and clamping the other axes to the grid (a centre outside a non-periodic
 * side belongs to the owner of the nearest cell). vfe_mpi_owner says which rank that is; a
 * host whose particles are elsewhere sends each to that rank (vfe_mpi_route_particles does
 * it for plain arrays). A particle on the wrong rank fails the compute with
 * VFE_ERROR_INVALID_ARGUMENT naming it. orientation=random rotates by the particle ids
 * (vfe_particles.ids), so method=pmm with orientation=random requires ids
 * (vfe_compute_particles; vfe_compute passes none).
 *
 * On a polyMesh the owner of a centre is the rank owning the cell that holds it; a centre in
 * no cell of the whole mesh belongs to the rank owning the cell whose centre is nearest.
 * The ghost layer there is the other ranks' cells whose bounding box meets one of the
 * rank's cells' bounding boxes widened by the footprint's reach plus one cell (more under
 * outside=nearest, docs/scaling.md); only ranks whose bounding boxes come that close
 * exchange cells.
 *
 * Not thread-safe per engine, like any vfe_engine.
 */
#ifndef VFE_VFE_MPI_H
#define VFE_VFE_MPI_H

#include <mpi.h>
#include <vfe/vfe.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Collective. Rank's block [block_lo, block_hi) of cell indices of the global grid of
 *  global_cells cells of size spacing from origin; the blocks of all ranks tile the grid
 *  without overlap (checked). Local cell (i, j, k) (global indices) has index
 *  (i-lo0) + (hi0-lo0)*((j-lo1) + (hi1-lo1)*(k-lo2)). The communicator is duplicated;
 *  comm may be freed afterwards. On failure *out is untouched and vfe_last_error(NULL)
 *  says why (on every rank). */
VFE_API vfe_status vfe_mpi_create_cartesian(MPI_Comm comm, const double origin[3], const double spacing[3],
                                            const int64_t global_cells[3], const int64_t block_lo[3],
                                            const int64_t block_hi[3], vfe_engine** out);

/** Collective. Each rank passes its processorN folder as decomposePar writes it (the case
 *  folder processorN, its constant or its polyMesh folder): points, faces, owner,
 *  neighbour, boundary and the pointProcAddressing, faceProcAddressing and
 *  cellProcAddressing that map its points, faces and cells to the undecomposed mesh's
 *  (plain or .gz, ASCII or binary). Local cells keep the processor mesh's order. On a
 *  communicator of one rank an undecomposed case folder is taken as it is. Every rank must
 *  hold at least one cell; cyclic patches are refused (VFE_ERROR_UNSUPPORTED). The
 *  communicator is duplicated. On failure *out is untouched and vfe_last_error(NULL)
 *  says why (on every rank). */
VFE_API vfe_status vfe_mpi_create_polymesh(MPI_Comm comm, const char* processor_dir, vfe_engine** out);

/** A rank's part of a decomposed polyMesh in the host's memory: its processor mesh ordered
 *  as vfe_create_polymesh_arrays takes it (internal faces first, normal from owner to
 *  neighbour; cells = 1 + max(owner)), and global ids that number the undecomposed mesh's
 *  points, faces and cells alike on every rank: exactly decomposePar's pointProcAddressing,
 *  faceProcAddressing (global face + 1, negated when the rank's face is the global face
 *  reversed, i.e. on a processor patch where this rank's cell is the global neighbour) and
 *  cellProcAddressing. coupled_faces lists the faces on processor patches (shared with
 *  another rank), e.g. every face of an OpenFOAM host's processorPolyPatches. An OpenFOAM
 *  host running with -parallel reads the three addressing files from its processor folder
 *  (they are what decomposePar wrote; the global face and point ids must be the ones every
 *  rank agrees on). The arrays are copied. */
typedef struct vfe_mpi_polymesh {
  int64_t n_points;
  const double* points;          /* 3 n_points */
  const int64_t* point_ids;      /* n_points: global point */
  int64_t n_faces;
  const int64_t* face_offsets;   /* n_faces + 1, from 0 */
  const int64_t* face_points;    /* face_offsets[n_faces] */
  const int64_t* owner;          /* n_faces */
  int64_t n_internal_faces;
  const int64_t* neighbour;      /* n_internal_faces */
  const int64_t* face_ids;       /* n_faces: +-(global face + 1) */
  const int64_t* cell_ids;       /* cells: global cell */
  int64_t n_coupled_faces;
  const int64_t* coupled_faces;  /* n_coupled_faces face indices in [n_internal_faces, n_faces) */
} vfe_mpi_polymesh;

/** Collective. As vfe_mpi_create_polymesh, from the host's memory. */
VFE_API vfe_status vfe_mpi_create_polymesh_arrays(MPI_Comm comm, const vfe_mpi_polymesh* mesh, vfe_engine** out);

/** Rank that owns the cell holding a particle centred at centre (the particle contract). On a
 *  polyMesh only centres in the rank's own or ghost cells are known (else
 *  VFE_ERROR_INVALID_ARGUMENT). An engine not made by the creators above answers
 *  VFE_ERROR_INVALID_ARGUMENT. */
VFE_API vfe_status vfe_mpi_owner(const vfe_engine* e, const double centre[3], int* rank);

/** Collective. Sends every particle to the rank that owns it (vfe_mpi_owner; on a polyMesh
 *  a centre beyond the rank's cells and ghosts is looked up on every rank, the centres
 *  gathered everywhere: meant for the first hand-over, not every step). In: n packed
 *  particles (centres 3n, radii n, ids n). Out: *n_out particles in arrays allocated with
 *  malloc (the caller frees them), in the order of their source rank, then input order.
 *  On failure nothing is allocated. An engine not made by the creators above answers
 *  VFE_ERROR_INVALID_ARGUMENT. */
VFE_API vfe_status vfe_mpi_route_particles(const vfe_engine* e, int64_t n, const double* centres,
                                           const double* radii, const int64_t* ids, int64_t* n_out,
                                           double** centres_out, double** radii_out, int64_t** ids_out);

#ifdef __cplusplus
}
#endif

#endif /* VFE_VFE_MPI_H */
