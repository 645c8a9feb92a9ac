// Fuzz target: shapes through vfe_add_shape. First byte: 0 = the rest is an ASCII or binary
// STL file, 1 = an OBJ file, otherwise the rest is a shape spec ("ellipsoid 1 2 3", ...).
#include "fuzz_files.hpp"

#include <vfe/vfe.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view rest = vfe::fuzz::as_text(data + 1, size - 1);
  std::string spec;
  if (data[0] % 3 < 2) {
    const auto path = vfe::fuzz::scratch_dir() / (data[0] % 3 == 0 ? "shape.stl" : "shape.obj");
    vfe::fuzz::write_file(path, rest);
    spec = "mesh " + path.string();
  } else {
    // Superquadrics and clumps are sampled when they are made: keep specs short.
    if (rest.size() > 512) return 0;
    spec.assign(rest.data(), rest.size());
    if (spec.find('\0') != std::string::npos) return 0;
  }
  const double origin[3] = {0, 0, 0}, spacing[3] = {1, 1, 1};
  const int64_t cells[3] = {2, 2, 2};
  vfe_engine* e = nullptr;
  if (vfe_create_cartesian(origin, spacing, cells, &e) != VFE_OK) __builtin_trap();
  int32_t id = -7;
  const vfe_status s = vfe_add_shape(e, spec.c_str(), &id);
  if (s == VFE_ERROR_INTERNAL) __builtin_trap();  // every bad input has its own status
  if (s != VFE_OK && id != -7) __builtin_trap();  // output untouched on failure
  vfe_destroy(e);
  return 0;
}
