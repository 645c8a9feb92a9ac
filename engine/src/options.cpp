#include "options.hpp"

#include <vfe/error.hpp>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <vector>

namespace vfe {

namespace {

/// An option's value as quoted in a message: long values are cut, so a 4 MiB option string
/// never becomes a 4 MiB message.
std::string quoted(std::string_view v) {
  constexpr std::size_t kMax = 64;
  if (v.size() <= kMax) return "'" + std::string(v) + "'";
  return "'" + std::string(v.substr(0, kMax)) + "...' (" + std::to_string(v.size()) + " characters)";
}

[[noreturn]] void bad(std::string_view key, std::string_view value, std::string_view expected) {
  throw Error(VFE_ERROR_INVALID_ARGUMENT,
              "option '" + std::string(key) + "': bad value " + quoted(value) + "; expected " + std::string(expected));
}

std::int64_t parse_int(std::string_view key, std::string_view v, std::int64_t lo, std::int64_t hi) {
  std::int64_t x = 0;
  auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size() || x < lo || x > hi)
    bad(key, v, "an integer from " + std::to_string(lo) + " to " + std::to_string(hi));
  return x;
}

bool parse_bool(std::string_view key, std::string_view v) { return parse_int(key, v, 0, 1) == 1; }

double parse_double(std::string_view key, std::string_view v, double lo, double hi) {
  double x = 0;
  auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || p != v.data() + v.size() || !std::isfinite(x) || x < lo || x > hi) {
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

template <class E, std::size_t N>
const char* name_of(E e, const std::pair<const char*, E> (&table)[N]) {
  for (const auto& [name, value] : table)
    if (value == e) return name;
  return "?";
}

constexpr std::pair<const char*, Method> kMethods[] = {
    {"direct", Method::direct},           {"pmm", Method::pmm},
    {"exact", Method::exact},             {"divided", Method::divided},
    {"gaussian", Method::gaussian},       {"porous_cube", Method::porous_cube},
    {"big_particle", Method::big_particle}, {"trilinear", Method::trilinear},
    {"auto", Method::automatic}};
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
constexpr std::pair<const char*, ParticleOrder> kParticleOrders[] = {
    {"auto", ParticleOrder::automatic}, {"input", ParticleOrder::input}, {"blocked", ParticleOrder::blocked}};
constexpr const char* kLogLevels[] = {"trace", "debug", "info", "warn", "error", "off"};

std::string print_bool(bool b) { return b ? "1" : "0"; }

/// One option: its key, how its value is read into Options and printed back.
struct OptionSpec {
  const char* key;
  void (*parse)(Options&, std::string_view key, std::string_view value);
  std::string (*print)(const Options&);
};

// The options, in the order format_options prints them. A new option is one row here.
const OptionSpec kOptions[] = {
    {"method", [](Options& o, std::string_view k, std::string_view v) { o.method = parse_enum(k, v, kMethods); },
     [](const Options& o) { return std::string(name_of(o.method, kMethods)); }},
    {"particle_grid",
     [](Options& o, std::string_view k, std::string_view v) {
       o.particle_grid = v == "auto" ? 0 : parse_int(k, v, 1, 10'000'000);
     },
     [](const Options& o) { return o.particle_grid == 0 ? std::string("auto") : std::to_string(o.particle_grid); }},
    {"particle_grid_max",
     [](Options& o, std::string_view k, std::string_view v) { o.particle_grid_max = parse_int(k, v, 1, 10'000'000); },
     [](const Options& o) { return std::to_string(o.particle_grid_max); }},
    {"template",
     [](Options& o, std::string_view k, std::string_view v) { o.template_family = parse_enum(k, v, kTemplates); },
     [](const Options& o) { return std::string(name_of(o.template_family, kTemplates)); }},
    {"orientation",
     [](Options& o, std::string_view k, std::string_view v) { o.orientation = parse_enum(k, v, kOrientations); },
     [](const Options& o) { return std::string(name_of(o.orientation, kOrientations)); }},
    {"outside", [](Options& o, std::string_view k, std::string_view v) { o.outside = parse_enum(k, v, kOutside); },
     [](const Options& o) { return std::string(name_of(o.outside, kOutside)); }},
    {"outside_tolerance",
     [](Options& o, std::string_view k, std::string_view v) { o.outside_tolerance = parse_double(k, v, 0.0, 1e30); },
     [](const Options& o) { return number_text(o.outside_tolerance); }},
    {"threads",
     [](Options& o, std::string_view k, std::string_view v) { o.threads = static_cast<int>(parse_int(k, v, 0, 4096)); },
     [](const Options& o) { return std::to_string(o.threads); }},
    {"deterministic", [](Options& o, std::string_view k, std::string_view v) { o.deterministic = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.deterministic); }},
    {"alpha_min", [](Options& o, std::string_view k, std::string_view v) { o.alpha_min = parse_double(k, v, 0.0, 1.0); },
     [](const Options& o) { return number_text(o.alpha_min); }},
    {"periodic",
     [](Options& o, std::string_view k, std::string_view v) {
       unsigned mask = 0;
       if (v != "none") {
         if (v.empty() || v.size() > 3) bad(k, v, "none or a combination of x, y, z (e.g. xy)");
         for (char c : v) {
           if (c != 'x' && c != 'y' && c != 'z') bad(k, v, "none or a combination of x, y, z (e.g. xy)");
           mask |= 1u << (c - 'x');
         }
       }
       o.periodic = mask;
     },
     [](const Options& o) {
       if (!o.periodic) return std::string("none");
       std::string axes;
       for (int d = 0; d < 3; ++d)
         if ((o.periodic >> d) & 1u) axes += char('x' + d);
       return axes;
     }},
    {"accumulation",
     [](Options& o, std::string_view k, std::string_view v) { o.accumulation = parse_enum(k, v, kAccumulation); },
     [](const Options& o) { return std::string(name_of(o.accumulation, kAccumulation)); }},
    {"seed",
     [](Options& o, std::string_view k, std::string_view v) {
       o.seed = static_cast<std::uint64_t>(parse_int(k, v, 0, std::numeric_limits<std::int64_t>::max()));
     },
     [](const Options& o) { return std::to_string(o.seed); }},
    {"sigma", [](Options& o, std::string_view k, std::string_view v) { o.sigma = parse_positive(k, v, 100.0); },
     [](const Options& o) { return number_text(o.sigma); }},
    {"gamma", [](Options& o, std::string_view k, std::string_view v) { o.gamma = parse_positive(k, v, 100.0); },
     [](const Options& o) { return number_text(o.gamma); }},
    {"superficial_velocity",
     [](Options& o, std::string_view k, std::string_view v) { o.superficial_velocity = parse_double(k, v, 0.0, 1e30); },
     [](const Options& o) { return number_text(o.superficial_velocity); }},
    {"fluid_dt", [](Options& o, std::string_view k, std::string_view v) { o.fluid_dt = parse_double(k, v, 0.0, 1e30); },
     [](const Options& o) { return number_text(o.fluid_dt); }},
    {"log_level",
     [](Options& o, std::string_view k, std::string_view v) {
       if (std::find(std::begin(kLogLevels), std::end(kLogLevels), v) == std::end(kLogLevels))
         bad(k, v, "one of trace, debug, info, warn, error, off");
       o.log_level = std::string(v);
     },
     [](const Options& o) { return o.log_level; }},
    {"fast_path", [](Options& o, std::string_view k, std::string_view v) { o.fast_path = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.fast_path); }},
    {"rotation_bank", [](Options& o, std::string_view k, std::string_view v) { o.rotation_bank = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.rotation_bank); }},
    {"lattice", [](Options& o, std::string_view k, std::string_view v) { o.lattice = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.lattice); }},
    {"incremental", [](Options& o, std::string_view k, std::string_view v) { o.incremental = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.incremental); }},
    {"move_tolerance",
     [](Options& o, std::string_view k, std::string_view v) { o.move_tolerance = parse_double(k, v, 0.0, 1e30); },
     [](const Options& o) { return number_text(o.move_tolerance); }},
    {"touched_only", [](Options& o, std::string_view k, std::string_view v) { o.touched_only = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.touched_only); }},
    {"weights", [](Options& o, std::string_view k, std::string_view v) { o.weights = parse_bool(k, v); },
     [](const Options& o) { return print_bool(o.weights); }},
    {"smoothing_length",
     [](Options& o, std::string_view k, std::string_view v) { o.smoothing_length = parse_double(k, v, 0.0, 1e30); },
     [](const Options& o) { return number_text(o.smoothing_length); }},
    {"particle_order",
     [](Options& o, std::string_view k, std::string_view v) { o.particle_order = parse_enum(k, v, kParticleOrders); },
     [](const Options& o) { return std::string(name_of(o.particle_order, kParticleOrders)); }},
};

