// What `vfe run` does the same way for one frame and for a series of frames: the methods
// and their checked option strings, the mesh line of the log, and the field writers.
#pragma once

#include "config.hpp"
#include "foam_writer.hpp"
#include "run.hpp"
#include "scene_mesh.hpp"
#include "scene_particles.hpp"
#include "vtk_writer.hpp"

#include <spdlog/logger.h>

#include <filesystem>
#include <string>
#include <vector>

namespace vfe::apps {

/// The methods of a run and the option strings they compute with.
struct MethodPlan {
  std::string defaults;  ///< the engine's default options
  std::string global;    ///< the scene's options over them (threads, particle options, config, command line)
  std::vector<MethodSpec> methods;  ///< one per setting
  MethodSpec reference;
  bool reference_listed = false;  ///< the reference is one of the methods
  int threads = 0;                ///< threads the engine uses (0 resolved to the count)

  /// The full option string of a method: defaults, then global, then its own.
  std::string options_for(const MethodSpec& m) const;
  /// The method whose field a CFD solver reads as plain `voidfraction`: the one run with the
  /// engine's default options (e.g. plain pmm), else the first.
  std::string default_label() const;
  /// "exact", or "label (method options)" when the reference is not a plain method.
  std::string reference_title() const;
};

/// Checks every method's options (and the reference's) on a one-cell engine, so a typo fails
/// before any particle is read. Throws ConfigError naming the config and the method.
MethodPlan plan_methods(const SceneConfig& config, const RunOptions& options);

/// Puts the particle source's options (e.g. orientation=given) under the config's.
void add_particle_options(MethodPlan& plan, const SceneConfig& config, const RunOptions& options,
                          const std::string& particle_options);

/// ", a lattice of box cells" for a polyMesh the engine computes on the grid of the same
/// cells (option lattice), else "".
const char* lattice_note(const MeshSpec& mesh, const SceneMesh& built);

/// Logs the mesh's size and chi (mean chi on a polyMesh or rectilinear grid).
void log_mesh(spdlog::logger& log, const MeshSpec& mesh, const SceneMesh& built, double chi);

/// One method's fields of one compute, kept for the writers.
struct MethodField {
  std::string label;
  std::vector<double> eps, solid;
  std::string options;
  std::vector<double> us;  ///< coupling: Us, 3 per cell (else empty)
};

/// Us per cell of the engine's last compute of particles (weights=1): the deposit of
/// velocity x volume over the deposit of volume, (0, 0, 0) where no solid is; 3 per cell.
std::vector<double> particle_velocity_field(const vfe::Engine& engine, const SceneParticles& particles);

/// The engine's per-particle weights of its last compute of particles (weights=1) as CSV:
/// particle (index in the frame), id (the dump's, when it has ids), cell, fraction of the
/// particle's volume in that cell.
void write_weights_csv(const std::filesystem::path& file, const vfe::Engine& engine, const SceneParticles& particles);

/// The VTK cell arrays of the fields: voidfraction_<label>, solid_volume_<label>, Us_<label>.
std::vector<CellArray> field_arrays(const std::vector<MethodField>& fields);

/// Writes the arrays on the mesh as stem.vti (Cartesian) or stem.vtu (polyMesh,
/// rectilinear); returns the file written.
std::filesystem::path write_mesh_vtk(const std::filesystem::path& stem, const SceneMesh& built,
                                     const std::vector<CellArray>& arrays);

/// Writes one OpenFOAM time folder: voidfraction_<label> (and Us_<label>) per field, and
/// plain voidfraction (and Us) from the default method, else the first method that ran.
void write_foam_time(const std::filesystem::path& time_dir, const std::string& time_name,
                     const std::vector<MethodField>& fields, const MethodPlan& plan,
                     const std::vector<FoamPatch>& patches, spdlog::logger& log);

}  // namespace vfe::apps
