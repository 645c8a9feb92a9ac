#include "options.hpp"

#include <vfe/engine.hpp>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <vector>

namespace vfe {

namespace {

const char* const kKeys =
    "method, particle_grid, particle_grid_max, template, orientation, outside, threads, deterministic, alpha_min, "
    "periodic, accumulation, seed, sigma, gamma, superficial_velocity, fluid_dt, log_level, fast_path, rotation_bank, incremental, move_tolerance, "
    "touched_only";

[[noreturn]] void bad(std::string_view key, std::string_view value, std::string_view expected) {
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "option '" + std::string(key) + "': bad value '" +
                                              std::string(value) + "'; expected " + std::string(expected));
}

std::int64_t parse_int(std::string_view key, std::string_view v, std::int64_t lo, std::int64_t hi) {
  std::int64_t x = 0;
  auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size() || x < lo || x > hi)
    bad(key, v, "an integer from " + std::to_string(lo) + " to " + std::to_string(hi));
  return x;
}

double parse_double(std::string_view key, std::string_view v, double lo, double hi) {
  std::string s(v);
  char* end = nullptr;
  const double x = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(x) || x < lo || x > hi) {
    std::ostringstream e;
    e << "a number from " << lo << " to " << hi;
    bad(key, v, e.str());
  }
  return x;
}

/// A number in (0, hi].
double parse_positive(std::string_view key, std::string_view v, double hi) {
  const double x = parse_double(key, v, 0.0, hi);
  if (!(x > 0)) {
    std::ostringstream e;
    e << "a number > 0 and <= " << hi;
    bad(key, v, e.str());
  }
  return x;
}

/// Shortest text that reads back to the same double.
std::string number_text(double x) {
  char buf[32];
  for (int p = 6; p <= 17; ++p) {
    std::snprintf(buf, sizeof buf, "%.*g", p, x);
    if (std::strtod(buf, nullptr) == x) break;
  }
  return buf;
}

template <class E, std::size_t N>
E parse_enum(std::string_view key, std::string_view v, const std::pair<const char*, E> (&table)[N]) {
  std::string names;
  for (const auto& [name, value] : table) {
    if (v == name) return value;
    names += (names.empty() ? "" : ", ") + std::string(name);
  }
  bad(key, v, "one of " + names);
}

constexpr std::pair<const char*, Method> kMethods[] = {
    {"direct", Method::direct},           {"pmm", Method::pmm},
    {"exact", Method::exact},             {"divided", Method::divided},
    {"gaussian", Method::gaussian},       {"porous_cube", Method::porous_cube},
    {"big_particle", Method::big_particle}, {"trilinear", Method::trilinear}};
constexpr std::pair<const char*, TemplateFamily> kTemplates[] = {
    {"spherical", TemplateFamily::spherical}, {"fibonacci", TemplateFamily::fibonacci},
    {"voxel", TemplateFamily::voxel}};
constexpr std::pair<const char*, Orientation> kOrientations[] = {
    {"random", Orientation::random}, {"given", Orientation::given}, {"none", Orientation::none}};
constexpr std::pair<const char*, Outside> kOutside[] = {
    {"nearest", Outside::nearest}, {"centre", Outside::centre}, {"drop", Outside::drop}, {"error", Outside::error}};
constexpr std::pair<const char*, Accumulation> kAccumulation[] = {
    {"auto", Accumulation::automatic}, {"private", Accumulation::privatised},
    {"atomic", Accumulation::atomic}, {"sorted", Accumulation::sorted}};

template <class E, std::size_t N>
const char* name_of(E e, const std::pair<const char*, E> (&table)[N]) {
  for (const auto& [name, value] : table)
    if (value == e) return name;
  return "?";
}