const OptionSpec* find_option(std::string_view key) {
  for (const OptionSpec& spec : kOptions)
    if (key == spec.key) return &spec;
  return nullptr;
}

[[noreturn]] void unknown_option(std::string_view key) {
  std::string known;
  for (const OptionSpec& spec : kOptions) known += (known.empty() ? "" : ", ") + std::string(spec.key);
  throw Error(VFE_ERROR_INVALID_ARGUMENT, "unknown option " + quoted(key) + "; known options: " + known);
}

}  // namespace

Options parse_options(std::string_view text, const Options& base) {
  Options o = base;
  std::vector<std::string_view> seen;
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
                  "option " + quoted(token) + " is not of the form key=value (e.g. method=pmm)");
    const std::string_view key = token.substr(0, eq);
    const OptionSpec* spec = find_option(key);
    if (!spec) unknown_option(key);
    // A key given twice is a mistake a host would not see if the last one silently won.
    if (std::find(seen.begin(), seen.end(), key) != seen.end())
      throw Error(VFE_ERROR_INVALID_ARGUMENT,
                  "option '" + std::string(key) + "' is given twice; give each option once per call");
    seen.push_back(key);
    spec->parse(o, key, token.substr(eq + 1));
    pos = end;
  }
  return o;
}

std::string_view to_string(Method m) { return name_of(m, kMethods); }

std::span<const std::string_view> method_names() {
  static const auto names = [] {
    std::array<std::string_view, std::size(kMethods)> n{};
    for (std::size_t i = 0; i < n.size(); ++i) n[i] = kMethods[i].first;
    return n;
  }();
  return names;
}

std::string option_value(const Options& o, std::string_view key) {
  const OptionSpec* spec = find_option(key);
  if (!spec) unknown_option(key);
  return spec->print(o);
}

std::string format_options(const Options& o) {
  std::string out;
  for (const OptionSpec& spec : kOptions) {
    if (!out.empty()) out += ' ';
    out += std::string(spec.key) + "=" + spec.print(o);
  }
  return out;
}

}  // namespace vfe
