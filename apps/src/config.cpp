#include "config.hpp"

#include "engine_methods.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;

struct Ctx {
  std::string source;

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const {
    const YAML::Mark m = at.IsDefined() ? at.Mark() : YAML::Mark::null_mark();
    if (!m.is_null())
      throw ConfigError(source + ":" + std::to_string(m.line + 1) + ": " + what);
    throw ConfigError(source + ": " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { throw ConfigError(source + ": " + what); }
};

std::string list(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

/// Every key of map must be one of allowed.
void check_keys(const Ctx& ctx, const YAML::Node& map, const std::vector<std::string>& allowed,
                const std::string& where) {
  for (const auto& kv : map) {
    const std::string key = kv.first.as<std::string>();
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end())
      ctx.fail(kv.first, "unknown key '" + key + "' in " + where + "; allowed keys: " + list(allowed) +
                             " (check the spelling)");
  }
}

std::string scalar(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) ctx.fail(n, what + " must be a single value (text)");
  return n.as<std::string>();
}

double number(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) ctx.fail(n, what + " must be a number");
  try {
    const double v = n.as<double>();
    if (!std::isfinite(v)) ctx.fail(n, what + " must be a finite number, got '" + n.Scalar() + "'");
    return v;
  } catch (const YAML::BadConversion&) {
    ctx.fail(n, what + " must be a number, got '" + n.Scalar() + "'");
  }
}

std::int64_t integer(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) ctx.fail(n, what + " must be an integer");
  try {
    return n.as<std::int64_t>();
  } catch (const YAML::BadConversion&) {
    ctx.fail(n, what + " must be an integer, got '" + n.Scalar() + "'");
  }
}

/// [a, b, c] or a single value repeated.
std::array<double, 3> triple(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (n.IsScalar()) {
    const double v = number(ctx, n, what);
    return {v, v, v};
  }
  if (!n.IsSequence() || n.size() != 3)
    ctx.fail(n, what + " must be a list of 3 numbers [x, y, z] (or a single number)");
  return {number(ctx, n[0], what), number(ctx, n[1], what), number(ctx, n[2], what)};
}

std::array<std::int64_t, 3> triple_int(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (n.IsScalar()) {
    const auto v = integer(ctx, n, what);
    return {v, v, v};
  }
  if (!n.IsSequence() || n.size() != 3)
    ctx.fail(n, what + " must be a list of 3 integers [nx, ny, nz] (or a single integer)");
  return {integer(ctx, n[0], what), integer(ctx, n[1], what), integer(ctx, n[2], what)};
}

/// The engine's method names, "direct, pmm, ...".
std::string method_list() {
  std::string list;
  for (const std::string& name : engine_method_names()) list.append(list.empty() ? "" : ", ").append(name);
  return list;
}

bool is_identifier_like(const std::string& s) {
  if (s.empty()) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
  });
}

std::string default_label(const std::string& method, const std::string& options) {
  std::istringstream in(options);
  std::string tok, label = method;
  while (in >> tok) {
    std::replace(tok.begin(), tok.end(), '=', '-');
    label += "_" + tok;
  }
  return label;
}

MethodSpec method_entry(const Ctx& ctx, const YAML::Node& n, const std::string& where) {
  MethodSpec m;
  if (n.IsScalar()) {
    m.method = n.as<std::string>();
  } else if (n.IsMap()) {
    check_keys(ctx, n, {"method", "options", "label", "settings"}, where);
    if (!n["method"]) ctx.fail(n, where + " has no 'method' key; write e.g. {method: pmm, options: \"particle_grid=27\"}");
    m.method = scalar(ctx, n["method"], where + ": method");
    if (n["options"]) {
      if (n["options"].IsNull())
        m.options.clear();
      else
        m.options = scalar(ctx, n["options"], where + ": options");
    }
    if (n["label"]) m.label = scalar(ctx, n["label"], where + ": label");
    if (const YAML::Node st = n["settings"]) {
      if (!st.IsSequence() || st.size() == 0)
        ctx.fail(st, where + ": settings must be a list of option strings, e.g. [\"particle_grid=20\", "
                             "\"particle_grid=80\"]");
      for (std::size_t i = 0; i < st.size(); ++i) {
        const std::string setting = scalar(ctx, st[i], where + ": settings");
        if (setting.find("method=") != std::string::npos)
          ctx.fail(st[i], where + ": a setting must not set method= (use the 'method' key)");
        try {
          if (merge_options({setting}).empty()) ctx.fail(st[i], where + ": a setting is empty");
        } catch (const ConfigError& e) {
          ctx.fail(st[i], where + ": settings: " + e.what());
        }
        if (std::find(m.settings.begin(), m.settings.end(), setting) != m.settings.end())
          ctx.fail(st[i], where + ": setting '" + setting + "' is listed twice");
        m.settings.push_back(setting);
      }
    }
  } else {
    ctx.fail(n, where + " must be a method name (e.g. pmm) or a map {method: NAME, options: \"k=v ...\", "
                        "label: NAME}");
  }
  if (!is_identifier_like(m.method))
    ctx.fail(n, where + ": '" + m.method + "' is not a method name; use one of " + method_list());
  if (m.options.find("method=") != std::string::npos)
    ctx.fail(n, where + ": options must not set method= (use the 'method' key)");
  if (m.label.empty()) m.label = default_label(m.method, m.options);
  if (m.label.find_first_of(" \t\",\n") != std::string::npos)
    ctx.fail(n, where + ": label '" + m.label + "' must not contain blanks, quotes or commas");
  try {
    (void)merge_options({m.options});
  } catch (const ConfigError& e) {
    ctx.fail(n, where + ": " + e.what());
  }
  return m;
}

