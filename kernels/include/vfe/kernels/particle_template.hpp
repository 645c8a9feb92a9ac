// Particle templates of the particle meshing method (PMM): a unit sphere cut into
// sub-elements, each represented by its centroid and its share of the volume.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vfe/kernels/point_tree.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace vfe::kernels {

struct ParticleTemplate {
  /// Sub-element centroids of a sphere of radius 1 centred at the origin.
  std::vector<Eigen::Vector3d> points;
  /// Each sub-element's share of the particle volume; they sum to 1 (to round-off).
  std::vector<double> fractions;
  std::string family;  ///< "spherical", "fibonacci", "voxel" or "divided"
  double reach = 0;    ///< largest |point|: the template's points lie in this ball
  int shells = 0, bands = 0, sectors = 0;  ///< spherical family's layout; 0 for others
  int lattice = 0;     ///< voxel family: cubes per diameter; 0 for others
  /// The points as floats for counting sub-elements per octant (octant_split.hpp): x of
  /// every point, then y, then z, each padded with zeros to split_words x 64 values, all
  /// times kSplitScale.
  /// Empty unless prepare_octant_split made them (it needs equal fractions).
  std::vector<float> split_points;
  std::size_t split_words = 0;
  /// For more than kMostUngroupedWords x 64 points (octant_split.hpp), the points above
  /// are in groups of eight near one another (their order is not the template's), and
  /// these are balls holding the groups, scaled alike: centres x, y, z, then radii, each
  /// padded to split_words x 8 values. A split plane that misses a group's ball puts the
  /// whole group on one side.
  std::vector<float> split_groups;
  /// The points in a tree of balls (point_tree.hpp), for meshes whose cells locate points one
  /// by one (polyMesh); empty unless made (the engine makes it for large templates).
  PointTree tree;

  std::size_t size() const { return points.size(); }
};

/// Equal-volume radial shells x equal-solid-angle polar bands x azimuthal sectors,
/// each sub-element at its true centroid. Uses the layout whose size is nearest to n
/// (preferring near-cubical sub-elements); n = 1 gives the centre.
ParticleTemplate make_spherical_template(int n);

/// n equal-volume points: radii stratified in r^3 (equal-volume shells, one point each),
/// directions on a Fibonacci spiral, radial order decorrelated from the spiral, the set
/// recentred so its centroid is the origin. Any n >= 1.
ParticleTemplate make_fibonacci_template(int n);

/// Cube subdivision: the sphere's bounding cube cut into m x m x m equal cubes; the cubes
/// whose centres lie in the sphere are the sub-elements, each at its cube's centre with an
/// equal share of the volume (their volumes rescaled so they sum to the sphere's volume
/// exactly). m is chosen so the count is nearest to n (the smaller m on a tie); the cube
/// centres are (2i + 1)/m - 1 per axis, never on the sphere itself. n = 1 gives the centre.
ParticleTemplate make_voxel_template(int n);

/// Number of cube centres (2i + 1)/m - 1 (i, j, k < m) inside the unit sphere.
std::int64_t voxel_count(int m);

/// Shells x bands x sectors the spherical family uses for a requested size n.
Eigen::Vector3i spherical_layout(int n);

/// Fixed pseudo-random rotation (uniform on SO(3)) for a particle index and a seed.
Eigen::Matrix3d random_rotation(std::uint64_t index, std::uint64_t seed);

/// The same kind of rotation drawn from a fixed bank of 4096 (built once per process):
/// (index, seed) picks one by a hash. What PMM uses per particle: a lookup instead of a
/// few sines and cosines; 4096 distinct orientations are plenty to break the alignment of
/// template points with cell faces.
const Eigen::Matrix3d& banked_random_rotation(std::uint64_t index, std::uint64_t seed);

/// The same matrix of the same bank as floats, row by row (9 values; half the bytes, for
/// code that compares in float).
const float* banked_random_rotation_rows(std::uint64_t index, std::uint64_t seed);

/// Rotations in the bank.
inline constexpr std::size_t kRotationBankSize = 4096;

/// The bank's rotation in slot `slot` (< kRotationBankSize): banked_random_rotation of
/// (index, seed) is banked_rotation(rotation_bank_slot(index, seed)).
const Eigen::Matrix3d& banked_rotation(std::size_t slot);

/// rotation_bank_slot in place, on any unsigned 64-bit type: a scalar, or a GCC vector of
/// them (several particles' slots at once, lane by lane the same values; in place, since
/// returning a 256-bit vector would change the ABI of a build without AVX).
template <class U>
[[gnu::always_inline]] inline void rotation_bank_slots(U& z, std::uint64_t seed) {
  // Every constant a std::uint64_t: Clang takes a scalar into a vector operation only of
  // the vector's own element type (unsigned long, not unsigned long long).
  constexpr std::uint64_t k1 = 0x9E3779B97F4A7C15ull, k2 = 0xD1B54A32D192ED03ull, k3 = 0x632BE59BD9B4E019ull,
                          k4 = 0xBF58476D1CE4E5B9ull, k5 = 0x94D049BB133111EBull,
                          mask = std::uint64_t(kRotationBankSize - 1);
  z = z * k1 + std::uint64_t(seed * k2 + k3);
  z = (z ^ (z >> 30)) * k4;
  z = (z ^ (z >> 27)) * k5;
  z ^= z >> 31;
  z &= mask;
}

/// The bank slot of (index, seed): a hash, so neighbouring indices get unrelated rotations.
inline std::size_t rotation_bank_slot(std::uint64_t index, std::uint64_t seed) {
  rotation_bank_slots(index, seed);
  return static_cast<std::size_t>(index);
}

/// The whole bank as floats, slot after slot, 9 values each (banked_random_rotation_rows
/// of (index, seed) is this + 9 * rotation_bank_slot(index, seed)): for loops that look up
/// many particles' rotations without a call each.
const float* banked_rotation_rows_table();

/// R rounded to floats, row by row: the layout banked_random_rotation_rows gives.
inline void rotation_rows(const Eigen::Matrix3d& R, float rows[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rows[3 * i + j] = static_cast<float>(R(i, j));
}

/// Rotation matrix of a quaternion (w, x, y, z), normalised first.
inline Eigen::Matrix3d rotation_from_quaternion(const double* q) {
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

/// PMM's locate step for one particle on a block of cells: template point q maps to
/// x = base + transform * q in cell units relative to the block, and lands in block cell
/// clamp(floor(x_d), 0, m_d - 1) per axis; out[s] = i + m0 * (j + m1 * k). Requires
/// x_d > -2^31 (the caller keeps base small). Branch-free so the compiler vectorises it.
void locate_in_block(const ParticleTemplate& tmpl, const Eigen::Vector3d& base, const Eigen::Matrix3d& transform,
                     const std::int64_t m[3], std::int32_t* out);

/// PMM kernel for one particle: every sub-element's volume goes to the cell that holds
/// its centroid. `transform` maps template points (unit sphere) to space: the rotation
/// scaled by the radius. locate(point) -> cell (any integer type; the sink interprets
/// it); sink(cell, point, volume).
template <class Locate, class Sink>
inline void pmm_deposit(const ParticleTemplate& tmpl, const Eigen::Vector3d& centre,
                        const Eigen::Matrix3d& transform, double particle_volume,
                        Locate&& locate, Sink&& sink) {
  const std::size_t n = tmpl.points.size();
  for (std::size_t s = 0; s < n; ++s) {
    const Eigen::Vector3d p = centre + transform * tmpl.points[s];
    sink(locate(p), p, particle_volume * tmpl.fractions[s]);
  }
}

}  // namespace vfe::kernels
