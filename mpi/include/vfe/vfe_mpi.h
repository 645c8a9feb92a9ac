/* vfe_mpi: the vfe engine on a Cartesian grid decomposed over MPI ranks. C99 API.
 *
 * Each rank owns a block of cells of one global grid and is given the particles whose
 * centres lie in its block. The rank keeps an ordinary vfe engine on its block plus a
 * ghost layer as wide as the largest particle footprint needs; after the local compute the
 * ghost cells' deposits are summed into their owners (a reverse halo sum among the actual
 * neighbours only). Owned-cell fields then equal the serial engine's on the undecomposed
 * grid given the same particles with the same ids.
 *
 * Deviation from the distributed-mesh contract (docs/scaling.md): vfe_engine is opaque inside libvfe, which stays free of MPI, so
 * the distributed engine is its own handle, vfe_mpi_engine, with vfe_mpi_* equivalents of
 * the vfe_* calls. Functions marked "collective" must be called by every rank of the
 * communicator, in the same order, with the same options; their status is the same on
 * every rank (a failure on one rank fails the call everywhere, with that rank's message).
 *
 * Particle contract: a particle is given on exactly one rank, the one whose block holds
 * the cell floor((centre - origin) / spacing) of its centre, after wrapping periodic axes
 * into the grid and clamping the other axes to the grid (a centre outside a non-periodic
 * side belongs to the owner of the nearest cell). vfe_mpi_owner says which rank that is; a
 * host whose particles are elsewhere sends each to that rank (vfe_mpi_route_particles does
 * it for plain arrays). A particle on the wrong rank fails the compute with
 * VFE_ERROR_INVALID_ARGUMENT naming it. orientation=random rotates by the particle ids
 * (vfe_particles.ids), so method=pmm with orientation=random requires ids.
 *
 * Spheres only (no shapes); Cartesian grids only (vfe_mpi_create_polymesh answers
 * VFE_ERROR_UNSUPPORTED). Not thread-safe per handle, like vfe_engine.
 */
#ifndef VFE_VFE_MPI_H
#define VFE_VFE_MPI_H

#include <mpi.h>
#include <vfe/vfe.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vfe_mpi_engine vfe_mpi_engine; /* opaque */

/** Collective. Rank's block [block_lo, block_hi) of cell indices of the global grid of
 *  global_cells cells of size spacing from origin; the blocks of all ranks tile the grid
 *  without overlap (checked). Local cell (i, j, k) (global indices) has index
 *  (i-lo0) + (hi0-lo0)*((j-lo1) + (hi1-lo1)*(k-lo2)). The communicator is duplicated;
 *  comm may be freed afterwards. On failure *out is untouched and vfe_mpi_last_error(NULL)
 *  says why. */
VFE_API vfe_status vfe_mpi_create_cartesian(MPI_Comm comm, const double origin[3], const double spacing[3],
                                            const int64_t global_cells[3], const int64_t block_lo[3],
                                            const int64_t block_hi[3], vfe_mpi_engine** out);

/** Collective. Not implemented yet: answers VFE_ERROR_UNSUPPORTED. */
VFE_API vfe_status vfe_mpi_create_polymesh(MPI_Comm comm, const char* processor_dir, vfe_mpi_engine** out);

/** Collective. Frees the handle; NULL is a no-op (on every rank, or on none). */
VFE_API void vfe_mpi_destroy(vfe_mpi_engine* e);

/** Collective. vfe_configure's keys and values; periodic= applies to the global grid.
 *  smoothing_length > 0 (a diffusion over the whole mesh) answers VFE_ERROR_UNSUPPORTED. */
VFE_API vfe_status vfe_mpi_configure(vfe_mpi_engine* e, const char* options);

/** Owned cells of this rank, or -1 when e is NULL. */
VFE_API int64_t vfe_mpi_cell_count(const vfe_mpi_engine* e);
/** Volume of every owned cell. */
VFE_API vfe_status vfe_mpi_cell_volumes(const vfe_mpi_engine* e, double* out);