/// The nodes of one axis of a rectilinear mesh: a list of increasing coordinates, or
/// {lo, hi, cells, grading} with cell sizes in geometric progression whose last / first
/// ratio is grading (1 = uniform; blockMesh's simpleGrading).
std::vector<double> axis_nodes(const Ctx& ctx, const YAML::Node& mesh, const std::string& axis,
                               const std::string& where) {
  const YAML::Node n = mesh[axis];
  const std::string at = where + ": " + axis;
  if (!n) ctx.fail(mesh, where + ": no '" + axis + "' axis; give a node list or {lo, hi, cells, grading}");
  std::vector<double> x;
  if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i) x.push_back(number(ctx, n[i], at));
  } else if (n.IsMap()) {
    check_keys(ctx, n, {"lo", "hi", "cells", "grading"}, at);
    if (!n["lo"] || !n["hi"] || !n["cells"]) ctx.fail(n, at + " needs lo, hi and cells (and optionally grading)");
    const double lo = number(ctx, n["lo"], at + ".lo"), hi = number(ctx, n["hi"], at + ".hi");
    const double cells = number(ctx, n["cells"], at + ".cells");
    const double grading = n["grading"] ? number(ctx, n["grading"], at + ".grading") : 1.0;
    if (!(hi > lo)) ctx.fail(n, at + ": needs lo < hi");
    if (!(cells >= 1) || cells != std::floor(cells) || cells > 1e7) ctx.fail(n["cells"], at + ".cells must be an integer >= 1");
    if (!(grading > 0)) ctx.fail(n["grading"], at + ".grading must be > 0");
    const int m = static_cast<int>(cells);
    const double r = m > 1 ? std::pow(grading, 1.0 / (m - 1)) : 1.0;  // ratio of neighbouring cells
    double sum = 0, size = 1;
    std::vector<double> sizes(m);
    for (int i = 0; i < m; ++i, size *= r) sum += sizes[i] = size;
    x.push_back(lo);
    double at_x = 0;
    for (int i = 0; i < m; ++i) x.push_back(i + 1 == m ? hi : lo + (at_x += sizes[i]) * (hi - lo) / sum);
  } else {
    ctx.fail(n, at + " must be a node list [x0, x1, ...] or {lo, hi, cells, grading}");
  }
  if (x.size() < 2) ctx.fail(n, at + " needs at least 2 nodes");
  for (std::size_t i = 1; i < x.size(); ++i)
    if (!(x[i] > x[i - 1])) ctx.fail(n, at + ": nodes must be strictly increasing (node " + std::to_string(i) + ")");
  return x;
}

