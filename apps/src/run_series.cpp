// `vfe run` on a series of frames: every method through the frames in timestep order, the
// jump of its void fraction between frames against the reference's, and the fields and
// particles per frame for ParaView (.pvd collections) and OpenFOAM (time folders).
#include "frame_series.hpp"
#include "report.hpp"
#include "run.hpp"
#include "run_plan.hpp"
#include "scene_mesh.hpp"
#include "text_format.hpp"
#include "timing.hpp"
#include "vtk_writer.hpp"

#include <vfe/stability.hpp>

#include <spdlog/logger.h>

#include <cstdio>
#include <limits>
#include <ostream>
#include <sstream>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The frame files' folder under the output folder, named in the .pvd files.
constexpr const char* kFramesFolder = "frames";

void write_frames_csv(const fs::path& file, const std::vector<FrameRow>& rows) {
  std::ostringstream o;
  o << "method,mesh,frame,timestep,time,ms,max_excess,mean_excess,max_exact_jump,changed_cells\n";
  for (const FrameRow& r : rows)
    o << csv_field(r.label) << ',' << csv_field(r.mesh) << ',' << r.frame << ',' << r.timestep << ','
      << csv_number(r.time) << ',' << csv_number(r.ms) << ',' << csv_number(r.max_excess) << ','
      << csv_number(r.mean_excess) << ',' << csv_number(r.max_exact_jump) << ',' << r.changed_cells << '\n';
  write_text_file(file, o.str());
}

void write_jumps_csv(const fs::path& file, const std::vector<SeriesRow>& rows) {
  std::ostringstream o;
  o << "mesh,method,engine_method,chi,frames,ms_median,max_excess,mean_excess,max_exact_jump,note\n";
  for (const SeriesRow& r : rows)
    o << csv_field(r.mesh) << ',' << csv_field(r.label) << ',' << csv_field(r.method) << ',' << csv_number(r.chi)
      << ',' << r.frames << ',' << csv_number(r.ms_median) << ',' << csv_number(r.max_excess) << ','
      << csv_number(r.mean_excess) << ',' << csv_number(r.max_exact_jump) << ',' << csv_field(r.note) << '\n';
  write_text_file(file, o.str());
}

/// The summary of one mesh: per method the median compute time and the jumps against the
/// reference over the whole series.
void print_series_table(std::ostream& out, const std::string& title, const std::vector<SeriesRow>& rows) {
  std::vector<std::vector<std::string>> cells = {
      {"method", "ms/frame", "max excess", "mean excess", "max/deps_crit", "max exact jump"}};
  std::vector<std::string> notes;
  for (const SeriesRow& r : rows) {
    if (r.skipped) {
      cells.push_back({r.label, "skipped", "-", "-", "-", "-"});
      notes.push_back(r.label + " skipped: " + r.note);
      continue;
    }
    cells.push_back({r.label, table_number("%.3f", r.ms_median), table_number("%.4f", r.max_excess),
                     table_number("%.2e", r.mean_excess), table_number("%.2f", r.max_excess / vfe::kDefaultJumpCriterion),
                     table_number("%.4f", r.max_exact_jump)});
  }
  out << title << '\n';
  print_columns(out, cells, 1);
  for (const std::string& n : notes) out << n << '\n';
  out << "(excess = |deps_method| - |deps_reference| per cell between consecutive frames: max over cells and pairs, "
         "mean over the cells where either field changed; deps_crit = pi/162)\n";
}

}  // namespace

