/* vfe: void fraction of CFD cells from DEM particles. C99 API.
 *
 * Every function returns a status; none throws, aborts or exits. A failed call leaves the
 * output buffers untouched, sets a message (vfe_last_error) that says what was wrong and
 * how to fix it, and leaves the engine usable. One engine must not be used by two threads
 * at once; distinct engines are independent. Lengths and volumes are in the host's units.
 */
#ifndef VFE_VFE_H
#define VFE_VFE_H

#include <stdint.h>

#include <vfe/version.h>

/* libvfe is built with hidden symbols; VFE_API marks what it exports. VFE_BUILDING_LIBRARY
 * is defined only while compiling the library itself. */
#if defined(_WIN32)
#if defined(VFE_BUILDING_LIBRARY)
#define VFE_API __declspec(dllexport)
#else
#define VFE_API __declspec(dllimport)
#endif
#else
#define VFE_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vfe_engine vfe_engine; /* opaque */

typedef enum vfe_status {
  VFE_OK = 0,
  VFE_ERROR_INVALID_ARGUMENT = 1,
  VFE_ERROR_OUT_OF_DOMAIN = 2,
  VFE_ERROR_IO = 3,
  VFE_ERROR_UNSUPPORTED = 4,
  VFE_ERROR_OUT_OF_MEMORY = 5,
  VFE_ERROR_INTERNAL = 6
} vfe_status;

/** Version string "MAJOR.MINOR.PATCH" of the loaded library. */
VFE_API const char* vfe_version(void);
/** Version of the loaded library as MAJOR*10000 + MINOR*100 + PATCH (VFE_VERSION_NUMBER
 *  of the headers it was built from). */
VFE_API uint32_t vfe_version_number(void);

/** Short name of a status ("VFE_OK", "VFE_ERROR_IO", ...); never NULL. */
VFE_API const char* vfe_status_name(vfe_status s);

/** Engine on a uniform Cartesian grid: cells[d] cells of size spacing[d] from origin.
 *  Cell (i, j, k) has index i + nx*(j + ny*k). */
VFE_API vfe_status vfe_create_cartesian(const double origin[3], const double spacing[3],
                                        const int64_t cells[3], vfe_engine** out);

/** Engine on an OpenFOAM polyMesh (case folder or its constant/polyMesh folder). */
VFE_API vfe_status vfe_create_polymesh(const char* polymesh_dir, vfe_engine** out);
/** Rectilinear (graded Cartesian) grid: n_x, n_y, n_z strictly increasing node coordinates
 *  per axis (at least 2 each); cell (i, j, k) has index i + (n_x-1)*(j + (n_y-1)*k).
 *  Methods direct, pmm and exact; axes may be periodic. */
VFE_API vfe_status vfe_create_rectilinear(const double* x_nodes, int64_t n_x, const double* y_nodes, int64_t n_y,
                                          const double* z_nodes, int64_t n_z, vfe_engine** out);

/** Frees the engine; NULL is a no-op. */
VFE_API void vfe_destroy(vfe_engine* e);

/** Sets options from "key=value key=value" (see the README for keys). Either all given
 *  options are applied or, on error, none. */
VFE_API vfe_status vfe_configure(vfe_engine* e, const char* options);

/** Number of cells, or -1 when e is NULL. */
VFE_API int64_t vfe_cell_count(const vfe_engine* e);

/** Writes the volume of every cell (cell_count values). */
VFE_API vfe_status vfe_cell_volumes(const vfe_engine* e, double* out);

/** Solid volume per cell of n spheres (centres 3n: x, y, z per particle; radii n;
 *  orientations 4n quaternions w, x, y, z or NULL: read only under orientation=given, where
 *  each particle's template is rotated by its quaternion (normalised); orientation=random
 *  rotates each template by a fixed pseudo-random rotation of the particle's index and
 *  orientation=none not at all, both ignoring orientations). solid_volume gets cell_count values (overwritten, not added to).
 *  The host's arrays are read, not copied, and not kept after the call. */