MeshSpec mesh_entry(const Ctx& ctx, const YAML::Node& n, std::size_t index, const fs::path& base_dir) {
  const std::string where0 = "mesh " + std::to_string(index + 1);
  if (!n.IsMap())
    ctx.fail(n, where0 + " must be a map with keys name, type, origin/bounds, spacing, cells (cartesian) or "
                         "name, type, path (polymesh)");
  MeshSpec m;
  m.line = n.Mark().is_null() ? 0 : n.Mark().line + 1;
  m.name = n["name"] ? scalar(ctx, n["name"], where0 + ": name") : "mesh" + std::to_string(index + 1);
  const std::string where = "mesh '" + m.name + "'";
  if (!is_identifier_like(m.name))
    ctx.fail(n["name"], where + ": the name may only have letters, digits, '_' and '-'");
  if (n["type"]) m.type = scalar(ctx, n["type"], where + ": type");
  if (m.type != "cartesian" && m.type != "polymesh" && m.type != "rectilinear")
    ctx.fail(n["type"], where + ": unknown mesh type '" + m.type +
                            "'; use type: cartesian (origin/bounds, spacing, cells), type: rectilinear (x, y, z: "
                            "node lists or {lo, hi, cells, grading}) or type: polymesh (path: an OpenFOAM case or "
                            "polyMesh folder)");
  if (m.type == "rectilinear") {
    check_keys(ctx, n, {"name", "type", "x", "y", "z"}, where + " (type rectilinear)");
    for (int d = 0; d < 3; ++d) m.nodes[d] = axis_nodes(ctx, n, std::string(1, "xyz"[d]), where);
    return m;
  }
  if (m.type == "polymesh") {
    check_keys(ctx, n, {"name", "type", "path"}, where + " (type polymesh)");
    if (!n["path"] || n["path"].IsNull())
      ctx.fail(n, where + ": type polymesh needs 'path: FOLDER', an OpenFOAM case folder (with "
                          "constant/polyMesh) or a polyMesh folder, relative to the config's folder");
    const std::string p = scalar(ctx, n["path"], where + ": path");
    if (p.empty()) ctx.fail(n["path"], where + ": path is empty");
    m.path = fs::path(p).is_absolute() ? fs::path(p) : (base_dir / p).lexically_normal();
    return m;
  }
  check_keys(ctx, n, {"name", "type", "origin", "spacing", "cells", "bounds"}, where);
  if (n["origin"]) m.origin = triple(ctx, n["origin"], where + ": origin");
  if (n["spacing"]) m.spacing = triple(ctx, n["spacing"], where + ": spacing");
  if (n["cells"]) m.cells = triple_int(ctx, n["cells"], where + ": cells");
  if (n["bounds"]) {
    const YAML::Node b = n["bounds"];
    if (b.IsScalar() && b.as<std::string>() == "particles_box") {
      m.bounds_particles_box = true;
    } else if (b.IsSequence() && b.size() == 6) {
      std::array<double, 6> v{};
      for (std::size_t i = 0; i < 6; ++i) v[i] = number(ctx, b[i], where + ": bounds");
      m.bounds = v;
    } else {
      ctx.fail(b, where + ": bounds must be 'particles_box' or [xlo, xhi, ylo, yhi, zlo, zhi]");
    }
  }
  const bool has_bounds = m.bounds_particles_box || m.bounds.has_value();
  if (has_bounds && m.origin)
    ctx.fail(n, where + ": give either 'origin' (with spacing and cells) or 'bounds' (with spacing or "
                        "cells), not both");
  if (!has_bounds && !m.origin)
    ctx.fail(n, where + ": no position; add 'origin: [x, y, z]' with 'spacing' and 'cells', or "
                        "'bounds: particles_box' with 'spacing'");
  if (m.origin && !(m.spacing && m.cells))
    ctx.fail(n, where + ": 'origin' needs both 'spacing' and 'cells'");
  if (has_bounds && !m.spacing && !m.cells)
    ctx.fail(n, where + ": 'bounds' needs 'spacing' (or 'cells')");
  if (has_bounds && m.spacing && m.cells)
    ctx.fail(n, where + ": with 'bounds' give 'spacing' or 'cells', not both");
  if (m.spacing)
    for (double h : *m.spacing)
      if (!(h > 0)) ctx.fail(n["spacing"], where + ": spacing must be > 0");
  if (m.cells)
    for (auto c : *m.cells)
      if (c < 1) ctx.fail(n["cells"], where + ": cells must be >= 1 in every direction");
  if (m.bounds)
    for (int d = 0; d < 3; ++d)
      if (!((*m.bounds)[2 * d + 1] > (*m.bounds)[2 * d]))
        ctx.fail(n["bounds"], where + ": bounds need lo < hi in every direction");
  return m;
}

/// One entry of the shapes list, its spec checked by registering it on probe.
ShapeEntry shape_entry(const Ctx& ctx, const YAML::Node& n, std::size_t index, const fs::path& base_dir,
                       vfe::Engine& probe) {
  const std::string where0 = "shapes: entry " + std::to_string(index + 1);
  if (!n.IsMap()) ctx.fail(n, where0 + " must be a map {name: NAME, spec: \"ellipsoid 1 0.6 0.4\"}");
  check_keys(ctx, n, {"name", "spec"}, where0);
  if (!n["name"]) ctx.fail(n, where0 + " has no 'name' key");
  if (!n["spec"]) ctx.fail(n, where0 + " has no 'spec' key (sphere | ellipsoid A B C | superquadric A B C E1 E2 | "
                                       "clump x y z r; ... | mesh FILE)");
  ShapeEntry e;
  e.line = n.Mark().is_null() ? 0 : n.Mark().line + 1;
  e.name = scalar(ctx, n["name"], where0 + ": name");
  const std::string where = "shapes: '" + e.name + "'";
  if (!is_identifier_like(e.name))
    ctx.fail(n["name"], where + ": the name may only have letters, digits, '_' and '-'");
  e.spec = scalar(ctx, n["spec"], where + ": spec");
  // A mesh file is relative to the config's folder.
  std::istringstream in(e.spec);
  std::string kind;
  in >> kind;
  if (kind == "mesh") {
    std::string path;
    std::getline(in >> std::ws, path);
    while (!path.empty() && std::isspace(static_cast<unsigned char>(path.back()))) path.pop_back();
    if (!path.empty() && !fs::path(path).is_absolute()) e.spec = "mesh " + (base_dir / path).lexically_normal().string();
  }
  try {
    (void)probe.add_shape(e.spec);
  } catch (const vfe::Error& err) {
    ctx.fail(n["spec"], where + ": spec: " + err.what());
  }
  return e;
}

