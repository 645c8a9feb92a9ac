// C++ facade of the vfe engine. The C API (vfe.h) is a thin catch-all layer over this.
#pragma once

#include <vfe/error.hpp>
#include <vfe/vfe.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace vfe {

/// A uniform Cartesian grid: cells[d] cells of size spacing[d] from origin;
/// cell (i, j, k) has index i + nx*(j + ny*k). With first_cell, the grid is the block of
/// cells [first_cell, first_cell + cells) of the grid from origin: cell (i, j, k)'s lower
/// corner is origin + (first_cell + (i, j, k)) * spacing, computed as that larger grid
/// computes it, so a block's deposits equal the larger grid's bit for bit (libvfe_mpi).
struct CartesianGridSpec {
  std::array<double, 3> origin{0, 0, 0};
  std::array<double, 3> spacing{1, 1, 1};
  std::array<std::int64_t, 3> cells{1, 1, 1};
  std::array<std::int64_t, 3> first_cell{0, 0, 0};
};

/// An OpenFOAM polyMesh: the case folder, its constant folder or the polyMesh folder
/// itself (ASCII or binary, plain or gzipped files). Cells keep OpenFOAM's order.
struct PolyMeshSpec {
  std::string dir;
};

/// A rectilinear (graded Cartesian) grid: strictly increasing node coordinates per axis
/// (at least 2 each); cell (i, j, k) spans [x_i, x_i+1) x [y_j, y_j+1) x [z_k, z_k+1) and
/// has index i + nx*(j + ny*k). Served as a polyMesh of hexahedra (direct, pmm, exact)
/// whose axes may be periodic.
struct RectilinearGridSpec {
  std::array<std::vector<double>, 3> nodes;
};

/// A face-based mesh in the host's memory (vfe_create_polymesh_arrays): ordered as OpenFOAM
/// orders it, internal faces first (area vector from owner to neighbour), then boundary
/// faces; cells = 1 + max(owner). The arrays are copied; the engine equals the one
/// PolyMeshSpec gives for the same mesh.
struct PolyMeshArrays {
  std::int64_t n_points = 0;
  const double* points = nullptr;             ///< 3 per point
  std::int64_t n_faces = 0;
  const std::int64_t* face_offsets = nullptr; ///< n_faces + 1, from 0
  const std::int64_t* face_points = nullptr;  ///< face_offsets[n_faces]
  const std::int64_t* owner = nullptr;        ///< n_faces
  std::int64_t n_internal_faces = 0;
  const std::int64_t* neighbour = nullptr;    ///< n_internal_faces
};

/// An OpenFOAM polyMesh's arrays as its files hold them (read_polymesh_buffers); view()
/// gives the PolyMeshArrays of the same mesh (which takes no patches: boundary faces are the
/// faces after the internal ones).
struct PolyMeshBuffers {
  std::vector<double> points;  ///< 3 per point
  std::vector<std::int64_t> face_offsets{0}, face_points, owner, neighbour;
  /// The boundary file's patches (type "processor" for decomposePar's processor patches).
  struct Patch {
    std::string name, type;
    std::int64_t start_face = 0, n_faces = 0;
  };
  std::vector<Patch> patches;
  PolyMeshArrays view() const {
    return {static_cast<std::int64_t>(points.size() / 3), points.data(),
            static_cast<std::int64_t>(owner.size()),      face_offsets.data(),
            face_points.data(),                            owner.data(),
            static_cast<std::int64_t>(neighbour.size()),  neighbour.data()};
  }
};
/// Reads the polyMesh of a case, constant or polyMesh folder (as PolyMeshSpec) into memory;
/// throws Error as Engine(PolyMeshSpec) does.
VFE_API PolyMeshBuffers read_polymesh_buffers(const std::string& dir);
/// A labelList file of that polyMesh folder (plain or name.gz, ASCII or binary), e.g. the
/// pointProcAddressing, faceProcAddressing and cellProcAddressing decomposePar writes into
/// each processorN folder. Throws Error (VFE_ERROR_IO when missing, naming the file).
VFE_API std::vector<std::int64_t> read_polymesh_labels(const std::string& dir, const std::string& name);

/// Every method's name ("direct", "pmm", ...), in a fixed order.
VFE_API std::span<const std::string_view> method_names();

/// Zero-copy view of the host's particle arrays. Strides count doubles between
/// consecutive particles (0 = packed: 3 for centres, 1 for radii, 4 for orientations).
/// orientations may be null (quaternions w, x, y, z otherwise).
struct ParticleView {
  std::int64_t n = 0;
  const double* centres = nullptr;
  const double* radii = nullptr;
  const double* orientations = nullptr;
  /// Optional shape per particle (ids from Engine::add_shape); with shapes, radii are
  /// the shapes' scales lambda (lengths multiply by lambda, volumes by lambda^3).
  const std::int32_t* shape_ids = nullptr;
  std::int64_t centre_stride = 0;
  std::int64_t radius_stride = 0;
  std::int64_t orientation_stride = 0;
};

using Report = vfe_report;

/// deterministic=1 sums every cell in fixed point, as a whole number of units 2^exponent,
/// so that a sum does not depend on the order of its terms (threads, ranks, particles).
__extension__ typedef __int128 FixedSum;
/// The unit exponent for terms of magnitude at most `largest`: 2^-80 of it.
inline int fixed_unit_exponent(double largest) {
  return largest > 0 && std::isfinite(largest) ? std::ilogb(largest) - 80 : 0;
}
inline double from_fixed(FixedSum sum, int exponent) { return std::ldexp(static_cast<double>(sum), exponent); }