/** Rank that owns the cell holding a particle centred at centre (the particle contract). */
VFE_API vfe_status vfe_mpi_owner(const vfe_mpi_engine* e, const double centre[3], int* rank);

/** Collective. Solid volume of this rank's particles' deposits summed over all ranks, per
 *  owned cell (overwritten). vfe_mpi_compute passes no ids (so not for pmm with
 *  orientation=random); vfe_mpi_compute_particles takes the host's layout and ids. The
 *  ghost layer is widened (on every rank) when a particle's footprint needs it. */
VFE_API vfe_status vfe_mpi_compute(vfe_mpi_engine* e, int64_t n, const double* centres, const double* radii,
                                   const double* orientations, double* solid_volume);
VFE_API vfe_status vfe_mpi_compute_particles(vfe_mpi_engine* e, const vfe_particles* p, double* solid_volume);

/** Void fraction 1 - Vs/V of the owned cells after the last compute (clipped at alpha_min). */
VFE_API vfe_status vfe_mpi_void_fraction(const vfe_mpi_engine* e, double* out);

/** Collective. With weights=1: out[c*k + j] = sum over every rank's particles p of
 *  fraction_pc * values[p*k + j] for the owned cells c; values are this rank's particles of
 *  the last compute. Overwrites out. */
VFE_API vfe_status vfe_mpi_deposit(vfe_mpi_engine* e, int32_t components, const double* values, double* out);
/** Collective. With weights=1: per particle of this rank's last compute, the fraction-weighted
 *  mean of cell_field (owned cells, k per cell) over its cells, ghost values fetched from
 *  their owners (a forward halo exchange). */
VFE_API vfe_status vfe_mpi_interpolate(vfe_mpi_engine* e, int32_t components, const double* cell_field,
                                       double* out);
/** With weights=1: per particle of this rank's last compute its cells as global cell
 *  indices i + nx*(j + ny*k) (periodic images wrapped) and fractions (CSR). */
VFE_API vfe_status vfe_mpi_weights_size(const vfe_mpi_engine* e, int64_t* n_particles, int64_t* n_entries);
VFE_API vfe_status vfe_mpi_weights(const vfe_mpi_engine* e, int64_t* offsets, int64_t* cells, double* fractions);

/** Report of the last compute over all ranks (sums; particle_grid_min/max over ranks). */
VFE_API vfe_status vfe_mpi_last_report(const vfe_mpi_engine* e, vfe_report* out);
/** A fact by name: the vfe_report fields (over all ranks) and, for this rank, "ghost_width"
 *  (cells, largest over axes), "neighbours" (ranks exchanged with, itself included when it
 *  is its own periodic neighbour), "local_cells" (owned + ghost), "halo_values" (doubles
 *  this rank sends in one reverse halo sum), "halo_bytes" (bytes sent in it), and of the last
 *  compute on this rank "local_seconds" (wall time of the local engine's compute),
 *  "local_cpu_seconds" (its CPU time on the calling thread; with threads=1 its whole cost)
 *  and "exchange_seconds" (wall time of the halo sum and the report's allreduce). */
VFE_API vfe_status vfe_mpi_last_report_value(const vfe_mpi_engine* e, const char* key, double* out);

/** Message of the last failure on e ("" if none); for NULL, of the last failed creation. */
VFE_API const char* vfe_mpi_last_error(const vfe_mpi_engine* e);
VFE_API vfe_status vfe_mpi_set_log_callback(vfe_mpi_engine* e, vfe_log_fn fn, void* user);

/** Collective. Sends every particle to the rank that owns it (vfe_mpi_owner). In: n packed
 *  particles (centres 3n, radii n, ids n). Out: *n_out particles in arrays allocated with
 *  malloc (the caller frees them), in the order of their source rank, then input order.
 *  On failure nothing is allocated. */
VFE_API vfe_status vfe_mpi_route_particles(const vfe_mpi_engine* e, int64_t n, const double* centres,
                                           const double* radii, const int64_t* ids, int64_t* n_out,
                                           double** centres_out, double** radii_out, int64_t** ids_out);

#ifdef __cplusplus
}
#endif

#endif /* VFE_VFE_MPI_H */
