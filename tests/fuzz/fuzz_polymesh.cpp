// Fuzz target: the OpenFOAM polyMesh reader and the mesh built from it (vfe_create_polymesh).
// Input: one flag byte (bit 0: gzip every file), then the files points, faces, owner,
// neighbour and boundary in that order, separated by the line "//@@". Files past the last
// separator are missing (the reader must say so).
#include "fuzz_files.hpp"

#include <vfe/vfe.h>

#include <array>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const bool gzip = (data[0] & 1) != 0;
  std::string_view rest = vfe::fuzz::as_text(data + 1, size - 1);
  const auto dir = vfe::fuzz::scratch_dir() / "polyMesh";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  constexpr std::array<const char*, 5> names = {"points", "faces", "owner", "neighbour", "boundary"};
  constexpr std::string_view separator = "\n//@@\n";
  for (std::size_t i = 0; i < names.size() && rest.data() != nullptr; ++i) {
    const std::size_t end = rest.find(separator);
    const std::string_view file = rest.substr(0, end);
    vfe::fuzz::write_file(dir / (std::string(names[i]) + (gzip ? ".gz" : "")), file, gzip);
    if (end == std::string_view::npos) break;
    rest.remove_prefix(end + separator.size());
  }
  vfe_engine* e = nullptr;
  if (vfe_create_polymesh(dir.string().c_str(), &e) == VFE_OK) {
    // A mesh that was accepted must be usable.
    if (vfe_cell_count(e) < 1) __builtin_trap();
    vfe_destroy(e);
  } else if (e != nullptr) {
    __builtin_trap();  // a failed call leaves the output untouched
  }
  return 0;
}
