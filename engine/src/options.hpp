// Engine options: parsing "key=value key=value" and printing them back.
#pragma once

#include <vfe/vfe.h>

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace vfe {

/// automatic: method=auto, per sphere the cheapest of the fast path, pmm and exact (methods/hybrid.hpp).
enum class Method { direct, pmm, exact, divided, gaussian, porous_cube, big_particle, trilinear, automatic };
enum class TemplateFamily { spherical, fibonacci, voxel };
enum class Orientation { random, given, none };
enum class Outside { nearest, centre, drop, error };
enum class Accumulation { automatic, privatised, atomic, sorted };
/// automatic: blocked where it pays (particle_order.hpp), input: the host's order.
enum class ParticleOrder { automatic, input, blocked };

/// Side of the cube with the volume of a sphere of diameter 1: (pi / 6)^(1/3).
inline constexpr double kVolumeCube = 0.80599597700823482;

struct Options {
  Method method = Method::pmm;
  std::int64_t particle_grid = 0;  ///< 0 = auto
  /// Largest particle grid auto may choose: below chi ~ 0.6 the stability formula asks for
  /// tens of thousands of sub-elements per particle.
  std::int64_t particle_grid_max = 20000;
  /// fibonacci: the stress test (docs/stability.md) shows it stable at a consistent n for
  /// every orientation, where the spherical family's rings of coplanar centroids are not.
  TemplateFamily template_family = TemplateFamily::fibonacci;
  Orientation orientation = Orientation::random;
  Outside outside = Outside::nearest;
  /// outside=error: how far (in the host's length unit) a particle may reach beyond the
  /// mesh before it is an error; DEM wall contacts overlap a wall by micrometres.
  double outside_tolerance = 0;
  int threads = 0;  ///< 0 = all
  bool deterministic = false;
  double alpha_min = 0;
  Accumulation accumulation = Accumulation::automatic;
  std::uint64_t seed = 0;  ///< of the per-particle random template rotation
  unsigned periodic = 0;   ///< periodic axes: bit 0 x, bit 1 y, bit 2 z
  /// gaussian: standard deviation in particle diameters; about the sphere's own per-axis
  /// spread R / sqrt(5) = 0.224 d.
  double sigma = 0.25;
  /// porous_cube: cube side in particle diameters; (pi / 6)^(1/3): the cube of the
  /// sphere's volume.
  double gamma = kVolumeCube;
  /// particle_grid=auto's flux form (both > 0): the jump a step may cause is
  /// U_s dt_f / dx instead of the default pi / (6 * 27) of docs/design.md section 8. 0 = not given.
  double superficial_velocity = 0;
  double fluid_dt = 0;
  std::string log_level = "warn";
  // Work a scene may not need, each switchable so its saving can be measured
  // (docs/performance.md).
  bool fast_path = true;      ///< a particle inside one cell: one deposit, no sub-elements
  bool rotation_bank = true;  ///< orientation=random from a bank of pre-built rotations
  /// A polyMesh whose cells are a lattice of axis-aligned boxes computes on the grid of
  /// the same cells (0: the general polyMesh path).
  bool lattice = true;
  /// Keep each particle's deposits; the next compute redoes only particles that moved by
  /// more than move_tolerance (or changed radius, orientation or shape).
  bool incremental = false;
  double move_tolerance = 0;
  /// Clear, merge and sum only the cells particles touch instead of the whole field.
  bool touched_only = false;
  /// Keep per particle its cells and the fraction of its volume in each (vfe_weights).
  bool weights = false;
  /// Length of the conservative diffusion of the solid volume over the face graph; 0 = off.
  double smoothing_length = 0;
  /// blocked: compute a copy of the spheres bucketed by slabs of the field (particle_order.hpp).
  ParticleOrder particle_order = ParticleOrder::automatic;
};

/// Applies "key=value ..." on top of base; throws Error (invalid argument naming the key,
/// or unsupported for a known value not available yet). Nothing is changed on error.
Options parse_options(std::string_view text, const Options& base);

/// "key=value key=value" of every option.
std::string format_options(const Options& o);
/// Value of one option as text; throws Error for an unknown key.
std::string option_value(const Options& o, std::string_view key);

std::string_view to_string(Method m);
/// Every method's name, in the order of Method (also in the public engine.hpp).
VFE_API std::span<const std::string_view> method_names();

}  // namespace vfe
