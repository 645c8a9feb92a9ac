// Fuzz target: YAML scene configs (parse_config) and the Cartesian grids they resolve to.
#include "cartesian_grid.hpp"
#include "config.hpp"
#include "fuzz_files.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(vfe::fuzz::as_text(data, size));
  try {
    const vfe::apps::SceneConfig c = vfe::apps::parse_config(text, vfe::fuzz::scratch_dir(), "fuzz.yaml");
    const std::array<double, 6> box{0, 0.02, 0, 0.02, 0, 0.06};
    for (const auto& m : c.meshes) {
      if (m.type != "cartesian") continue;
      try {
        const vfe::CartesianGrid grid(vfe::apps::resolve_grid(m, &box, "fuzz.yaml"));
        if (!(grid.cell_volume() > 0) || grid.cell_count() < 1) __builtin_trap();
      } catch (const vfe::Error&) {
      }
    }
  } catch (const vfe::apps::ConfigError&) {
  } catch (const vfe::Error&) {
  }
  return 0;
}