RunResult run_series(const SceneConfig& cfg, const RunOptions& opt) {
  const auto log = opt.logger ? opt.logger : make_app_logger(true);
  const std::string source = cfg.source.string();
  const bool vtk = opt.vtk || cfg.vtk;
  const bool foam = opt.foam || cfg.foam;
  const fs::path out_dir = opt.output.value_or(cfg.output);
  const double dem_dt = cfg.series->dem_dt;
  if (cfg.coupling)
    throw ConfigError(source + ": coupling: true is not available for a series of frames yet; remove it, or run "
                               "one frame (particles: {file: PATH, frame: N})");

  MethodPlan plan = plan_methods(cfg, opt);
  auto t0 = Clock::now();
  const std::vector<SceneParticles> frames = load_frame_series(cfg);
  const SceneParticles& first = frames.front();
  const auto nframes = frames.size();
  log->info("{} frame(s), timesteps {} to {}, {} to {} particles, read in {:.0f} ms", nframes, first.timestep,
            frames.back().timestep, first.n, frames.back().n, ms_since(t0));
  if (!first.options.empty()) add_particle_options(plan, cfg, opt, first.options);
  const double mean_d = first.mean_diameter();

  std::error_code ec;
  const fs::path folder = vtk ? out_dir / kFramesFolder : out_dir;
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder))
    throw std::runtime_error(out_dir.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output or 'output:'");
  auto frame_file = [&](const std::string& stem, std::int64_t timestep) {
    return fs::path(kFramesFolder) / (stem + "_" + std::to_string(timestep));
  };
  if (vtk) {
    std::vector<PvdEntry> entries;
    for (const SceneParticles& f : frames) {
      fs::path rel = frame_file("particles", f.timestep);
      rel += ".vtp";
      write_vtp(out_dir / rel, f.centres, f.radii, f.velocities, f.ids);
      entries.push_back({frame_time(f.timestep, dem_dt), rel});
    }
    write_pvd(out_dir / "particles.pvd", entries);
    log->info("wrote {} ({} .vtp files)", (out_dir / "particles.pvd").string(), entries.size());
  }

  RunResult result;
  result.output = out_dir;
  auto unsupported = [](const vfe::Error& e) { return e.status() == VFE_ERROR_UNSUPPORTED; };
  auto frame_where = [&](std::size_t k) {
    return "timestep " + std::to_string(frames[k].timestep) + " (" + frames[k].source_name + ")";
  };

  for (const MeshSpec& mesh : scene_meshes(cfg, cfg.chi, mean_d)) {
    SceneMesh built = build_scene_mesh(mesh, &first.box, source);
    if (!built.note.empty()) log->info("mesh '{}': {}", mesh.name, built.note);
    vfe::Engine& engine = *built.engine;
    register_shapes(cfg, engine);
    const std::size_t ncells = built.cell_volumes.size();
    const double chi = mean_d > 0 ? built.cube_root_of_mean_volume() / mean_d : 0.0;
    log_mesh(*log, mesh, built, chi);
    const bool foam_here = foam && mesh.type == "polymesh";
    if (foam && !foam_here)
      log->warn("mesh '{}' is not an OpenFOAM case: OpenFOAM field files are written for polymesh meshes only",
                mesh.name);
    const bool keep_fields = vtk || foam_here;
    std::vector<std::vector<MethodField>> fields(nframes);  // per frame, kept for the writers
    std::vector<double> solid(ncells), eps(ncells);

    // The reference's void fraction of every frame, for the jumps.
    std::vector<std::vector<double>> ref(nframes);
    bool have_ref = false;
    try {
      engine.configure(plan.options_for(plan.reference));
      for (std::size_t k = 0; k < nframes; ++k) {
        with_mesh_context(mesh, "reference '" + plan.reference.label + "', " + frame_where(k),
                          [&] { engine.compute(frames[k].view(), solid); });
        ref[k].resize(ncells);
        engine.void_fraction(ref[k]);
        if (keep_fields && !plan.reference_listed)
          fields[k].push_back({plan.reference.label, ref[k], solid, plan.options_for(plan.reference), {}});
      }
      have_ref = true;
    } catch (const vfe::Error& e) {
      if (!unsupported(e)) throw;
      log->warn("mesh '{}': reference '{}' is not supported here ({}); jumps against it are not computed", mesh.name,
                plan.reference.label, e.what());
    }

    std::vector<SeriesRow> mesh_rows;
    for (const MethodSpec& m : plan.methods) {
      const std::string opts = plan.options_for(m);
      SeriesRow summary{mesh.name, m.label, m.method, chi, static_cast<std::int64_t>(nframes), 0, kNaN, kNaN, kNaN,
                        false, ""};
      try {
        engine.configure(opts);
      } catch (const vfe::Error& e) {
        if (!unsupported(e)) throw vfe::Error(e.status(), "mesh '" + mesh.name + "', method '" + m.label + "': " + e.what());
        log->warn("mesh '{}': method '{}' skipped: {}", mesh.name, m.label, e.what());
        summary.skipped = true;
        summary.note = e.what();
        mesh_rows.push_back(std::move(summary));
        continue;
      }
      FrameJump total;
      std::vector<double> times, previous;
      bool overfull_warned = false;
      for (std::size_t k = 0; k < nframes; ++k) {
        const SceneParticles& f = frames[k];
        t0 = Clock::now();
        with_mesh_context(mesh, "method '" + m.label + "', " + frame_where(k), [&] { engine.compute(f.view(), solid); });
        const double ms = ms_since(t0);
        engine.void_fraction(eps);
        times.push_back(ms);
        FrameRow row{mesh.name, m.label, m.method, chi, static_cast<std::int64_t>(k), f.timestep,
                     frame_time(f.timestep, dem_dt), ms, kNaN, kNaN, kNaN, 0};
        if (k > 0 && have_ref) {
          const FrameJump j = frame_jump(previous, eps, ref[k - 1], ref[k]);
          row.max_excess = j.max_excess;
          row.mean_excess = j.mean_excess();
          row.max_exact_jump = j.max_reference_jump;
          row.changed_cells = j.changed_cells;
          total.add(j);
        }
        log->info("  {} frame {}/{} (timestep {}, t = {:g}): {:.3f} ms, max excess jump {:.4f}", m.label, k + 1,
                  nframes, f.timestep, row.time, ms, row.max_excess);
        if (!overfull_warned) {
          const OverfullFacts overfull = overfull_facts(engine);
          overfull_warned = overfull.cells > 0;
          warn_overfull(*log, mesh.name, m.label, overfull, f.total_volume());
          if (overfull_warned) log->info("  {}: first at timestep {} (later frames are not reported)", m.label, f.timestep);
        }
        if (keep_fields) fields[k].push_back({m.label, eps, solid, opts, {}});
        previous = eps;
        result.frames.push_back(std::move(row));
      }
      summary.ms_median = median(times);
      if (have_ref && nframes > 1) {
        summary.max_excess = total.max_excess;
        summary.mean_excess = total.mean_excess();
        summary.max_exact_jump = total.max_reference_jump;
      }
      mesh_rows.push_back(std::move(summary));
    }

    if (vtk) {
      std::vector<PvdEntry> entries;
      for (std::size_t k = 0; k < nframes; ++k) {
        const fs::path written =
            write_mesh_vtk(out_dir / frame_file(mesh.name, frames[k].timestep), built, field_arrays(fields[k]));
        entries.push_back({frame_time(frames[k].timestep, dem_dt), fs::path(kFramesFolder) / written.filename()});
      }
      write_pvd(out_dir / (mesh.name + ".pvd"), entries);
      log->info("wrote {} ({} frames)", (out_dir / (mesh.name + ".pvd")).string(), nframes);
    }
    if (foam_here) {
      const std::vector<FoamPatch> patches = read_constraint_patches(find_polymesh_folder(mesh.path));
      for (std::size_t k = 0; k < nframes; ++k) {
        if (fields[k].empty()) continue;
        // 12 digits: 18000 * 1e-5 is the folder 0.18, not 0.18000000000000002.
        const std::string time_name = printf_number("%.12g", frame_time(frames[k].timestep, dem_dt));
        write_foam_time(out_dir / mesh.name / time_name, time_name, fields[k], plan, patches, *log);
      }
    }

    if (opt.table) {
      char title[512];
      std::snprintf(title, sizeof title, "\n%s / mesh %s: %zu cells (chi = %.2f), %zu frames (timesteps %lld to %lld), "
                                         "reference %s",
                    cfg.name.c_str(), mesh.name.c_str(), ncells, chi, nframes,
                    static_cast<long long>(first.timestep), static_cast<long long>(frames.back().timestep),
                    plan.reference_title().c_str());
      print_series_table(*opt.table, title, mesh_rows);
    }
    result.series.insert(result.series.end(), mesh_rows.begin(), mesh_rows.end());
    // Reports so far, so a long run leaves results even if a later mesh fails.
    write_frames_csv(out_dir / "frames.csv", result.frames);
    write_jumps_csv(out_dir / "frame_jumps.csv", result.series);
  }
  log->info("wrote {} and {}", (out_dir / "frames.csv").string(), (out_dir / "frame_jumps.csv").string());
  return result;
}

}  // namespace vfe::apps
