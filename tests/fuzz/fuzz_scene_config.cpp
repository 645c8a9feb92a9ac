// Fuzz target: YAML scene configs (parse_config) and the Cartesian grids they resolve to
// (engines built on the small ones).
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
        const vfe::CartesianGridSpec g = vfe::apps::resolve_grid(m, &box, "fuzz.yaml");
        // The engine validates the grid; build it only when its fields are small.
        if (double(g.cells[0]) * double(g.cells[1]) * double(g.cells[2]) > 1e6) continue;
        const vfe::Engine engine(g);
        if (engine.cell_count() < 1) __builtin_trap();
      } catch (const vfe::Error&) {
      }
    }
  } catch (const vfe::apps::ConfigError&) {
  } catch (const vfe::Error&) {
  }
  return 0;
}
