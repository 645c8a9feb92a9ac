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
#include <memory>
#include <optional>
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

namespace {

/// One method on one mesh through the series: its own engine (so incremental=1 and its
/// templates carry from frame to frame), its rows and its totals over the finished frames.
struct MethodRun {
  MethodSpec spec;
  std::string options;
  std::unique_ptr<vfe::Engine> engine;  ///< null when the mesh does not support the method
  std::string skipped_why;
  std::vector<FrameRow> rows;
  std::vector<double> times;
  FrameJump total;
  std::vector<double> previous;  ///< eps of the last finished frame
  bool overfull_warned = false;
};

/// One mesh: the reference's engine (the mesh's own) and one engine per method.
struct MeshRun {
  MeshSpec spec;
  SceneMesh built;
  double chi = 0;
  bool foam_here = false;
  std::vector<FoamPatch> patches;
  bool have_ref = false;
  std::vector<double> ref_previous;  ///< the reference's eps of the last finished frame
  std::vector<MethodRun> methods;
  std::vector<PvdEntry> pvd;
};

/// What one frame computed on one mesh, kept until the frame is done everywhere.
struct MeshFrame {
  std::vector<double> ref;  ///< the reference's eps (empty without a reference)
  std::vector<MethodField> fields;
  struct Method {
    FrameRow row;
    std::optional<FrameJump> jump;
    std::vector<double> eps;
  };
  std::vector<std::optional<Method>> methods;  ///< per MethodRun; empty for a skipped one
};

}  // namespace

