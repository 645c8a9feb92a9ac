// Particle shapes in template units, their exact mass properties, and their PMM templates.
#pragma once

#include <vfe/kernels/particle_template.hpp>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace vfe::kernels {

/// Limits on a shape's cost (README "Limits"). A mesh shape has at most this many
/// triangles; the STL/OBJ readers refuse larger files.
inline constexpr std::size_t kMaxMeshTriangles = std::size_t(1) << 22;  // 4194304
/// Most samples a shape's template is built from (make_shape_template).
inline constexpr std::size_t kMaxShapeSamples = 4000000;
/// Sampling walks vertical columns of a grid of spacing (volume / samples)^(1/3), and only
/// those a part of the body (a clump's sphere, a mesh's triangle) covers. A shape whose
/// parts cover more columns than this at kMaxShapeSamples, or whose extent spans more than
/// kMaxSampleSpan spacings along an axis, is refused when it is made: it is too thin, or
/// its parts too far apart, for its volume (a flat plate passes up to about 6000:1).
inline constexpr double kMaxSampleColumns = 8388608;  // 2^23
inline constexpr double kMaxSampleSpan = 2147483647;   // 2^31 - 1 (column indices are int)

/// Closed triangle surface; triangles list vertex indices counter-clockwise seen from
/// outside (outward normals).
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
};

/// "" when the mesh is closed and consistently oriented with outward normals (every edge
/// used exactly twice, in opposite directions; positive enclosed volume), otherwise a
/// message saying what is wrong and how to fix it.
std::string check_closed_mesh(const TriangleMesh& mesh);

/// Volume, centre of volume and second moment of volume about that centre
/// (integral of (x - c)(x - c)^T dV).
struct MassProperties {
  double volume = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second_moment = Eigen::Matrix3d::Zero();
};

/// Exact mass properties of a closed triangle mesh (divergence theorem over signed tetrahedra).
MassProperties mesh_mass_properties(const TriangleMesh& mesh);

/// Area of the union of disks (x, y, r) in the plane, exactly (Green's theorem over the
/// exposed arcs), with its first moments (integrals of x and y over the union).
struct DiskUnion {
  double area = 0, moment_x = 0, moment_y = 0;
};
DiskUnion disk_union(const std::vector<Eigen::Vector3d>& disks);

/// A body in its own template units, centred where its spec puts the origin (the
/// particle's position). Sphere: radius 1.
class Shape {
 public:
  enum class Kind { sphere, ellipsoid, superquadric, clump, mesh };

  static Shape sphere();
  /// Semi-axes a, b, c > 0.
  static Shape ellipsoid(double a, double b, double c);
  /// (|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1) <= 1, with 0.1 <= e1, e2 <= 2.
  static Shape superquadric(double a, double b, double c, double e1, double e2);
  /// Union of spheres (x, y, z, r); overlapping parts counted once.
  static Shape clump(std::vector<Eigen::Vector4d> spheres);
  /// Closed, consistently oriented triangle mesh (throws std::invalid_argument otherwise).
  static Shape mesh(TriangleMesh mesh);

  Kind kind() const { return kind_; }
  /// Semi-axes (ellipsoid, superquadric; 1 1 1 for the sphere).
  const Eigen::Vector3d& axes() const { return axes_; }
  std::string description() const;
  /// Exact volume (clump: union volume by exact slice areas integrated to 1e-12 relative).
  double volume() const { return props_.volume; }
  const Eigen::Vector3d& centroid() const { return props_.centroid; }
  /// Second moment about the centroid: exact for sphere, ellipsoid and mesh; from the
  /// template sampling (relative error ~1e-3) for superquadric and clump.
  const Eigen::Matrix3d& second_moment() const { return props_.second_moment; }
  /// Bounding box of the body itself (a mesh's unused vertices do not count).
  const Eigen::AlignedBox3d& bounds() const { return bounds_; }
  /// The clump's spheres (x, y, z, r); empty for other kinds.
  const std::vector<Eigen::Vector4d>& spheres() const { return spheres_; }
  /// The surface of a mesh shape (empty for the other kinds).
  const TriangleMesh& mesh() const { return mesh_; }

  /// The z-intervals where the vertical line through (x, y) lies inside the body, sorted
  /// and disjoint. `out` is cleared first.
  void column(double x, double y, std::vector<std::pair<double, double>>& out) const;
  bool contains(const Eigen::Vector3d& p) const;

 private:
  Kind kind_ = Kind::sphere;
  Eigen::Vector3d axes_{1, 1, 1};
  double e1_ = 1, e2_ = 1;
  std::vector<Eigen::Vector4d> spheres_;
  TriangleMesh mesh_;
  MassProperties props_;
  Eigen::AlignedBox3d bounds_;
};

/// Moments of a sampled body: sample points with equal volume weights.
struct SampledBody {
  std::vector<Eigen::Vector3d> points;
  double cell_volume = 0;  ///< volume each sample stands for
};

/// Columns of sample_shape's grid at `target` samples that the shape's parts cover (a
/// column covered by two parts counts twice), or throws std::invalid_argument, naming the
/// limit, when the shape is beyond kMaxSampleColumns or kMaxSampleSpan.
double check_sampling_cost(const Shape& shape, std::size_t target);

/// Midpoint samples of the body on a regular grid of about `target` points inside it. Its
/// cost is the columns the body's parts cover plus the samples (see kMaxSampleColumns);
/// throws std::invalid_argument past the limits (check_sampling_cost).
SampledBody sample_shape(const Shape& shape, std::size_t target);

/// PMM template of n sub-elements for the shape, in the shape's template units.
/// Sphere and ellipsoid: the spherical template (mapped by the semi-axes): exact
/// centroids and equal volumes. Others: the body is sampled on a fine grid and cut into n
/// compact parts of equal volume by recursive bisection along the widest axis; each part
/// is represented by its centroid. Volumes sum to 1 (fractions of the exact volume) and
/// the template's centre of volume is moved onto the exact centroid.
ParticleTemplate make_shape_template(const Shape& shape, int n);

/// The same from samples of the shape taken once (sample_shape; the cut reorders them, so
/// they are taken by value). n is capped at a twentieth of the samples.
ParticleTemplate make_shape_template(const Shape& shape, int n, std::vector<Eigen::Vector3d> samples);

/// Partition `variant` of the shape into n equal-volume sub-elements, so that particles
/// given different variants (a bank the driver picks from by particle index, as spheres
/// get a random rotation) do not share one partition whose layers of sub-element centroids
/// cross a cell face together. Variant 0 is make_shape_template(shape, n) unchanged.
/// Variant k >= 1: sphere and ellipsoid: the fibonacci template turned by the fixed
/// rotation random_rotation(k, .) about the shape's own centre, then mapped by the
/// semi-axes (an affine map keeps equal volumes and the centroid at the centre); other
/// shapes: midpoint samples on a lattice turned by that rotation and shifted by a fixed
/// fraction of its spacing, cut by recursive bisection along the lattice's own axes.
/// Every variant has exactly equal fractions 1/n summing to 1 and its centre of volume on
/// the shape's exact centroid. About samples_per_element samples per sub-element
/// (200k to 4M in all) are taken for the sampled shapes.
ParticleTemplate make_shape_template_variant(const Shape& shape, int n, std::uint32_t variant,
                                             std::size_t samples_per_element = 400);

}  // namespace vfe::kernels