/// particles: {files: GLOB | [PATH, ...]} or {file: PATH, frames: ...}, with frames: all |
/// [first, last], timesteps: [from, to] (either may be ~) and dem_dt.
FrameSeriesSpec frame_series(const Ctx& ctx, const YAML::Node& p, const fs::path& base_dir) {
  FrameSeriesSpec s;
  s.line = p.Mark().is_null() ? 0 : p.Mark().line + 1;
  auto add = [&](const YAML::Node& n) {
    const std::string f = scalar(ctx, n, "particles: files");
    if (f.empty()) ctx.fail(n, "particles: files: an entry is empty");
    s.files.push_back(fs::path(f).is_absolute() ? f : (base_dir / f).lexically_normal().string());
  };
  if (const YAML::Node cmd = p["command"]) {
    s.command = scalar(ctx, cmd, "particles: command");
    s.command_folder = base_dir;
    if (s.command.empty()) ctx.fail(cmd, "particles: command is empty; give the shell command that prints the frames");
  }
  const YAML::Node files = p["files"] ? p["files"] : p["file"];
  if (!s.command.empty()) {
    // a live source: no files
  } else if (files.IsSequence()) {
    if (files.size() == 0) ctx.fail(files, "particles: files is an empty list; list dumps or give a glob");
    for (std::size_t i = 0; i < files.size(); ++i) add(files[i]);
  } else {
    add(files);
  }
  if (const YAML::Node f = p["frames"]) {
    const std::string what = "particles: frames must be 'all' or [first, last] (0-based indices of the series in "
                             "timestep order, negative from the end)";
    if (f.IsScalar() && f.as<std::string>() == "all") {
      // every frame: the defaults
    } else if (f.IsSequence() && f.size() == 2) {
      s.first_frame = integer(ctx, f[0], "particles: frames: first");
      s.last_frame = integer(ctx, f[1], "particles: frames: last");
      if (!s.command.empty() && (s.first_frame < 0 || (s.last_frame < s.first_frame && s.last_frame != -1)))
        ctx.fail(f, "particles: frames of a command are counted as they come: give [first, last] with 0 <= first "
                    "<= last, or last = -1 for every frame from first on");
    } else {
      ctx.fail(f, what);
    }
  }
  if (const YAML::Node t = p["timesteps"]) {
    if (!t.IsSequence() || t.size() != 2)
      ctx.fail(t, "particles: timesteps must be [from, to] (inclusive; ~ for no bound), e.g. [16500, ~]");
    if (!t[0].IsNull()) s.from_timestep = integer(ctx, t[0], "particles: timesteps: from");
    if (!t[1].IsNull()) s.to_timestep = integer(ctx, t[1], "particles: timesteps: to");
    if (s.from_timestep && s.to_timestep && *s.to_timestep < *s.from_timestep)
      ctx.fail(t, "particles: timesteps: to (" + std::to_string(*s.to_timestep) + ") is before from (" +
                      std::to_string(*s.from_timestep) + ")");
  }
  if (const YAML::Node dt = p["dem_dt"]) {
    s.dem_dt = number(ctx, dt, "particles: dem_dt");
    if (!(s.dem_dt > 0)) ctx.fail(dt, "particles: dem_dt must be > 0 (the DEM time step, e.g. 1e-5)");
  }
  return s;
}

