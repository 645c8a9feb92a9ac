#include "run_plan.hpp"

#include "text_format.hpp"

#include <algorithm>
#include <cstdio>
#include <sstream>
#include <string>
#include <thread>

namespace vfe::apps {

namespace {

constexpr const char* kVelocityDimensions = "[0 1 -1 0 0 0 0]";

std::string g3(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

int resolve_threads(const std::string& value) {
  int t = 0;
  try {
    t = std::stoi(value);
  } catch (...) {
    t = 0;
  }
  if (t > 0) return t;
  const unsigned hc = std::thread::hardware_concurrency();
  return hc ? static_cast<int>(hc) : 1;
}

/// The scene's options; the coupling fields need the weights of each compute.
std::string run_options(const SceneConfig& cfg, const RunOptions& opt, const std::string& particle_options) {
  const std::string o = scene_options(cfg, opt.threads, particle_options, cfg.source.string());
  return cfg.coupling ? merge_options({o, "weights=1"}) : o;
}

}  // namespace

std::string MethodPlan::options_for(const MethodSpec& m) const {
  return merge_options({defaults, global, "method=" + m.method, m.options});
}

std::string MethodPlan::default_label() const {
  const std::string default_options = merge_options({defaults, global});
  for (const auto& m : methods)
    if (options_for(m) == default_options) return m.label;
  return methods.empty() ? std::string() : methods.front().label;
}

std::string MethodPlan::reference_title() const {
  if (reference.label == reference.method && reference.options.empty()) return reference.label;
  return reference.label + " (" + reference.method + (reference.options.empty() ? "" : " " + reference.options) + ")";
}

MethodPlan plan_methods(const SceneConfig& cfg, const RunOptions& opt) {
  const std::string source = cfg.source.string();
  if (opt.threads && *opt.threads < 0)
    throw ConfigError("threads must be 0 (all) or a count >= 1 (got " + std::to_string(*opt.threads) + ")");
  MethodPlan plan;
  plan.global = run_options(cfg, opt, "");
  plan.methods = expand_settings(cfg.methods);
  plan.reference = cfg.reference;
  plan.reference_listed = std::any_of(plan.methods.begin(), plan.methods.end(), [&](const MethodSpec& m) {
    return m.label == plan.reference.label && m.method == plan.reference.method && m.options == plan.reference.options;
  });
  // Polymesh folders, then every option string on a one-cell engine. Each method starts
  // from the engine's defaults, so one method's options never leak into the next.
  check_mesh_paths(cfg);
  vfe::Engine probe(vfe::CartesianGridSpec{});
  plan.defaults = probe.options();
  auto check = [&](const MethodSpec& m, const std::string& what) {
    try {
      probe.configure(plan.options_for(m));
    } catch (const vfe::Error& e) {
      throw ConfigError(source + ": " + what + " '" + m.label + "': " + e.what());
    } catch (const ConfigError& e) {
      throw ConfigError(source + ": " + what + " '" + m.label + "': " + e.what());
    }
  };
  check(plan.reference, "reference");
  for (const auto& m : plan.methods) check(m, "method");
  probe.configure(merge_options({plan.defaults, plan.global}));
  plan.threads = resolve_threads(probe.option("threads"));
  return plan;
}

void add_particle_options(MethodPlan& plan, const SceneConfig& cfg, const RunOptions& opt,
                          const std::string& particle_options) {
  plan.global = run_options(cfg, opt, particle_options);
}

const char* lattice_note(const MeshSpec& mesh, const SceneMesh& built) {
  return mesh.type == "polymesh" && built.engine->last_report_value("lattice_cells") > 0 ? ", a lattice of box cells"
                                                                                         : "";
}

void log_mesh(spdlog::logger& log, const MeshSpec& mesh, const SceneMesh& built, double chi) {
  const double cell_size = built.cube_root_of_mean_volume();
  const bool poly = mesh.type == "polymesh";
  if (poly || mesh.type == "rectilinear")
    log.info("mesh '{}': {} of {} cells{}, mean cell size {} (mean chi = {:.2f})", mesh.name,
             poly ? "polyMesh" : "rectilinear grid", built.cell_volumes.size(), lattice_note(mesh, built),
             g3(cell_size), chi);
  else
    log.info("mesh '{}': {} x {} x {} cells of {} (chi = {:.2f})", mesh.name, built.grid.cells[0], built.grid.cells[1],
             built.grid.cells[2], g3(cell_size), chi);
}

std::vector<double> particle_velocity_field(const vfe::Engine& engine, const SceneParticles& particles) {
  const std::size_t ncells = static_cast<std::size_t>(engine.cell_count());
  const std::vector<double> volume = particles.volumes();
  std::vector<double> values(4 * volume.size());
  for (std::size_t p = 0; p < volume.size(); ++p) {
    for (std::size_t d = 0; d < 3; ++d) values[4 * p + d] = particles.velocities[3 * p + d] * volume[p];
    values[4 * p + 3] = volume[p];
  }
  std::vector<double> deposited(4 * ncells);
  engine.deposit(4, values, deposited);
  std::vector<double> us(3 * ncells, 0.0);
  for (std::size_t c = 0; c < ncells; ++c)
    if (deposited[4 * c + 3] > 0)
      for (std::size_t d = 0; d < 3; ++d) us[3 * c + d] = deposited[4 * c + d] / deposited[4 * c + 3];
  return us;
}

void write_weights_csv(const std::filesystem::path& file, const vfe::Engine& engine, const SceneParticles& particles) {
  const vfe::Engine::WeightsSize size = engine.weights_size();
  std::vector<std::int64_t> offsets(static_cast<std::size_t>(size.particles + 1)),
      cells(static_cast<std::size_t>(size.entries));
  std::vector<double> fractions(static_cast<std::size_t>(size.entries));
  engine.weights(offsets, cells, fractions);
  const bool ids = particles.ids.size() == static_cast<std::size_t>(size.particles) && size.particles > 0;
  std::ostringstream o;
  o << (ids ? "particle,id,cell,fraction\n" : "particle,cell,fraction\n");
  for (std::size_t p = 0; p < static_cast<std::size_t>(size.particles); ++p)
    for (std::int64_t k = offsets[p]; k < offsets[p + 1]; ++k) {
      o << p << ',';
      if (ids) o << particles.ids[p] << ',';
      o << cells[static_cast<std::size_t>(k)] << ',' << csv_number(fractions[static_cast<std::size_t>(k)]) << '\n';
    }
  write_text_file(file, o.str());
}

std::vector<CellArray> field_arrays(const std::vector<MethodField>& fields) {
  std::vector<CellArray> arrays;
  for (const MethodField& f : fields) {
    arrays.push_back({"voidfraction_" + f.label, f.eps});
    arrays.push_back({"solid_volume_" + f.label, f.solid});
    if (!f.us.empty()) arrays.push_back({"Us_" + f.label, f.us, 3});
  }
  return arrays;
}

std::filesystem::path write_mesh_vtk(const std::filesystem::path& stem, const SceneMesh& built,
                                     const std::vector<CellArray>& arrays) {
  std::filesystem::path f = stem;
  if (built.engine->is_polymesh()) {
    f += ".vtu";
    std::vector<double> centres(3 * built.cell_volumes.size());
    built.engine->cell_centres(centres);
    write_vtu(f, built.engine->poly_topology(), centres, arrays);
  } else {
    f += ".vti";
    write_vti(f, built.grid, arrays);
  }
  return f;
}

void write_foam_time(const std::filesystem::path& time_dir, const std::string& time_name,
                     const std::vector<MethodField>& fields, const MethodPlan& plan,
                     const std::vector<FoamPatch>& patches, spdlog::logger& log) {
  const MethodField* plain = nullptr;
  const std::string default_label = plan.default_label();
  for (const MethodField& f : fields) {
    write_foam_scalar_field(time_dir / ("voidfraction_" + f.label), "voidfraction_" + f.label, time_name, f.eps,
                            patches, f.options);
    if (!f.us.empty())
      write_foam_vector_field(time_dir / ("Us_" + f.label), "Us_" + f.label, time_name, f.us, kVelocityDimensions,
                              patches, f.options);
    if (f.label == default_label) plain = &f;
  }
  if (!plain)  // the default method was skipped here: the first listed method that ran
    for (const auto& m : plan.methods) {
      auto it = std::find_if(fields.begin(), fields.end(), [&](const MethodField& f) { return f.label == m.label; });
      if (it != fields.end()) {
        plain = &*it;
        break;
      }
    }
  if (!plain) {
    log.info("wrote {} (voidfraction_<method>)", time_dir.string());
    return;
  }
  write_foam_scalar_field(time_dir / "voidfraction", "voidfraction", time_name, plain->eps, patches,
                          plain->label + ": " + plain->options);
  if (!plain->us.empty())
    write_foam_vector_field(time_dir / "Us", "Us", time_name, plain->us, kVelocityDimensions, patches,
                            plain->label + ": " + plain->options);
  log.info("wrote {} (voidfraction from {}, and voidfraction_<method> for every method)", time_dir.string(),
           plain->label);
}

}  // namespace vfe::apps
