#include "scene_particles.hpp"

#include "dump_reader.hpp"
#include "random.hpp"

#include <cmath>
#include <numbers>

namespace vfe::apps {

namespace {

std::string where_shape(const SceneConfig& c, const ShapeEntry& e) {
  return c.source.string() + (e.line > 0 ? ":" + std::to_string(e.line) : std::string()) + ": shapes: '" + e.name + "'";
}

}  // namespace

vfe::ParticleView SceneParticles::view() const {
  vfe::ParticleView v;
  v.n = n;
  v.centres = centres.data();
  v.radii = radii.data();
  v.orientations = orientations.empty() ? nullptr : orientations.data();
  v.shape_ids = shape_ids.empty() ? nullptr : shape_ids.data();
  return v;
}

std::vector<double> SceneParticles::volumes() const {
  std::vector<double> v(radii.size());
  for (std::size_t i = 0; i < radii.size(); ++i) {
    const double r = radii[i];
    v[i] = (shape_ids.empty() ? 4.0 / 3.0 * std::numbers::pi : shape_volumes[static_cast<std::size_t>(shape_ids[i])]) *
           r * r * r;
  }
  return v;
}

double SceneParticles::total_volume() const {
  double s = 0;
  for (double v : volumes()) s += v;
  return s;
}

double SceneParticles::mean_diameter() const {
  if (radii.empty()) return 0;
  // Diameter of the sphere of equal volume per shape, at scale 1 (2 for a unit sphere).
  std::vector<double> eq(shape_volumes.size());
  for (std::size_t k = 0; k < eq.size(); ++k) eq[k] = std::cbrt(6.0 * shape_volumes[k] / std::numbers::pi);
  double s = 0;
  for (std::size_t i = 0; i < radii.size(); ++i)
    s += radii[i] * (shape_ids.empty() ? 2.0 : eq[static_cast<std::size_t>(shape_ids[i])]);
  return s / static_cast<double>(radii.size());
}

void register_shapes(const SceneConfig& c, vfe::Engine& engine) {
  for (std::size_t i = 0; i < c.shapes.size(); ++i) {
    std::int32_t id = -1;
    try {
      id = engine.add_shape(c.shapes[i].spec);
    } catch (const vfe::Error& e) {
      throw ConfigError(where_shape(c, c.shapes[i]) + ": spec: " + e.what());
    }
    if (id != static_cast<std::int32_t>(i))
      throw ConfigError(where_shape(c, c.shapes[i]) + ": registered as shape " + std::to_string(id) + ", expected " +
                        std::to_string(i) + " (register shapes on a fresh engine)");
  }
}

void generate_particles(const GenerateSpec& g, std::vector<double>& centres, std::vector<double>& orientations) {
  const auto n = static_cast<std::size_t>(g.count);
  centres.resize(3 * n);
  orientations.clear();
  SplitMix64 rng(g.seed * 0xD1B54A32D192ED03ull + 0x5851F42D4C957F2Dull);
  for (std::size_t i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) centres[3 * i + d] = g.box[2 * d] + (g.box[2 * d + 1] - g.box[2 * d]) * rng.uniform();
  if (g.orientations != "random") return;
  orientations.resize(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::array<double, 4> q = random_unit_quaternion(rng);
    for (int k = 0; k < 4; ++k) orientations[4 * i + k] = q[k];
  }
}

std::vector<double> config_shape_volumes(const SceneConfig& c) {
  std::vector<double> volumes;
  if (c.shapes.empty()) return volumes;
  vfe::Engine probe(vfe::CartesianGridSpec{});
  register_shapes(c, probe);
  for (std::size_t i = 0; i < c.shapes.size(); ++i) volumes.push_back(probe.shape_volume(static_cast<std::int32_t>(i)));
  return volumes;
}

void check_coupling_velocities(const SceneConfig& c, const SceneParticles& p) {
  if (!c.coupling || p.n == 0 || !p.velocities.empty()) return;
  throw ConfigError(c.source.string() + ": coupling: true needs the particles' velocities; " +
                    (c.generate ? std::string("generated particles have none")
                                : "the dump " + p.source_name + " has no vx vy vz columns" +
                                      (c.series ? " (timestep " + std::to_string(p.timestep) + ")" : std::string())) +
                    "; dump them (LIGGGHTS: dump ... id type x y z radius vx vy vz), or remove coupling");
}

SceneParticles load_particles(const SceneConfig& c) {
  const std::string source = c.source.string();
  if (c.series)
    throw ConfigError(source + ": particles: a series of frames (files, frames) is computed by `vfe run`; "
                               "this command takes one frame: particles: {file: PATH, frame: N}");
  if (c.generate) {
    SceneParticles p;
    p.shape_volumes = config_shape_volumes(c);
    const GenerateSpec& g = *c.generate;
    const int id = c.shape_index(g.shape);
    if (id < 0) throw ConfigError(source + ": particles: generate: shape '" + g.shape + "' is not in the 'shapes' list");
    p.n = g.count;
    p.box = g.box;
    p.source_name = "generated";
    generate_particles(g, p.centres, p.orientations);
    p.radii.assign(static_cast<std::size_t>(p.n), g.scale);
    p.shape_ids.assign(static_cast<std::size_t>(p.n), id);
    p.options = g.orientations == "random" ? "orientation=given" : "orientation=none";
    return p;
  }
  return particles_from_dump(c, read_dump_frame(c.particles_file.string(), FrameSelector{c.frame}), c.particles_file,
                             config_shape_volumes(c));
}

SceneParticles particles_from_dump(const SceneConfig& c, DumpFrame&& f, const std::filesystem::path& file,
                                   std::vector<double> shape_volumes) {
  SceneParticles p;
  const std::string source = c.source.string();
  p.shape_volumes = std::move(shape_volumes);
  p.timestep = f.timestep;
  p.n = f.n;
  p.box = f.box;
  p.source_name = file.filename().string();
  p.centres = std::move(f.centres);
  p.radii = std::move(f.radii);
  p.orientations = std::move(f.orientations);
  p.velocities = std::move(f.velocities);
  p.ids = f.ids;
  if (c.shape_by_type.empty()) return p;

  const bool by_shape = !f.shapes.empty();
  const std::vector<std::int32_t>& key = by_shape ? f.shapes : f.types;
  const char* column = by_shape ? "shape" : "type";
  if (key.empty() && p.n > 0) {
    std::string cols;
    for (const auto& x : f.columns) cols += (cols.empty() ? "" : " ") + x;
    throw ConfigError(source + ": particles: shape_by_type needs a 'shape' or 'type' column in " + file.string() +
                      ", whose ATOMS header has '" + cols + "'; dump the particles' type (or shape) too");
  }
  p.shape_ids.resize(static_cast<std::size_t>(p.n));
  for (std::size_t i = 0; i < p.shape_ids.size(); ++i) {
    const auto it = c.shape_by_type.find(key[i]);
    if (it == c.shape_by_type.end())
      throw ConfigError(source + ": particles: shape_by_type has no entry for " + column + " " +
                        std::to_string(key[i]) + " (particle " +
                        (f.ids.empty() ? "index " + std::to_string(i) : "id " + std::to_string(f.ids[i])) + " of " +
                        file.filename().string() + "); add " + std::to_string(key[i]) + ": NAME");
    p.shape_ids[i] = c.shape_index(it->second);
  }
  // Shapes turn with the particles when the dump has their quaternions; otherwise the
  // engine's orientation option applies (random by default).
  if (!p.orientations.empty()) p.options = "orientation=given";
  return p;
}

}  // namespace vfe::apps
