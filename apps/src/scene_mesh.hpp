// One mesh of a scene built into an engine, the same way for every command: a Cartesian
// grid (listed, or one per chi value), a rectilinear grid or an OpenFOAM polyMesh.
#pragma once

#include "config.hpp"

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace vfe::apps {

/// A scene mesh's engine and the cell facts the reports need.
struct SceneMesh {
  std::unique_ptr<vfe::Engine> engine;
  vfe::CartesianGridSpec grid;  ///< the Cartesian grid (cartesian meshes only)
  /// Cells per axis (cartesian and rectilinear meshes); {0, 0, 0} on a polyMesh.
  std::array<std::int64_t, 3> cells_per_axis{0, 0, 0};
  std::vector<double> cell_volumes;
  std::string note;  ///< what resolve_grid had to adjust (cartesian meshes), else ""

  bool polymesh() const { return engine && engine->is_polymesh(); }
  /// Cube root of the mean cell volume.
  double cube_root_of_mean_volume() const;
  /// Mean over the cells of the cube root of each cell's volume (the cell size a particle
  /// meets in a typical cell of a graded or refined mesh).
  double mean_cube_root_volume() const;
};

/// Runs f; an engine Error gets the mesh (and what ran on it, when given) in its message.
template <class F>
void with_mesh_context(const MeshSpec& mesh, const std::string& what, F&& f) {
  try {
    f();
  } catch (const vfe::Error& e) {
    throw vfe::Error(e.status(), "mesh '" + mesh.name + "'" + (what.empty() ? std::string() : ", " + what) + ": " +
                                     e.what());
  }
}

/// Builds the engine of one scene mesh; particles_box is needed by bounds: particles_box.
/// Engine errors are rethrown naming the mesh. Throws ConfigError or vfe::Error.
SceneMesh build_scene_mesh(const MeshSpec& mesh, const std::array<double, 6>* particles_box,
                           const std::string& source);

/// Another engine on the mesh of built (a series keeps one engine per method, so that each
/// method's incremental state and templates carry from frame to frame); a polyMesh is read
/// again. Engine errors are rethrown naming the mesh.
std::unique_ptr<vfe::Engine> another_engine(const MeshSpec& mesh, const SceneMesh& built);

/// The listed meshes of a scene followed by one Cartesian grid per chi value (cells of chi
/// x mean_diameter). Throws ConfigError when chi values are given without particles.
std::vector<MeshSpec> scene_meshes(const SceneConfig& cfg, const std::vector<double>& chis, double mean_diameter);

}  // namespace vfe::apps