void apply(Options& o, std::string_view key, std::string_view v) {
  if (key == "method") {
    o.method = parse_enum(key, v, kMethods);
  } else if (key == "particle_grid") {
    o.particle_grid = v == "auto" ? 0 : parse_int(key, v, 1, 10'000'000);
  } else if (key == "particle_grid_max") {
    o.particle_grid_max = parse_int(key, v, 1, 10'000'000);
  } else if (key == "template") {
    o.template_family = parse_enum(key, v, kTemplates);
  } else if (key == "orientation") {
    o.orientation = parse_enum(key, v, kOrientations);
  } else if (key == "outside") {
    o.outside = parse_enum(key, v, kOutside);
  } else if (key == "threads") {
    o.threads = static_cast<int>(parse_int(key, v, 0, 4096));
  } else if (key == "deterministic") {
    o.deterministic = parse_int(key, v, 0, 1) == 1;
  } else if (key == "alpha_min") {
    o.alpha_min = parse_double(key, v, 0.0, 1.0);
  } else if (key == "periodic") {
    unsigned mask = 0;
    if (v != "none") {
      for (char c : v) {
        if (c != 'x' && c != 'y' && c != 'z') bad(key, v, "none or a combination of x, y, z (e.g. xy)");
        mask |= 1u << (c - 'x');
      }
    }
    o.periodic = mask;
  } else if (key == "accumulation") {
    o.accumulation = parse_enum(key, v, kAccumulation);
  } else if (key == "seed") {
    o.seed = static_cast<std::uint64_t>(parse_int(key, v, 0, std::numeric_limits<std::int64_t>::max()));
  } else if (key == "sigma") {
    o.sigma = parse_positive(key, v, 100.0);
  } else if (key == "gamma") {
    o.gamma = parse_positive(key, v, 100.0);
  } else if (key == "superficial_velocity") {
    o.superficial_velocity = parse_double(key, v, 0.0, 1e30);
  } else if (key == "fluid_dt") {
    o.fluid_dt = parse_double(key, v, 0.0, 1e30);
  } else if (key == "log_level") {
    if (v != "trace" && v != "debug" && v != "info" && v != "warn" && v != "error" && v != "off")
      bad(key, v, "one of trace, debug, info, warn, error, off");
    o.log_level = std::string(v);
  } else if (key == "fast_path") {
    o.fast_path = parse_int(key, v, 0, 1) == 1;
  } else if (key == "rotation_bank") {
    o.rotation_bank = parse_int(key, v, 0, 1) == 1;
  } else if (key == "incremental") {
    o.incremental = parse_int(key, v, 0, 1) == 1;
  } else if (key == "move_tolerance") {
    o.move_tolerance = parse_double(key, v, 0.0, 1e30);
  } else if (key == "touched_only") {
    o.touched_only = parse_int(key, v, 0, 1) == 1;
  } else {
    throw Error(VFE_ERROR_INVALID_ARGUMENT,
                "unknown option '" + std::string(key) + "'; known options: " + kKeys);
  }
}

}  // namespace

Options parse_options(std::string_view text, const Options& base) {
  Options o = base;
  std::size_t pos = 0;
  while (pos < text.size()) {
    while (pos < text.size() && std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
    if (pos >= text.size()) break;
    std::size_t end = pos;
    while (end < text.size() && !std::isspace(static_cast<unsigned char>(text[end]))) ++end;
    const std::string_view token = text.substr(pos, end - pos);
    const std::size_t eq = token.find('=');
    if (eq == std::string_view::npos || eq == 0 || eq + 1 == token.size())
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "option '" + std::string(token) + "' is not of the form key=value (e.g. method=pmm)");
    apply(o, token.substr(0, eq), token.substr(eq + 1));
    pos = end;
  }
  return o;
}

std::string_view to_string(Method m) { return name_of(m, kMethods); }

std::string option_value(const Options& o, std::string_view key) {
  if (key == "method") return name_of(o.method, kMethods);
  if (key == "particle_grid") return o.particle_grid == 0 ? "auto" : std::to_string(o.particle_grid);
  if (key == "particle_grid_max") return std::to_string(o.particle_grid_max);
  if (key == "template") return name_of(o.template_family, kTemplates);
  if (key == "orientation") return name_of(o.orientation, kOrientations);
  if (key == "outside") return name_of(o.outside, kOutside);
  if (key == "threads") return std::to_string(o.threads);
  if (key == "deterministic") return o.deterministic ? "1" : "0";
  if (key == "alpha_min") return number_text(o.alpha_min);
  if (key == "sigma") return number_text(o.sigma);
  if (key == "gamma") return number_text(o.gamma);
  if (key == "superficial_velocity") return number_text(o.superficial_velocity);
  if (key == "fluid_dt") return number_text(o.fluid_dt);
  if (key == "periodic") {
    if (!o.periodic) return "none";
    std::string axes;
    for (int d = 0; d < 3; ++d)
      if ((o.periodic >> d) & 1u) axes += char('x' + d);
    return axes;
  }
  if (key == "accumulation") return name_of(o.accumulation, kAccumulation);
  if (key == "seed") return std::to_string(o.seed);
  if (key == "log_level") return o.log_level;
  if (key == "fast_path") return o.fast_path ? "1" : "0";
  if (key == "rotation_bank") return o.rotation_bank ? "1" : "0";
  if (key == "incremental") return o.incremental ? "1" : "0";
  if (key == "move_tolerance") return number_text(o.move_tolerance);
  if (key == "touched_only") return o.touched_only ? "1" : "0";
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "unknown option '" + std::string(key) + "'; known options: " + kKeys);
}

std::string format_options(const Options& o) {
  std::string out;
  for (const char* key : {"method", "particle_grid", "particle_grid_max", "template", "orientation", "outside", "threads",
                          "deterministic", "alpha_min", "periodic", "accumulation", "seed", "sigma", "gamma",
                          "superficial_velocity", "fluid_dt", "log_level", "fast_path", "rotation_bank",
                          "incremental", "move_tolerance", "touched_only"}) {
    if (!out.empty()) out += ' ';
    out += std::string(key) + "=" + option_value(o, key);
  }
  return out;
}

}  // namespace vfe
