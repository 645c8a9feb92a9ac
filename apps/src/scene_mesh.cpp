#include "scene_mesh.hpp"

#include <algorithm>
#include <cmath>

namespace vfe::apps {

double SceneMesh::cube_root_of_mean_volume() const {
  double sum = 0;
  for (double v : cell_volumes) sum += v;
  return std::cbrt(sum / static_cast<double>(std::max<std::size_t>(cell_volumes.size(), 1)));
}

double SceneMesh::mean_cube_root_volume() const {
  double sum = 0;
  for (double v : cell_volumes) sum += std::cbrt(v);
  return sum / static_cast<double>(std::max<std::size_t>(cell_volumes.size(), 1));
}

namespace {

/// The engine of a mesh; grid is the resolved grid of a Cartesian mesh.
std::unique_ptr<vfe::Engine> mesh_engine(const MeshSpec& mesh, const vfe::CartesianGridSpec& grid) {
  std::unique_ptr<vfe::Engine> e;
  with_mesh_context(mesh, "", [&] {
    if (mesh.type == "polymesh")
      e = std::make_unique<vfe::Engine>(vfe::PolyMeshSpec{mesh.path.string()});
    else if (mesh.type == "rectilinear")
      e = std::make_unique<vfe::Engine>(vfe::RectilinearGridSpec{mesh.nodes});
    else
      e = std::make_unique<vfe::Engine>(grid);
  });
  return e;
}

}  // namespace

SceneMesh build_scene_mesh(const MeshSpec& mesh, const std::array<double, 6>* particles_box,
                           const std::string& source) {
  SceneMesh m;
  if (mesh.type == "rectilinear") {
    for (int d = 0; d < 3; ++d) m.cells_per_axis[d] = static_cast<std::int64_t>(mesh.nodes[d].size()) - 1;
  } else if (mesh.type != "polymesh") {
    m.grid = resolve_grid(mesh, particles_box, source, &m.note);
    m.cells_per_axis = m.grid.cells;
  }
  m.engine = mesh_engine(mesh, m.grid);
  m.cell_volumes.resize(static_cast<std::size_t>(m.engine->cell_count()));
  m.engine->cell_volumes(m.cell_volumes);
  return m;
}

std::unique_ptr<vfe::Engine> another_engine(const MeshSpec& mesh, const SceneMesh& built) {
  return mesh_engine(mesh, built.grid);
}

std::vector<MeshSpec> scene_meshes(const SceneConfig& cfg, const std::vector<double>& chis, double mean_diameter) {
  if (!chis.empty() && !(mean_diameter > 0))
    throw ConfigError(cfg.source.string() +
                      ": chi: [...] needs particles to size the cells (the frame has none); list meshes instead");
  std::vector<MeshSpec> meshes = cfg.meshes;
  for (double chi : chis) meshes.push_back(chi_mesh(chi, mean_diameter));
  return meshes;
}

}  // namespace vfe::apps