SceneConfig parse_root(const Ctx& ctx, const YAML::Node& root, const fs::path& base_dir) {
  if (!root.IsDefined() || root.IsNull()) ctx.fail("the config is empty; see configs/bed_mono.yaml for an example");
  if (!root.IsMap()) ctx.fail(root, "the config must be a map of keys (name, particles, meshes, methods, ...)");
  check_keys(ctx, root,
             {"name", "shapes", "particles", "meshes", "chi", "methods", "reference", "threads", "repeats", "options",
              "output", "vtk", "foam", "coupling"},
             "the config");
  SceneConfig c;
  c.source = ctx.source;

  c.name = root["name"] ? scalar(ctx, root["name"], "name") : fs::path(ctx.source).stem().string();
  if (c.name.empty()) c.name = "scene";

  // shapes (before particles, which name them)
  if (const YAML::Node sh = root["shapes"]) {
    if (!sh.IsSequence() || sh.size() == 0)
      ctx.fail(sh, "shapes must be a list of {name: NAME, spec: \"ellipsoid 1 0.6 0.4\"} entries");
    vfe::Engine probe(vfe::CartesianGridSpec{});
    for (std::size_t i = 0; i < sh.size(); ++i) {
      ShapeEntry e = shape_entry(ctx, sh[i], i, base_dir, probe);
      if (c.shape_index(e.name) >= 0) ctx.fail(sh[i], "two shapes are named '" + e.name + "'; give each its own name");
      c.shapes.push_back(std::move(e));
    }
  }

  // particles: a dump (file, frame, shape_by_type) or generated
  const YAML::Node p = root["particles"];
  if (!p) ctx.fail(root, "no 'particles' key; add particles: {file: PATH_TO_DUMP} or particles: {generate: {...}}");
  auto known_shape = [&](const YAML::Node& at, const std::string& name, const std::string& where) {
    if (c.shape_index(name) >= 0) return;
    std::vector<std::string> names;
    for (const auto& e : c.shapes) names.push_back(e.name);
    ctx.fail(at, where + ": shape '" + name + "' is not in the 'shapes' list" +
                     (names.empty() ? std::string(" (there is none; add shapes: [{name: " + name + ", spec: \"...\"}])")
                                    : " (known: " + list(names) + ")"));
  };
  std::string file;
  if (p.IsScalar()) {
    file = p.as<std::string>();
  } else if (p.IsMap() && p["generate"]) {
    check_keys(ctx, p, {"generate"}, "particles (with generate, the particles are not read from a file)");
    const YAML::Node g = p["generate"];
    const std::vector<std::string> keys = {"count", "shape", "scale", "box", "seed", "orientations"};
    if (!g.IsMap())
      ctx.fail(g, "particles: generate must be a map {count: N, shape: NAME, scale: S, box: [x0, x1, y0, y1, z0, z1], "
                  "seed: 1, orientations: random}");
    check_keys(ctx, g, keys, "particles: generate");
    for (const char* k : {"count", "shape", "scale", "box"})
      if (!g[k]) ctx.fail(g, std::string("particles: generate has no '") + k + "' key (needs count, shape, scale, box)");
    GenerateSpec gen;
    gen.count = integer(ctx, g["count"], "particles: generate: count");
    if (gen.count < 1 || gen.count > 100000000)
      ctx.fail(g["count"], "particles: generate: count must be in [1, 100000000]");
    gen.shape = scalar(ctx, g["shape"], "particles: generate: shape");
    known_shape(g["shape"], gen.shape, "particles: generate: shape");
    gen.scale = number(ctx, g["scale"], "particles: generate: scale");
    if (!(gen.scale > 0)) ctx.fail(g["scale"], "particles: generate: scale must be > 0 (the shape's unit length)");
    const YAML::Node b = g["box"];
    if (!b.IsSequence() || b.size() != 6)
      ctx.fail(b, "particles: generate: box must be [xlo, xhi, ylo, yhi, zlo, zhi]");
    for (std::size_t i = 0; i < 6; ++i) gen.box[i] = number(ctx, b[i], "particles: generate: box");
    for (int d = 0; d < 3; ++d)
      if (!(gen.box[2 * d + 1] > gen.box[2 * d])) ctx.fail(b, "particles: generate: box needs lo < hi in every direction");
    if (g["seed"]) {
      const auto seed = integer(ctx, g["seed"], "particles: generate: seed");
      if (seed < 0) ctx.fail(g["seed"], "particles: generate: seed must be >= 0");
      gen.seed = static_cast<std::uint64_t>(seed);
    }
    if (g["orientations"]) {
      gen.orientations = scalar(ctx, g["orientations"], "particles: generate: orientations");
      if (gen.orientations != "random" && gen.orientations != "none")
        ctx.fail(g["orientations"], "particles: generate: orientations must be 'random' (random unit quaternions) "
                                    "or 'none' (every particle unrotated)");
    }
    c.generate = gen;
  } else if (p.IsMap()) {
    check_keys(ctx, p,
               {"file", "files", "command", "frame", "frames", "timesteps", "dem_dt", "shape_by_type", "generate"},
               "particles");
    if (p["command"] && (p["file"] || p["files"] || p["frame"]))
      ctx.fail(p["command"], "particles: 'command' reads the frames from the command's output; give no 'file', "
                             "'files' or 'frame' with it");
    if (p["file"] && p["files"])
      ctx.fail(p, "particles: give either 'file' (one dump) or 'files' (a glob or a list of dumps), not both");
    if (!p["file"] && !p["files"] && !p["command"])
      ctx.fail(p, "particles has no 'file' key; add file: PATH_TO_DUMP, files: \"dir/*.dump.gz\" (a series), "
                  "command: \"...\" (frames from a command's output) or generate: {...}");
    if (p["frame"] && (p["frames"] || p["files"]))
      ctx.fail(p["frame"], "particles: 'frame' picks one frame of one file; a series takes 'frames: all' or "
                           "'frames: [first, last]' (and 'timesteps: [from, to]')");
    if (p["files"] || p["frames"] || p["command"]) c.series = frame_series(ctx, p, base_dir);
    else if (p["timesteps"] || p["dem_dt"])
      ctx.fail(p, "particles: 'timesteps' and 'dem_dt' belong to a series of frames; add 'frames: all' (every "
                  "frame of the file) or use 'files:'");
    if (p["file"]) file = scalar(ctx, p["file"], "particles: file");
    if (p["frame"]) {
      const YAML::Node f = p["frame"];
      const std::string s = f.IsScalar() ? f.as<std::string>() : "";
      if (s == "last")
        c.frame = -1;
      else if (s == "first")
        c.frame = 0;
      else
        c.frame = integer(ctx, f, "particles: frame (first, last, or an index; negative counts from the end)");
    }
    if (const YAML::Node m = p["shape_by_type"]) {
      if (!m.IsMap() || m.size() == 0)
        ctx.fail(m, "particles: shape_by_type must be a map of the dump's shape (or type) values to shape names, "
                    "e.g. {1: ell, 2: cube}");
      for (const auto& kv : m) {
        const std::int64_t t = integer(ctx, kv.first, "particles: shape_by_type: a key (a type value)");
        const std::string name = scalar(ctx, kv.second, "particles: shape_by_type: " + std::to_string(t));
        known_shape(kv.second, name, "particles: shape_by_type: " + std::to_string(t));
        c.shape_by_type[t] = name;
      }
    }
  } else {
    ctx.fail(p, "particles must be a map {file: PATH, frame: last} or {generate: {...}}");
  }
  if (!c.generate && !c.series) {
    if (file.empty()) ctx.fail(p, "particles: file is empty");
    c.particles_file = fs::path(file).is_absolute() ? fs::path(file) : (base_dir / file).lexically_normal();
  }
  if (!c.shapes.empty() && !c.shaped())
    ctx.fail(root["shapes"], "shapes are listed but no particle uses them; add particles: shape_by_type: {1: " +
                                 c.shapes.front().name + "} (dump) or particles: generate: {shape: " +
                                 c.shapes.front().name + ", ...}");

  // chi: grids over the particles' box
  if (const YAML::Node chi = root["chi"]) {
    std::vector<YAML::Node> values;
    if (chi.IsScalar())
      values.push_back(chi);
    else if (chi.IsSequence() && chi.size() > 0)
      for (std::size_t i = 0; i < chi.size(); ++i) values.push_back(chi[i]);
    else
      ctx.fail(chi, "chi must be a number or a list of numbers, e.g. chi: [0.75, 1, 2, 3]");
    for (const auto& v : values) {
      const double x = number(ctx, v, "chi");
      if (!(x > 0)) ctx.fail(v, "chi must be > 0 (cell size / mean particle diameter)");
      if (std::find(c.chi.begin(), c.chi.end(), x) != c.chi.end()) ctx.fail(v, "chi value listed twice");
      c.chi.push_back(x);
    }
  }

  // meshes
  const YAML::Node meshes = root["meshes"];
  const bool no_meshes = !meshes || meshes.IsNull() || (meshes.IsSequence() && meshes.size() == 0);
  if (no_meshes && c.chi.empty())
    ctx.fail(meshes ? meshes : root, "no mesh: add a 'meshes:' list with at least one mesh, e.g. "
                                     "{name: grid, type: cartesian, bounds: particles_box, spacing: 0.002}, "
                                     "or a 'chi:' list");
  if (!no_meshes && !meshes.IsSequence()) ctx.fail(meshes, "'meshes' must be a list of meshes");
  std::set<std::string> mesh_names;
  for (double x : c.chi) mesh_names.insert(chi_mesh_name(x));
  for (std::size_t i = 0; !no_meshes && i < meshes.size(); ++i) {
    MeshSpec m = mesh_entry(ctx, meshes[i], i, base_dir);
    if (!mesh_names.insert(m.name).second)
      ctx.fail(meshes[i], "two meshes are named '" + m.name + "' (chi: [...] makes meshes chi_<value>); "
                          "give each mesh its own name");
    c.meshes.push_back(std::move(m));
  }

  // methods
  const YAML::Node methods = root["methods"];
  if (!methods || methods.IsNull() || (methods.IsSequence() && methods.size() == 0))
    ctx.fail(methods ? methods : root, "no method: add a 'methods:' list, e.g. [direct, pmm, exact]");
  if (!methods.IsSequence()) ctx.fail(methods, "'methods' must be a list");
  std::set<std::string> labels;
  for (std::size_t i = 0; i < methods.size(); ++i) {
    MethodSpec m = method_entry(ctx, methods[i], "method entry " + std::to_string(i + 1));
    if (!labels.insert(m.label).second)
      ctx.fail(methods[i], "two methods have the label '" + m.label + "'; add label: NAME to tell them apart");
    c.methods.push_back(std::move(m));
  }

  // reference: a label of the methods list, or a method (entry); exact takes spheres only
  if (c.shaped()) c.reference = default_shape_reference();
  if (const YAML::Node r = root["reference"]) {
    bool found = false;
    if (r.IsScalar()) {
      const std::string name = r.as<std::string>();
      for (const auto& m : c.methods)
        if (m.label == name) {
          c.reference = m;
          found = true;
          break;
        }
    }
    if (!found) c.reference = method_entry(ctx, r, "reference");
  }

  if (root["threads"]) {
    const auto t = integer(ctx, root["threads"], "threads");
    if (t < 0 || t > 4096) ctx.fail(root["threads"], "threads must be 0 (all) or a count >= 1");
    c.threads = static_cast<int>(t);
  }
  if (root["repeats"]) {
    const auto r = integer(ctx, root["repeats"], "repeats");
    if (r < 1 || r > 1000000) ctx.fail(root["repeats"], "repeats must be >= 1");
    c.repeats = static_cast<int>(r);
  }
  if (root["options"] && !root["options"].IsNull()) {
    c.options = scalar(ctx, root["options"], "options");
    if (c.options.find("method=") != std::string::npos)
      ctx.fail(root["options"], "options must not set method= (list methods under 'methods')");
    try {
      (void)merge_options({c.options});
    } catch (const ConfigError& e) {
      ctx.fail(root["options"], std::string("options: ") + e.what());
    }
  }
  if (root["output"]) {
    const std::string o = scalar(ctx, root["output"], "output");
    c.output = fs::path(o).is_absolute() ? fs::path(o) : (base_dir / o).lexically_normal();
  } else {
    c.output = (base_dir / "out" / c.name).lexically_normal();
  }
  if (root["vtk"]) {
    try {
      c.vtk = root["vtk"].as<bool>();
    } catch (const YAML::BadConversion&) {
      ctx.fail(root["vtk"], "vtk must be true or false");
    }
  }
  if (root["foam"]) {
    try {
      c.foam = root["foam"].as<bool>();
    } catch (const YAML::BadConversion&) {
      ctx.fail(root["foam"], "foam must be true or false");
    }
  }
  if (root["coupling"]) {
    try {
      c.coupling = root["coupling"].as<bool>();
    } catch (const YAML::BadConversion&) {
      ctx.fail(root["coupling"], "coupling must be true or false");
    }
  }
  return c;
}

}  // namespace