RunResult run_series(const SceneConfig& cfg, const RunOptions& opt) {
  const auto log = opt.logger ? opt.logger : make_app_logger(true);
  const std::string source = cfg.source.string();
  const bool vtk = opt.vtk || cfg.vtk;
  const bool foam = opt.foam || cfg.foam;
  const bool coupling = cfg.coupling;
  const fs::path out_dir = opt.output.value_or(cfg.output);
  const double dem_dt = cfg.series->dem_dt;

  MethodPlan plan = plan_methods(cfg, opt);
  // The output folder comes first: a live command may write beside it.
  std::error_code ec;
  const fs::path folder = vtk || coupling ? out_dir / kFramesFolder : out_dir;
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder))
    throw std::runtime_error(out_dir.string() + ": cannot create the output folder (" + ec.message() +
                             "); choose another with --output or 'output:'");

  auto t0 = Clock::now();
  const std::unique_ptr<FrameSource> frames = open_frame_source(cfg);
  const std::int64_t known = frames->count();
  if (known < 0) log->info("reading frames from {} as they come", frames->description());
  SceneParticles frame;
  if (!frames->next(frame)) throw std::runtime_error(source + ": the series has no frame");
  if (known >= 0)
    log->info("{}, read in {:.0f} ms; first: timestep {}, {} particles", frames->description(), ms_since(t0),
              frame.timestep, frame.n);
  if (!frame.options.empty()) add_particle_options(plan, cfg, opt, frame.options);
  const double mean_d = frame.mean_diameter();
  const std::array<double, 6> first_box = frame.box;

  auto frame_file = [&](const std::string& stem, std::int64_t timestep) {
    return fs::path(kFramesFolder) / (stem + "_" + std::to_string(timestep));
  };
  auto unsupported = [](const vfe::Error& e) { return e.status() == VFE_ERROR_UNSUPPORTED; };
  auto frame_where = [&](const SceneParticles& f) {
    return "timestep " + std::to_string(f.timestep) + " (" + f.source_name + ")";
  };

  // Every mesh's engines, before the first frame is computed.
  std::vector<MeshRun> meshes;
  for (const MeshSpec& mesh : scene_meshes(cfg, cfg.chi, mean_d)) {
    MeshRun& mr = meshes.emplace_back();
    mr.spec = mesh;
    mr.built = build_scene_mesh(mesh, &first_box, source);
    if (!mr.built.note.empty()) log->info("mesh '{}': {}", mesh.name, mr.built.note);
    register_shapes(cfg, *mr.built.engine);
    mr.chi = mean_d > 0 ? mr.built.cube_root_of_mean_volume() / mean_d : 0.0;
    log_mesh(*log, mesh, mr.built, mr.chi);
    mr.foam_here = foam && mesh.type == "polymesh";
    if (foam && !mr.foam_here)
      log->warn("mesh '{}' is not an OpenFOAM case: OpenFOAM field files are written for polymesh meshes only",
                mesh.name);
    if (mr.foam_here) mr.patches = read_constraint_patches(find_polymesh_folder(mesh.path));
    try {
      mr.built.engine->configure(plan.options_for(plan.reference));
      mr.have_ref = true;
    } catch (const vfe::Error& e) {
      if (!unsupported(e)) throw;
      log->warn("mesh '{}': reference '{}' is not supported here ({}); jumps against it are not computed", mesh.name,
                plan.reference.label, e.what());
    }
    for (const MethodSpec& m : plan.methods) {
      MethodRun& run = mr.methods.emplace_back();
      run.spec = m;
      run.options = plan.options_for(m);
      std::unique_ptr<vfe::Engine> engine = another_engine(mesh, mr.built);
      register_shapes(cfg, *engine);
      try {
        engine->configure(run.options);
        run.engine = std::move(engine);
      } catch (const vfe::Error& e) {
        if (!unsupported(e))
          throw vfe::Error(e.status(), "mesh '" + mesh.name + "', method '" + m.label + "': " + e.what());
        log->warn("mesh '{}': method '{}' skipped: {}", mesh.name, m.label, e.what());
        run.skipped_why = e.what();
      }
    }
  }

  RunResult result;
  result.output = out_dir;
  std::vector<PvdEntry> particle_pvd;
  std::int64_t done = 0;               // frames finished on every mesh
  std::int64_t first_timestep = frame.timestep, last_timestep = frame.timestep;

  // After a compute with coupling: the frame's weights as CSV and its Us field.
  auto coupling_outputs = [&](const MeshRun& mr, const std::string& label, const vfe::Engine& engine,
                              const SceneParticles& f, bool keep) {
    std::vector<double> us;
    if (!coupling) return us;
    fs::path rel = frame_file(mr.spec.name + "_weights_" + label, f.timestep);
    rel += ".csv";
    write_weights_csv(out_dir / rel, engine, f);
    if (keep) us = particle_velocity_field(engine, f);
    return us;
  };

  // Computes one frame on every mesh and method, then writes its files and keeps its rows.
  auto compute_frame = [&](const SceneParticles& f) {
    const double time = frame_time(f.timestep, dem_dt);
    const auto frame_start = Clock::now();
    std::vector<MeshFrame> computed(meshes.size());
    for (std::size_t mi = 0; mi < meshes.size(); ++mi) {
      MeshRun& mr = meshes[mi];
      MeshFrame& out = computed[mi];
      const std::size_t ncells = mr.built.cell_volumes.size();
      const bool keep_fields = vtk || mr.foam_here;
      std::vector<double> solid(ncells);
      if (mr.have_ref) {
        vfe::Engine& engine = *mr.built.engine;
        try {
          with_mesh_context(mr.spec, "reference '" + plan.reference.label + "', " + frame_where(f),
                            [&] { engine.compute(f.view(), solid); });
          out.ref.resize(ncells);
          engine.void_fraction(out.ref);
          if (!plan.reference_listed) {
            std::vector<double> us = coupling_outputs(mr, plan.reference.label, engine, f, keep_fields);
            if (keep_fields)
              out.fields.push_back({plan.reference.label, out.ref, solid, plan.options_for(plan.reference), std::move(us)});
          }
        } catch (const vfe::Error& e) {
          if (!unsupported(e)) throw;
          log->warn("mesh '{}': reference '{}' is not supported here ({}); jumps against it are not computed",
                    mr.spec.name, plan.reference.label, e.what());
          mr.have_ref = false;
          out.ref.clear();
        }
      }
      for (MethodRun& run : mr.methods) {
        std::optional<MeshFrame::Method>& slot = out.methods.emplace_back();
        if (!run.engine) continue;
        vfe::Engine& engine = *run.engine;
        MeshFrame::Method m;
        const auto t = Clock::now();
        with_mesh_context(mr.spec, "method '" + run.spec.label + "', " + frame_where(f),
                          [&] { engine.compute(f.view(), solid); });
        const double ms = ms_since(t);
        m.eps.resize(ncells);
        engine.void_fraction(m.eps);
        m.row = FrameRow{mr.spec.name, run.spec.label, run.spec.method, mr.chi, done, f.timestep, time, ms,
                         kNaN, kNaN, kNaN, 0};
        if (done > 0 && !out.ref.empty() && !mr.ref_previous.empty()) {
          const FrameJump j = frame_jump(run.previous, m.eps, mr.ref_previous, out.ref);
          m.row.max_excess = j.max_excess;
          m.row.mean_excess = j.mean_excess();
          m.row.max_exact_jump = j.max_reference_jump;
          m.row.changed_cells = j.changed_cells;
          m.jump = j;
        }
        log->debug("  mesh '{}', {}: {:.3f} ms, max excess jump {:.4f}", mr.spec.name, run.spec.label, ms,
                   m.row.max_excess);
        if (!run.overfull_warned) {
          const OverfullFacts overfull = overfull_facts(engine);
          run.overfull_warned = overfull.cells > 0;
          warn_overfull(*log, mr.spec.name, run.spec.label, overfull, f.total_volume());
          if (run.overfull_warned)
            log->info("  {}: first at timestep {} (later frames are not reported)", run.spec.label, f.timestep);
        }
        std::vector<double> us = coupling_outputs(mr, run.spec.label, engine, f, keep_fields);
        if (keep_fields) out.fields.push_back({run.spec.label, m.eps, solid, run.options, std::move(us)});
        slot = std::move(m);
      }
    }

    // The frame is computed everywhere: its files, then its rows.
    if (vtk) {
      fs::path rel = frame_file("particles", f.timestep);
      rel += ".vtp";
      write_vtp(out_dir / rel, f.centres, f.radii, f.velocities, f.ids);
      particle_pvd.push_back({time, rel});
      write_pvd(out_dir / "particles.pvd", particle_pvd);
    }
    for (std::size_t mi = 0; mi < meshes.size(); ++mi) {
      MeshRun& mr = meshes[mi];
      MeshFrame& out = computed[mi];
      if (vtk) {
        const fs::path written =
            write_mesh_vtk(out_dir / frame_file(mr.spec.name, f.timestep), mr.built, field_arrays(out.fields));
        mr.pvd.push_back({time, fs::path(kFramesFolder) / written.filename()});
        write_pvd(out_dir / (mr.spec.name + ".pvd"), mr.pvd);
      }
      if (mr.foam_here && !out.fields.empty()) {
        // 12 digits: 18000 * 1e-5 is the folder 0.18, not 0.18000000000000002.
        const std::string time_name = printf_number("%.12g", time);
        write_foam_time(out_dir / mr.spec.name / time_name, time_name, out.fields, plan, mr.patches, *log);
      }
      for (std::size_t k = 0; k < mr.methods.size(); ++k) {
        if (!out.methods[k]) continue;
        MethodRun& run = mr.methods[k];
        MeshFrame::Method& m = *out.methods[k];
        run.times.push_back(m.row.ms);
        if (m.jump) run.total.add(*m.jump);
        run.rows.push_back(m.row);
        run.previous = std::move(m.eps);
      }
      mr.ref_previous = std::move(out.ref);
    }
    last_timestep = f.timestep;
    ++done;
    log->info("frame {}{} (timestep {}, t = {:g}): computed in {:.1f} ms", done,
              known >= 0 ? "/" + std::to_string(known) : std::string(), f.timestep, time, ms_since(frame_start));
  };

  // The reports of the finished frames (after each frame, and when the series stops early).
  auto write_reports = [&](bool tables) {
    result.frames.clear();
    result.series.clear();
    for (const MeshRun& mr : meshes) {
      std::vector<SeriesRow> mesh_rows;
      for (const MethodRun& run : mr.methods) {
        SeriesRow summary{mr.spec.name, run.spec.label, run.spec.method, mr.chi, done, 0, kNaN, kNaN, kNaN,
                          !run.engine, run.skipped_why};
        if (run.engine) {
          result.frames.insert(result.frames.end(), run.rows.begin(), run.rows.end());
          summary.ms_median = run.times.empty() ? kNaN : median(run.times);
          if (run.total.max_excess > -std::numeric_limits<double>::infinity()) {  // a pair of frames was compared
            summary.max_excess = run.total.max_excess;
            summary.mean_excess = run.total.mean_excess();
            summary.max_exact_jump = run.total.max_reference_jump;
          }
        }
        mesh_rows.push_back(std::move(summary));
      }
      if (tables && opt.table) {
        char title[512];
        std::snprintf(title, sizeof title,
                      "\n%s / mesh %s: %zu cells (chi = %.2f), %lld frames (timesteps %lld to %lld), reference %s",
                      cfg.name.c_str(), mr.spec.name.c_str(), mr.built.cell_volumes.size(), mr.chi,
                      static_cast<long long>(done), static_cast<long long>(first_timestep),
                      static_cast<long long>(last_timestep), plan.reference_title().c_str());
        print_series_table(*opt.table, title, mesh_rows);
      }
      result.series.insert(result.series.end(), mesh_rows.begin(), mesh_rows.end());
    }
    write_frames_csv(out_dir / "frames.csv", result.frames);
    write_jumps_csv(out_dir / "frame_jumps.csv", result.series);
  };

  try {
    do {
      compute_frame(frame);
      write_reports(false);
    } while (frames->next(frame));
  } catch (const std::exception& e) {
    // What the finished frames computed stays: their files are written, and the reports.
    if (done > 0) {
      try {
        write_reports(true);
        log->error("the series stopped after {} frame(s) (timesteps {} to {}); their results are in {}", done,
                   first_timestep, last_timestep, out_dir.string());
      } catch (const std::exception& w) {
        log->error("could not write the reports of the finished frames: {}", w.what());
      }
    }
    throw;
  }
  write_reports(true);
  if (vtk) log->info("wrote {} .pvd collections of {} frames in {}", meshes.size() + 1, done, out_dir.string());
  if (coupling) log->info("wrote the weights of every frame in {}", (out_dir / kFramesFolder).string());
  log->info("wrote {} and {}", (out_dir / "frames.csv").string(), (out_dir / "frame_jumps.csv").string());
  return result;
}

}  // namespace vfe::apps
