// Fuzz target: the LIGGGHTS/LAMMPS dump reader. First byte: bit 0 = gzip the rest.
#include "dump_reader.hpp"
#include "fuzz_files.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const auto path = vfe::fuzz::scratch_dir() / "frames.dump";
  vfe::fuzz::write_file(path, vfe::fuzz::as_text(data + 1, size - 1), (data[0] & 1) != 0);
  try {
    const auto frames = vfe::apps::read_dump(path.string());
    for (const auto& f : frames)
      if (f.radii.size() != static_cast<std::size_t>(f.n) || f.centres.size() != 3 * f.radii.size()) __builtin_trap();
    (void)vfe::apps::read_dump_frame(path.string());
  } catch (const vfe::apps::DumpError&) {
  }
  return 0;
}