int SceneConfig::shape_index(const std::string& shape_name) const {
  for (std::size_t i = 0; i < shapes.size(); ++i)
    if (shapes[i].name == shape_name) return static_cast<int>(i);
  return -1;
}

MethodSpec default_shape_reference() { return {"pmm", "particle_grid=4000", "pmm_particle_grid-4000", {}}; }

SceneConfig parse_config(const std::string& text, const fs::path& base_dir, const std::string& source) {
  Ctx ctx{source};
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    if (!e.mark.is_null())
      throw ConfigError(source + ":" + std::to_string(e.mark.line + 1) + ": not valid YAML: " + e.msg);
    throw ConfigError(source + ": not valid YAML: " + e.msg);
  }
  try {
    return parse_root(ctx, root, base_dir);
  } catch (const YAML::Exception& e) {
    if (!e.mark.is_null())
      throw ConfigError(source + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
    throw ConfigError(source + ": " + e.msg);
  }
}

void keep_methods(SceneConfig& config, const std::vector<std::string>& labels) {
  if (labels.empty()) return;
  for (const std::string& label : labels)
    if (std::none_of(config.methods.begin(), config.methods.end(), [&](const MethodSpec& m) { return m.label == label; })) {
      std::string known;
      for (const auto& m : config.methods) known += (known.empty() ? "" : ", ") + m.label;
      throw ConfigError(config.source.string() + ": no method labelled '" + label + "' to run; the config has " + known);
    }
  std::erase_if(config.methods, [&](const MethodSpec& m) {
    return std::find(labels.begin(), labels.end(), m.label) == labels.end();
  });
}