VFE_API vfe_status vfe_compute(vfe_engine* e, int64_t n, const double* centres,
                               const double* radii, const double* orientations,
                               double* solid_volume);

/** Void fraction 1 - Vs/V of the last successful compute (cell_count values), clipped
 *  below at alpha_min when that option is set. */
VFE_API vfe_status vfe_void_fraction(const vfe_engine* e, double* out);

/** Message of the last failure on e ("" if none); for e == NULL, of the last failed
 *  creation in this thread. Valid until the next call on e. */
VFE_API const char* vfe_last_error(const vfe_engine* e);

/** Non-spherical particles: register a shape once, then pass per-particle shape ids.
 *  A shape is given in its own template units; scale (lambda) multiplies its lengths, so
 *  its volume scales by lambda^3; the particle's position is the shape's origin. "sphere"
 *  is the unit-radius sphere (scale = radius). spec: "sphere" | "ellipsoid A B C" (semi-axes)
 *  | "superquadric A B C E1 E2" | "clump x y z r; x y z r; ..." | "mesh FILE" (closed
 *  triangle mesh, STL ASCII/binary or OBJ). Methods: pmm and direct for every shape; the
 *  others for spheres only (VFE_ERROR_UNSUPPORTED otherwise). */
VFE_API vfe_status vfe_add_shape(vfe_engine* e, const char* spec, int32_t* shape_id);
VFE_API vfe_status vfe_compute_shapes(vfe_engine* e, int64_t n, const double* centres,
                                      const double* scales, const double* orientations,
                                      const int32_t* shape_ids, double* solid_volume);

/** Name of method i (0, 1, ...: "direct", "pmm", "exact", ...), NULL past the last. */
VFE_API const char* vfe_method_name(int32_t i);

/* ---- Coupling API ---------------------------------------------------------------------- */

/** A face-based mesh from the host's memory, ordered as OpenFOAM orders it: internal faces
 *  first (normal from owner to neighbour), then boundary faces; cells = 1 + max(owner).
 *  Gives the same engine as vfe_create_polymesh on the same mesh. The arrays are copied. */
VFE_API vfe_status vfe_create_polymesh_arrays(int64_t n_points, const double* points /* 3 n_points */,
                                              int64_t n_faces, const int64_t* face_offsets /* n_faces+1 */,
                                              const int64_t* face_points /* face_offsets[n_faces] */,
                                              const int64_t* owner /* n_faces */, int64_t n_internal_faces,
                                              const int64_t* neighbour /* n_internal_faces */, vfe_engine** out);

/** Particles in the host's own layout: byte strides between consecutive particles (0 =
 *  packed), read in place, nothing copied or kept. Centres are x, y, z per particle.
 *  Orientations (w, x, y, z) are read with orientation=given only; orientation=random
 *  draws each particle's rotation from its id when ids is given, else from its index. */
typedef struct vfe_particles {
  int64_t n;
  const double* centres;      int64_t centres_stride;      /* x,y,z */
  const double* radii;        int64_t radii_stride;        /* radius; the scale for shapes */
  const double* orientations; int64_t orientations_stride; /* w,x,y,z, or NULL */
  const int32_t* shape_ids;   int64_t shape_ids_stride;    /* NULL: spheres */
  const int64_t* ids;         int64_t ids_stride;          /* the host's particle ids, or NULL */
} vfe_particles;
VFE_API vfe_status vfe_compute_particles(vfe_engine* e, const vfe_particles* p, double* solid_volume);

/** With option weights=1: per particle of the last compute, its cells and the fraction of
 *  its volume in each (CSR). Fractions of a particle sum to 1 less its dropped share. */
VFE_API vfe_status vfe_weights_size(const vfe_engine* e, int64_t* n_particles, int64_t* n_entries);
VFE_API vfe_status vfe_weights(const vfe_engine* e, int64_t* offsets /* n_particles+1 */,
                               int64_t* cells /* n_entries */, double* fractions /* n_entries */);
