// VTK XML writers of cell fields, readable by ParaView: ImageData (.vti) for Cartesian
// grids, UnstructuredGrid (.vtu) of polyhedra for OpenFOAM polyMeshes.
#pragma once

#include <vfe/engine.hpp>

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace vfe::apps {

struct CellArray {
  std::string name;
  std::vector<double> values;  ///< components per cell, cell (i, j, k) at i + nx*(j + ny*k) on a grid
  int components = 1;          ///< 3 for a vector field (x, y, z of a cell together)
};

enum class VtkEncoding { ascii, base64 };

/// Writes cell data arrays on the grid as a .vti file. Throws std::runtime_error if an
/// array has the wrong size or the file cannot be written.
void write_vti(const std::filesystem::path& file, const vfe::CartesianGridSpec& grid,
               const std::vector<CellArray>& arrays, VtkEncoding encoding = VtkEncoding::base64);

/// Writes cell data arrays on a polyhedral mesh as a .vtu file: every cell a VTK_POLYHEDRON
/// (type 42) with its faces (the legacy `faces` / `faceoffsets` arrays), each face turned so
/// its normal points out of the cell (decided with cell_centres, 3 values per cell).
/// Throws std::runtime_error if the topology is inconsistent, an array has the wrong size
/// or the file cannot be written.
void write_vtu(const std::filesystem::path& file, const vfe::Engine::PolyTopology& topology,
               std::span<const double> cell_centres, const std::vector<CellArray>& arrays,
               VtkEncoding encoding = VtkEncoding::base64);

/// Writes particles as a .vtp PolyData of points (one vertex each) with point arrays: radius
/// (n), velocity (3n, omitted when empty) and id (n, omitted when empty). Throws
/// std::runtime_error if an array has the wrong size or the file cannot be written.
void write_vtp(const std::filesystem::path& file, std::span<const double> centres, std::span<const double> radii,
               std::span<const double> velocities, std::span<const std::int64_t> ids,
               VtkEncoding encoding = VtkEncoding::base64);

/// One entry of a ParaView collection: a data file at a time.
struct PvdEntry {
  double time = 0;
  std::filesystem::path file;  ///< relative to the .pvd file's folder
};

/// Writes a ParaView .pvd collection listing the files in the order given, each at its time.
void write_pvd(const std::filesystem::path& file, const std::vector<PvdEntry>& entries);

}  // namespace vfe::apps