SceneConfig load_config(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec))
    throw ConfigError(file.string() + ": no such config file; check the path");
  if (fs::is_directory(file, ec))
    throw ConfigError(file.string() + ": is a folder; give a YAML config file");
  std::ifstream in(file);
  if (!in) throw ConfigError(file.string() + ": cannot read the config file (permissions?)");
  std::ostringstream text;
  text << in.rdbuf();
  const fs::path base = fs::absolute(file, ec).parent_path();
  return parse_config(text.str(), base.empty() ? fs::path(".") : base, file.string());
}

vfe::CartesianGridSpec resolve_grid(const MeshSpec& m, const std::array<double, 6>* particles_box,
                                    const std::string& source, std::string* note) {
  vfe::CartesianGridSpec g;
  const std::string where = source + (m.line > 0 ? ":" + std::to_string(m.line) : std::string()) +
                            ": mesh '" + m.name + "'";
  if (m.type != "cartesian")
    throw ConfigError(where + ": is a " + m.type + " mesh, not a Cartesian grid");
  if (!m.origin && !m.bounds && !m.bounds_particles_box)
    throw ConfigError(where + ": no position; give origin, spacing and cells, or bounds and spacing");
  if (m.origin) {
    g.origin = *m.origin;
    g.spacing = *m.spacing;
    g.cells = *m.cells;
    return g;
  }
  std::array<double, 6> box{};
  if (m.bounds_particles_box) {
    if (!particles_box) throw ConfigError(where + ": bounds: particles_box needs the dump's BOX BOUNDS");
    box = *particles_box;
    for (int d = 0; d < 3; ++d)
      if (!(box[2 * d + 1] > box[2 * d]))
        throw ConfigError(where + ": the dump's BOX BOUNDS are empty in direction " + "xyz"[d] +
                          "; give origin, spacing and cells instead of bounds: particles_box");
  } else {
    box = *m.bounds;
  }
  std::string notes;
  for (int d = 0; d < 3; ++d) {
    const double lo = box[2 * d], len = box[2 * d + 1] - box[2 * d];
    g.origin[d] = lo;
    if (m.cells) {
      g.cells[d] = (*m.cells)[d];
      g.spacing[d] = len / static_cast<double>(g.cells[d]);
    } else {
      const double h = (*m.spacing)[d];
      const double ratio = len / h;
      // The cell count must be an integer the grid can have before it is converted to one.
      constexpr double kMaxCellsPerAxis = 1099511627776.0;  // 2^40, the grid's limit on all cells
      if (!(h > 0) || !(ratio <= kMaxCellsPerAxis)) {
        std::ostringstream msg;
        msg << where << ": spacing " << h << " in " << "xyz"[d] << " over the box length " << len << " gives " << ratio
            << " cells; give a spacing > 0 that makes at most 2^40 cells (per axis and in all)";
        throw ConfigError(msg.str());
      }
      const double r = std::round(ratio);
      if (r >= 1 && std::abs(ratio - r) <= 1e-6 * std::max(1.0, r)) {
        g.cells[d] = static_cast<std::int64_t>(r);
        g.spacing[d] = len / r;  // fit the box exactly
      } else {
        g.cells[d] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(ratio)));
        g.spacing[d] = h;
        notes += std::string(notes.empty() ? "" : "; ") + "spacing " + std::to_string(h) +
                 " does not divide the box length " + std::to_string(len) + " in " + "xyz"[d] +
                 ": the grid extends past the box to " + std::to_string(g.cells[d]) + " cells";
      }
    }
  }
  if (note) *note = notes;
  return g;
}

