// Fuzz target: the option string parser of vfe_configure (vfe::parse_options).
#include "fuzz_files.hpp"
#include "options.hpp"

#include <vfe/engine.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = vfe::fuzz::as_text(data, size);
  try {
    const vfe::Options o = vfe::parse_options(text, vfe::Options{});
    // What was accepted prints back to an option string that parses.
    (void)vfe::parse_options(vfe::format_options(o), vfe::Options{});
  } catch (const vfe::Error&) {
  }
  return 0;
}