/** out[c*k + j] = sum_p fraction_pc * values[p*k + j]   (overwrites out; conserves sums) */
VFE_API vfe_status vfe_deposit(const vfe_engine* e, int32_t components, const double* values,
                               double* out /* cell_count * components */);
/** out[p*k + j] = sum_c fraction_pc * field[c*k + j] / sum_c fraction_pc   (0 if no cell) */
VFE_API vfe_status vfe_interpolate(const vfe_engine* e, int32_t components, const double* cell_field,
                                   double* out /* n_particles * components */);
/** The host owns the log: level as spdlog's (0 trace .. 5 critical). NULL restores stderr. */
typedef void (*vfe_log_fn)(int level, const char* message, void* user);
VFE_API vfe_status vfe_set_log_callback(vfe_engine* e, vfe_log_fn fn, void* user);

/** Facts about the last successful compute. Volumes in the host's units. */
typedef struct vfe_report {
  int64_t particles;            /* particles given */
  int64_t fast_path_particles;  /* particles wholly inside one cell (one deposit) */
  int64_t sub_elements;         /* sub-elements / points / cell overlaps evaluated */
  int64_t particle_grid_min;    /* smallest and largest sub-elements per particle used */
  int64_t particle_grid_max;
  double particle_volume;       /* sum of the particles' volumes */
  double deposited_volume;      /* sum of the solid volume field */
  double dropped_volume;        /* lost outside the mesh under outside=drop */
  int64_t outside_particles;    /* particles with some volume outside the mesh: on a grid, spheres
                                   reaching beyond its box by more than outside_tolerance (the same
                                   count for every method); on a polyMesh and for shapes, those
                                   with volume the method placed beyond the mesh */
  double clipped_volume;        /* removed from eps by alpha_min (solid volume units) */
} vfe_report;

/** Copies the report of the last successful compute. */
VFE_API vfe_status vfe_last_report(const vfe_engine* e, vfe_report* out);

/** One fact of the last successful compute by name: any field of vfe_report, and
 *  "moved_particles" (particles computed anew; with incremental=1 those that moved),
 *  "touched_cells" (cells with solid volume; with touched_only=1, else -1), "overfull_cells"
 *  and "overfull_volume" (cells whose solid volume exceeds their volume, eps < 0, and the
 *  excess: a scene that does not match the mesh, or cells smaller than the particles),
 *  "counted_particles" (pmm: particles whose sub-elements were counted per octant of a window
 *  of at most 2 x 2 x 2 cells instead of located one by one; the cells are the same),
 *  "fused_pass" (1 when validation and deposits ran as one pass over the particles),
 *  "binned_regions" (that pass with several threads on a mesh of 600000 cells or more: the
 *  regions of cells its deposits were sorted into and then added region by region; 0 when
 *  they went to per-thread fields),
 *  "ordered_blocks" (the slabs of the field the spheres were computed in, option
 *  particle_order; 0 when they were computed in the host's order),
 *  "lattice_cells" (the cells of a polyMesh whose cells are a lattice of axis-aligned boxes,
 *  0 for other meshes), "lattice_particles" (particles that took that lattice's grid
 *  path, option lattice=1) and, for method=auto, "auto_fast", "auto_pmm" and "auto_exact"
 *  (spheres computed on the fast path, by pmm and by the exact overlap; shapes count as
 *  pmm; 0 for other methods), "exact_located_cells" and "exact_general_cells" (exact on
 *  a polyMesh: cut cells that are not boxes, by the sum over the faces that reach the ball
 *  from the centre's located side, and by the general formula over the whole boundary,
 *  taken near a face plane or edge line; 0 elsewhere). Unknown keys
 *  give VFE_ERROR_INVALID_ARGUMENT. New facts get new keys, so vfe_report never changes. */
VFE_API vfe_status vfe_last_report_value(const vfe_engine* e, const char* key, double* out);

#ifdef __cplusplus
}
#endif

#endif /* VFE_VFE_H */