fs::path find_polymesh_folder(const fs::path& dir) {
  std::error_code ec;
  auto has = [&](const fs::path& d, const char* name) {
    return fs::is_regular_file(d / name, ec) || fs::is_regular_file(d / (std::string(name) + ".gz"), ec);
  };
  for (const fs::path& d : {dir / "constant" / "polyMesh", dir / "polyMesh", dir})
    if (fs::is_directory(d, ec) && has(d, "points") && has(d, "faces") && has(d, "owner")) return d;
  return {};
}

void check_mesh_paths(const SceneConfig& c) {
  for (const MeshSpec& m : c.meshes) {
    if (m.type != "polymesh") continue;
    const std::string where = c.source.string() + (m.line > 0 ? ":" + std::to_string(m.line) : std::string()) +
                              ": mesh '" + m.name + "'";
    std::error_code ec;
    if (!fs::exists(m.path, ec))
      throw ConfigError(where + ": path " + m.path.string() +
                        " does not exist; give an OpenFOAM case folder (with constant/polyMesh) or a polyMesh "
                        "folder, relative to the config's folder");
    if (find_polymesh_folder(m.path).empty())
      throw ConfigError(where + ": no polyMesh in " + m.path.string() +
                        ": expected a case folder with constant/polyMesh, or a polyMesh folder, holding points, "
                        "faces, owner, neighbour and boundary (plain or .gz)");
  }
}

std::string chi_mesh_name(double chi) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "chi_%g", chi);
  return buf;
}

MeshSpec chi_mesh(double chi, double mean_diameter) {
  MeshSpec m;
  m.name = chi_mesh_name(chi);
  m.bounds_particles_box = true;
  const double h = chi * mean_diameter;
  m.spacing = std::array<double, 3>{h, h, h};
  return m;
}

std::vector<MethodSpec> expand_settings(const std::vector<MethodSpec>& methods) {
  std::vector<MethodSpec> out;
  for (const MethodSpec& m : methods) {
    if (m.settings.empty()) {
      out.push_back(m);
      continue;
    }
    for (const std::string& setting : m.settings) {
      MethodSpec e = m;
      e.settings.clear();
      e.options = merge_options({m.options, setting});
      std::string tag = merge_options({setting});
      std::replace(tag.begin(), tag.end(), '=', '-');
      std::replace(tag.begin(), tag.end(), ' ', '_');
      e.label = m.label + "_" + tag;
      out.push_back(std::move(e));
    }
  }
  return out;
}

std::string scene_options(const SceneConfig& cfg, std::optional<int> threads, const std::string& particle_options,
                          const std::string& source) {
  std::vector<std::string> parts = {"threads=" + std::to_string(cfg.threads), particle_options, cfg.options};
  if (threads) parts.push_back("threads=" + std::to_string(*threads));
  try {
    return merge_options(parts);
  } catch (const ConfigError& e) {
    throw ConfigError(source + ": options: " + e.what());
  }
}

std::string merge_options(const std::vector<std::string>& parts) {
  std::vector<std::pair<std::string, std::string>> kv;
  for (const auto& part : parts) {
    std::istringstream in(part);
    std::string tok;
    while (in >> tok) {
      const auto eq = tok.find('=');
      if (eq == std::string::npos || eq == 0)
        throw ConfigError("option '" + tok + "' is not of the form key=value");
      const std::string k = tok.substr(0, eq), v = tok.substr(eq + 1);
      auto it = std::find_if(kv.begin(), kv.end(), [&](const auto& p) { return p.first == k; });
      if (it != kv.end())
        it->second = v;
      else
        kv.emplace_back(k, v);
    }
  }
  std::string s;
  for (const auto& [k, v] : kv) s += (s.empty() ? "" : " ") + k + "=" + v;
  return s;
}

}  // namespace vfe::apps
