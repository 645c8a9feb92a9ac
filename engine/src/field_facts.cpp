#include "field_facts.hpp"

namespace vfe::detail {
namespace {

void uniform_baseline(const double* f, std::int64_t begin, std::int64_t end, double volume, double alpha_min,
                      FieldFacts& facts) {
  add_field_facts(f, begin, end, [volume](std::int64_t) { return volume; }, alpha_min, facts);
}

#ifdef VFE_HAS_V3_BUILD
// The same source for AVX2: the baseline build's 64-bit lane masks cost scalar compares.
__attribute__((target("arch=x86-64-v3"))) void uniform_v3(const double* f, std::int64_t begin, std::int64_t end,
                                                           double volume, double alpha_min, FieldFacts& facts) {
  add_field_facts(f, begin, end, [volume](std::int64_t) { return volume; }, alpha_min, facts);
}
#endif

}  // namespace

void add_uniform_field_facts(const double* f, std::int64_t begin, std::int64_t end, double volume, double alpha_min,
                             FieldFacts& facts) {
#ifdef VFE_HAS_V3_BUILD
  if (cpu_has_x86_64_v3()) return uniform_v3(f, begin, end, volume, alpha_min, facts);
#endif
  uniform_baseline(f, begin, end, volume, alpha_min, facts);
}

}  // namespace vfe::detail