class VFE_API Engine {
 public:
  /// Builds an engine on a Cartesian grid; throws Error on invalid geometry.
  explicit Engine(const CartesianGridSpec& grid);
  /// Builds an engine on an OpenFOAM polyMesh; throws Error (I/O or invalid mesh).
  /// Methods there: direct and pmm (spheres and shapes), exact (spheres); the others
  /// answer VFE_ERROR_UNSUPPORTED.
  explicit Engine(const PolyMeshSpec& mesh);
  /// Builds an engine on a rectilinear grid; throws Error naming a bad node.
  explicit Engine(const RectilinearGridSpec& grid);
  /// Builds an engine on a face-based mesh from the host's memory; throws Error naming
  /// the bad face, label or cell.
  explicit Engine(const PolyMeshArrays& mesh);
  ~Engine();
  Engine(const Engine&) = delete;
  Engine& operator=(const Engine&) = delete;

  /// Applies "key=value key=value"; all or nothing. Throws Error naming the bad key.
  void configure(std::string_view options);
  /// Current value of an option as text (throws Error for an unknown key).
  std::string option(std::string_view key) const;
  /// All options and their current values, "key=value key=value".
  std::string options() const;

  std::int64_t cell_count() const;
  /// True for a polyMesh engine (OpenFOAM or rectilinear), false for a Cartesian grid.
  bool is_polymesh() const;
  /// Cell centres in cell order (3 values per cell: x, y, z).
  void cell_centres(std::span<double> out) const;
  /// The polyMesh's points (3 per point), and per cell its faces as point lists, for
  /// writers that draw the cells (VTK polyhedra): face_offsets has one entry per face plus
  /// one, face_points the points of each face, cell_face_offsets one entry per cell plus
  /// one into cell_faces. Throws Error on a Cartesian engine.
  struct PolyTopology {
    std::vector<double> points;
    std::vector<std::int64_t> face_offsets, face_points, cell_face_offsets, cell_faces;
  };
  PolyTopology poly_topology() const;
  /// Cell volumes in cell order.
  void cell_volumes(std::span<double> out) const;
  /// The cell holding each point (3 values per point) into cells, -1 for a point in no cell;
  /// the same cell a compute deposits a sub-element at that point into.
  void locate(std::span<const double> points, std::span<std::int64_t> cells) const;

  /// Solid volume per cell of the given spheres into out (overwritten). Throws Error;
  /// out is untouched on failure.
  void compute(const ParticleView& particles, std::span<double> out);
  /// The same from the C API's view (byte strides, optional host ids).
  void compute(const vfe_particles& particles, std::span<double> out);

  /// With weights=1: per particle of the last compute, its cells and the fraction of its
  /// volume in each (CSR); the fractions of a particle sum to 1 less its dropped share.
  struct WeightsSize {
    std::int64_t particles = 0, entries = 0;
  };
  WeightsSize weights_size() const;
  void weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells, std::span<double> fractions) const;
  /// out[c*k + j] = sum_p fraction_pc * values[p*k + j] (k = components; overwrites out).
  void deposit(std::int32_t components, std::span<const double> values, std::span<double> out) const;
  /// deposit() in fixed point: out[c*k + j] in units 2^exponents[j], which must bound the
  /// values (fixed_unit_exponent of the largest |value| of component j). A distributed
  /// mesh passes the exponents of all ranks' values, so owners add ghosts' sums exactly.
  void deposit_fixed(std::int32_t components, std::span<const double> values, std::span<const int> exponents,
                     std::span<FixedSum> out) const;
  /// deterministic=1 takes its unit from the largest particle volume of a compute; with a
  /// volume set here, from the larger of the two (0: none). Every rank of a distributed mesh
  /// sets the largest_particle_volume of all ranks, so all sum in the same unit.
  void set_deterministic_volume(double largest_particle_volume);
  /// The largest volume of the given particles, as a compute measures them (spheres and
  /// registered shapes; particles a compute would refuse are skipped).
  double largest_particle_volume(const vfe_particles& particles) const;
  /// After a compute with deterministic=1: the solid volume per cell in fixed point.
  struct FixedField {
    std::span<const FixedSum> sums;
    int exponent = 0;
  };
  FixedField fixed_solid() const;
  /// out[p*k + j] = sum_c fraction_pc * field[c*k + j] / sum_c fraction_pc (0 with no cell).
  void interpolate(std::int32_t components, std::span<const double> cell_field, std::span<double> out) const;
  /// Sends the engine's log to fn (null: back to stderr).
  void set_log_callback(vfe_log_fn fn, void* user);
  /// Void fraction of the last compute (clipped at alpha_min if set).
  void void_fraction(std::span<double> out) const;
  /// Facts about the last successful compute.
  const Report& last_report() const;
  /// One fact of the last compute by name (vfe_last_report_value's keys); throws Error
  /// for an unknown key.
  double last_report_value(std::string_view key) const;
  /// Sub-elements per particle that particle_grid resolves to for a particle of the
  /// given diameter in a cell of the given size (the template's actual size).
  std::int64_t particle_grid_for(double diameter, double cell_size) const;

  /// Registers a shape from a spec ("sphere" | "ellipsoid A B C" | "superquadric A B C E1 E2"
  /// | "clump x y z r; ..." | "mesh FILE"); returns its id. Throws Error.
  std::int32_t add_shape(std::string_view spec);
  /// Volume of a registered shape in its template units (scale 1).
  double shape_volume(std::int32_t id) const;
  /// How far a registered shape reaches from its origin (the particle's position) at scale 1
  /// in any rotation, in its template units: 1 for the sphere, else the distance to the
  /// farthest corner of its bounding box (a bound).
  double shape_reach(std::int32_t id) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vfe
