// The engine's method names, read through the C API (vfe_method_name), which the shared
// library exports.
#pragma once

#include <vfe/vfe.h>

#include <cstdint>
#include <string>
#include <vector>

namespace vfe::apps {

/// Every method's name ("direct", "pmm", ...), in the engine's order.
inline std::vector<std::string> engine_method_names() {
  std::vector<std::string> names;
  for (std::int32_t i = 0; const char* name = vfe_method_name(i); ++i) names.emplace_back(name);
  return names;
}

}  // namespace vfe::apps
