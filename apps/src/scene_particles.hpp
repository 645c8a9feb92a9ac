// The particles of a scene: a dump frame (spheres, or shapes by type) or generated shaped
// particles, with the shapes registered on every engine in the config's order.
#pragma once

#include "config.hpp"
#include "dump_reader.hpp"

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace vfe::apps {

struct SceneParticles {
  std::int64_t timestep = 0;
  std::int64_t n = 0;
  std::array<double, 6> box{0, 0, 0, 0, 0, 0};  ///< dump BOX BOUNDS, or the generator's box
  std::string source_name;                      ///< dump file name, or "generated"
  std::vector<double> centres;                  ///< 3n
  std::vector<double> radii;                    ///< n: radii, or the shapes' scales when shaped
  std::vector<double> orientations;             ///< 4n quaternions (w, x, y, z), or empty
  std::vector<double> velocities;               ///< 3n (the dump's vx vy vz), or empty
  std::vector<std::int64_t> ids;                ///< n (the dump's id column), or empty
  std::vector<std::int32_t> shape_ids;          ///< n indices into the config's shapes, or empty (spheres)
  std::vector<double> shape_volumes;            ///< per shape of the config, at scale 1
  /// Engine options the particles need (orientation=given with quaternions, orientation=none
  /// for unrotated generated shapes); the config's options come after and win.
  std::string options;

  bool shaped() const { return !shape_ids.empty(); }
  /// Zero-copy view for Engine::compute (orientations and shape ids when present).
  vfe::ParticleView view() const;
  /// Solid volume: spheres 4/3 pi r^3, shapes volume * scale^3.
  double total_volume() const;
  /// Solid volume of each particle (n).
  std::vector<double> volumes() const;
  /// Mean volume-equivalent diameter (the diameter for spheres); 0 when empty.
  double mean_diameter() const;
};

/// Registers the config's shapes on an engine, in order (shape id i = config.shapes[i]).
/// Throws ConfigError naming the config and the shape.
void register_shapes(const SceneConfig& config, vfe::Engine& engine);

/// Reads the dump frame or generates the particles. Throws DumpError or ConfigError (a dump
/// value shape_by_type does not map, no shape/type column, a series of frames, ...).
SceneParticles load_particles(const SceneConfig& config);

/// The particles of one dump frame (file names it in messages): spheres, or shapes by the
/// config's shape_by_type. Throws ConfigError as load_particles.
SceneParticles particles_from_dump(const SceneConfig& config, DumpFrame&& frame, const std::filesystem::path& file,
                                   std::vector<double> shape_volumes);

/// With coupling: true the particles must carry velocities (the dump's vx vy vz, for Us):
/// throws ConfigError naming the config, the frame's dump (and timestep) and the fix.
void check_coupling_velocities(const SceneConfig& config, const SceneParticles& particles);

/// The scale-1 volume of each of the config's shapes (registered on a probe engine).
std::vector<double> config_shape_volumes(const SceneConfig& config);

/// count particles of one shape: centres uniform in box, unit quaternions uniform over
/// rotations (empty for orientations: none); deterministic for a seed on every platform.
void generate_particles(const GenerateSpec& spec, std::vector<double>& centres, std::vector<double>& orientations);

}  // namespace vfe::apps
