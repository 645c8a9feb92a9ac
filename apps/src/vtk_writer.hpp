// VTK XML ImageData (.vti) writer for Cartesian cell fields, readable by ParaView.
#pragma once

#include <vfe/engine.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace vfe::apps {

struct CellArray {
  std::string name;
  std::vector<double> values;  ///< one per cell, cell (i, j, k) at i + nx*(j + ny*k)
};

enum class VtkEncoding { ascii, base64 };

/// Writes cell data arrays on the grid as a .vti file. Throws std::runtime_error if an
/// array has the wrong size or the file cannot be written.
void write_vti(const std::filesystem::path& file, const vfe::CartesianGridSpec& grid,
               const std::vector<CellArray>& arrays, VtkEncoding encoding = VtkEncoding::base64);

}  // namespace vfe::apps
