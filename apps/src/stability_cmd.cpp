#include "stability_cmd.hpp"

#include "text_format.hpp"

#include <vfe/engine.hpp>
#include <vfe/vfe.h>

#include <spdlog/logger.h>
#include <spdlog/sinks/null_sink.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <ostream>
#include <stdexcept>

namespace vfe::apps {

namespace {

namespace fs = std::filesystem;

/// Nine significant digits: the stability files' own precision.
std::string num(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string jnum(double v) { return std::isfinite(v) ? num(v) : "null"; }

/// Engine options of a (template, orientation) on top of the command's own.
std::string family_options(const StabilityCommand& c, const std::string& tmpl, const std::string& orient) {
  std::string s = c.options;
  if (!tmpl.empty()) s += " template=" + tmpl;
  if (!orient.empty()) s += " orientation=" + orient;
  return s;
}

vfe::StabilityOptions base_options(const StabilityCommand& c, double chi, const std::string& engine_options) {
  vfe::StabilityOptions o;
  o.chi = chi;
  o.method = c.method;
  o.engine_options = engine_options;
  o.step = c.step;
  o.cells = c.cells;
  o.trajectories = c.trajectories;
  o.seed = c.seed;
  o.jump_criterion = c.jump_criterion;
  o.superficial_velocity = c.superficial_velocity;
  o.fluid_dt = c.fluid_dt;
  o.diameter = c.diameter;
  o.threads = c.threads;
  o.shape = c.shape;
  o.reference_grid = c.reference_grid;
  return o;
}

/// Smallest n of rows (sorted by n) from which every larger one passes; -1 if the
/// largest fails.
template <class Pass>
std::int64_t smallest_stable(const std::vector<const StabilityRow*>& rows, Pass&& pass, double* excess = nullptr) {
  std::int64_t n = -1;
  for (auto it = rows.rbegin(); it != rows.rend(); ++it) {
    if (!pass((*it)->result)) break;
    n = (*it)->result.grid_max;
    if (excess) *excess = (*it)->result.excess_jump;
  }
  return n;
}

void print_block(std::ostream& out, const std::string& title, const std::vector<StabilityRow>& rows,
                 std::size_t first, bool flux, bool shaped) {
  out << '\n' << title << '\n';
  char line[256];
  std::snprintf(line, sizeof line, "%-8s %7s %11s %8s %11s %11s %7s %6s", "grid", "n", "J", "J/unit",
                "max|deps|", shaped ? "max|ref|" : "max|exact|", "stable", "unst");
  out << line << (flux ? "   psi_max  psi_J  flux" : "") << '\n';
  for (std::size_t i = first; i < rows.size(); ++i) {
    const auto& r = rows[i].result;
    std::snprintf(line, sizeof line, "%-8s %7lld %11.3e %8.2f %11.3e %11.3e %7s %6d", r.particle_grid.c_str(),
                  static_cast<long long>(r.grid_max), r.excess_jump, r.excess_in_sub_elements, r.max_jump,
                  r.max_jump_exact, r.stable ? "yes" : "NO", r.unstable_trajectories);
    out << line;
    if (flux) {
      std::snprintf(line, sizeof line, " %9.3g %6.3g %5s", r.psi_max, r.psi_excess, r.flux_stable ? "yes" : "NO");
      out << line;
    }
    out << '\n';
  }
}

/// The reference of the jumps: exact for spheres, ellipsoids and meshes, a fine pmm for
/// the other shapes.
std::string reference_name(const StabilityCommand& c) {
  vfe::StabilityOptions o;
  o.shape = c.shape;
  o.reference_grid = c.reference_grid;
  return vfe::stability_reference(o).substr(std::string("method=").size());
}

void write_csv(const fs::path& file, const StabilityCommand& c, const std::vector<StabilityRow>& rows) {
  std::ofstream out(file);
  check_written(out, file);
  out << "method,template,orientation,chi,particle_grid,n_min_used,n,trajectories,step,cells,steps,seed,"
         "jump_criterion,J,J_mean,J_sub_elements,max_jump,max_jump_exact,stable,unstable_trajectories,"
         "worst_trajectory,flux_criterion,psi_max,psi_J,flux_stable,shape,reference\n";
  for (const auto& row : rows) {
    const auto& r = row.result;
    const double flux = c.superficial_velocity > 0 ? c.superficial_velocity * c.fluid_dt / (row.chi * c.diameter) : 0;
    const auto steps = static_cast<long long>(std::ceil(c.cells * row.chi / c.step - 1e-9));
    out << c.method << ',' << row.template_family << ',' << row.orientation << ',' << num(row.chi) << ','
        << r.particle_grid << ',' << r.grid_min << ',' << r.grid_max << ',' << c.trajectories << ','
        << num(c.step) << ',' << num(c.cells) << ',' << steps << ',' << c.seed << ',' << num(c.jump_criterion)
        << ',' << num(r.excess_jump) << ',' << num(r.mean_excess_jump) << ',' << num(r.excess_in_sub_elements)
        << ',' << num(r.max_jump) << ',' << num(r.max_jump_exact) << ',' << (r.stable ? 1 : 0) << ','
        << r.unstable_trajectories << ',' << r.worst_trajectory << ',' << num(flux) << ',' << num(r.psi_max)
        << ',' << num(r.psi_excess) << ',' << (flux > 0 ? (r.flux_stable ? "1" : "0") : "") << ','
        << (c.shape.empty() ? "sphere" : "\"" + c.shape + "\"") << ',' << reference_name(c) << '\n';
  }
  check_written(out, file);
}

void write_n_min_csv(const fs::path& file, const StabilityCommand& c, const std::vector<NMinRow>& rows) {
  std::ofstream out(file);
  check_written(out, file);
  out << "method,template,orientation,chi,n_min,J_at_n_min,n_min_flux,n_tested_max,jump_criterion,"
         "flux_criterion,trajectories,step\n";
  for (const auto& r : rows) {
    const double flux = c.superficial_velocity > 0 ? c.superficial_velocity * c.fluid_dt / (r.chi * c.diameter) : 0;
    out << c.method << ',' << r.template_family << ',' << r.orientation << ',' << num(r.chi) << ',' << r.n_min
        << ',' << num(r.excess_at_n_min) << ',' << r.n_min_flux << ',' << r.n_tested_max << ','
        << num(c.jump_criterion) << ',' << num(flux) << ',' << c.trajectories << ',' << num(c.step) << '\n';
  }
  check_written(out, file);
}

void write_json(const fs::path& file, const StabilityCommand& c, const StabilityOutcome& o) {
  std::ofstream out(file);
  check_written(out, file);
  out << "{\n  \"version\": " << json_string(vfe_version()) << ",\n";
  out << "  \"method\": " << json_string(c.method) << ",\n";
  out << "  \"options\": " << json_string(c.options) << ",\n";
  out << "  \"shape\": " << json_string(c.shape.empty() ? "sphere" : c.shape) << ",\n";
  out << "  \"reference\": " << json_string(reference_name(c)) << ",\n";
  out << "  \"step\": " << jnum(c.step) << ",\n  \"cells\": " << jnum(c.cells)
      << ",\n  \"trajectories\": " << c.trajectories << ",\n  \"seed\": " << c.seed
      << ",\n  \"jump_criterion\": " << jnum(c.jump_criterion) << ",\n  \"superficial_velocity\": "
      << jnum(c.superficial_velocity) << ",\n  \"fluid_dt\": " << jnum(c.fluid_dt)
      << ",\n  \"diameter\": " << jnum(c.diameter) << ",\n  \"sweep\": " << (c.sweep ? "true" : "false")
      << ",\n  \"results\": [";
  for (std::size_t i = 0; i < o.rows.size(); ++i) {
    const auto& row = o.rows[i];
    const auto& r = row.result;
    out << (i ? "," : "") << "\n    {\"template\": " << json_string(row.template_family)
        << ", \"orientation\": " << json_string(row.orientation) << ", \"chi\": " << jnum(row.chi)
        << ", \"particle_grid\": " << json_string(r.particle_grid) << ", \"n_min_used\": " << r.grid_min
        << ", \"n\": " << r.grid_max << ", \"J\": " << jnum(r.excess_jump) << ", \"J_mean\": "
        << jnum(r.mean_excess_jump) << ", \"J_sub_elements\": " << jnum(r.excess_in_sub_elements)
        << ", \"max_jump\": " << jnum(r.max_jump) << ", \"max_jump_exact\": " << jnum(r.max_jump_exact)
        << ", \"stable\": " << (r.stable ? "true" : "false")
        << ", \"unstable_trajectories\": " << r.unstable_trajectories
        << ", \"worst_trajectory\": " << r.worst_trajectory;
    if (c.superficial_velocity > 0)
      out << ", \"psi_max\": " << jnum(r.psi_max) << ", \"psi_J\": " << jnum(r.psi_excess)
          << ", \"flux_stable\": " << (r.flux_stable ? "true" : "false");
    out << "}";
  }
  out << "\n  ]";
  if (c.sweep) {
    out << ",\n  \"n_min\": [";
    for (std::size_t i = 0; i < o.n_min.size(); ++i) {
      const auto& r = o.n_min[i];
      out << (i ? "," : "") << "\n    {\"template\": " << json_string(r.template_family)
          << ", \"orientation\": " << json_string(r.orientation) << ", \"chi\": " << jnum(r.chi)
          << ", \"n_min\": " << r.n_min << ", \"J_at_n_min\": " << jnum(r.excess_at_n_min)
          << ", \"n_min_flux\": " << r.n_min_flux << ", \"n_tested_max\": " << r.n_tested_max << "}";
    }
    out << "\n  ]";
  }
  out << "\n}\n";
  check_written(out, file);
}

}  // namespace

std::vector<std::string> default_sweep_grids() {
  std::vector<std::string> g;
  for (int n : {1,    2,    3,    4,    5,    6,    8,    10,   12,   15,   20,   25,   30,   40,
                50,   60,   80,   100,  125,  150,  200,  250,  300,  400,  500,  600,  800,  1000,
                1250, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 8000, 10000, 12500, 16000, 20000})
    g.push_back(std::to_string(n));
  return g;
}

StabilityOutcome run_stability(const StabilityCommand& c) {
  auto log = c.logger ? c.logger : std::make_shared<spdlog::logger>("vfe-app", std::make_shared<spdlog::sinks::null_sink_mt>());
  if (c.chi.empty()) throw std::runtime_error("stability: give at least one chi (--chi)");
  for (double chi : c.chi)
    if (!(chi > 0) || !std::isfinite(chi)) throw std::runtime_error("stability: chi must be > 0 (got " + num(chi) + ")");
  const bool has_grid = c.method == "pmm";
  const std::vector<std::string> templates = has_grid && !c.templates.empty() ? c.templates : std::vector<std::string>{""};
  const std::vector<std::string> orientations =
      has_grid && !c.orientations.empty() ? c.orientations : std::vector<std::string>{""};
  const bool flux = c.superficial_velocity > 0 && c.fluid_dt > 0;

  StabilityOutcome outcome;
  outcome.output = c.output;
  std::error_code ec;
  fs::create_directories(c.output, ec);
  if (ec) throw std::runtime_error("cannot create output folder " + c.output.string() + ": " + ec.message());

  vfe::Engine probe(vfe::CartesianGridSpec{});
  const std::string defaults = probe.options();
  const auto t0 = std::chrono::steady_clock::now();
  for (const auto& tmpl : templates) {
    for (const auto& orient : orientations) {
      const std::string eopts = family_options(c, tmpl, orient);
      probe.configure(defaults);  // then the family's own: an option string names each key once
      probe.configure(eopts);
      const std::string tname = has_grid ? probe.option("template") : "-";
      const std::string oname = !c.shape.empty() ? "given" : has_grid ? probe.option("orientation") : "-";
      for (double chi : c.chi) {
        const std::string title = c.method + (has_grid ? " template=" + tname + " orientation=" + oname : "") +
                                  " chi=" + num(chi) +
                                  (c.shape.empty() ? std::string()
                                                   : " shape \"" + c.shape + "\" (reference " + reference_name(c) + ")");
        const std::size_t first = outcome.rows.size();
        auto run = [&](const std::vector<std::string>& grids) {
          vfe::StabilityOptions o = base_options(c, chi, eopts);
          o.particle_grids = grids;
          const vfe::StabilityReport rep = vfe::stability_test(o);
          if (outcome.steps_per_trajectory_first == 0) {
            outcome.steps_per_trajectory_first = rep.steps;
            outcome.flux_criterion_first = rep.flux_criterion;
          }
          for (const auto& r : rep.results) outcome.rows.push_back({tname, oname, chi, r});
          log->info("{}: grids {}..{} done ({} steps x {} trajectories, {:.1f} s so far)", title,
                    rep.results.front().particle_grid, rep.results.back().particle_grid, rep.steps, c.trajectories,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        };
        if (!c.sweep || !has_grid) {
          run(c.grids);
        } else {
          // The ladder, one requested grid per distinct template size at this chi.
          std::vector<std::pair<std::int64_t, std::string>> ladder;
          for (const auto& g : c.grids.empty() ? default_sweep_grids() : c.grids) {
            probe.configure("particle_grid=" + g);
            const std::int64_t n = probe.particle_grid_for(1.0, chi);
            if (std::none_of(ladder.begin(), ladder.end(), [n](const auto& e) { return e.first == n; }))
              ladder.push_back({n, g});
          }
          std::sort(ladder.begin(), ladder.end());
          // Batches in ascending n until the last three tested pass every criterion and
          // n reaches twice the smallest passing one (or the ladder ends).
          std::size_t next = 0;
          constexpr std::size_t kBatch = 4;
          while (next < ladder.size()) {
            std::vector<std::string> batch;
            for (; next < ladder.size() && batch.size() < kBatch; ++next) batch.push_back(ladder[next].second);
            run(batch);
            std::vector<const StabilityRow*> tested;
            for (std::size_t i = first; i < outcome.rows.size(); ++i) tested.push_back(&outcome.rows[i]);
            if (tested.size() < 3) continue;
            bool done = true;
            for (std::size_t i = tested.size() - 3; i < tested.size(); ++i)
              done &= tested[i]->result.stable && (!flux || tested[i]->result.flux_stable);
            const std::int64_t nm = smallest_stable(tested, [](const vfe::StabilityResult& r) { return r.stable; });
            done &= nm > 0 && tested.back()->result.grid_max >= 2 * nm;
            if (done) break;
          }
          std::vector<const StabilityRow*> tested;
          for (std::size_t i = first; i < outcome.rows.size(); ++i) tested.push_back(&outcome.rows[i]);
          std::sort(tested.begin(), tested.end(),
                    [](const StabilityRow* a, const StabilityRow* b) { return a->result.grid_max < b->result.grid_max; });
          NMinRow nr;
          nr.template_family = tname;
          nr.orientation = oname;
          nr.chi = chi;
          nr.n_min = smallest_stable(tested, [](const vfe::StabilityResult& r) { return r.stable; }, &nr.excess_at_n_min);
          if (flux) nr.n_min_flux = smallest_stable(tested, [](const vfe::StabilityResult& r) { return r.flux_stable; });
          nr.n_tested_max = tested.empty() ? 0 : tested.back()->result.grid_max;
          outcome.n_min.push_back(nr);
          log->info("{}: n_min = {}{}", title, nr.n_min, flux ? ", flux n_min = " + std::to_string(nr.n_min_flux) : "");
        }
        if (c.table) print_block(*c.table, title, outcome.rows, first, flux, !c.shape.empty());
      }
    }
  }

  if (c.table && c.sweep && !outcome.n_min.empty()) {
    *c.table << "\nn_min (J <= " << printf_number("%.5g", c.jump_criterion) << (flux ? "; flux: psi_J <= 1" : "")
             << ", " << c.trajectories << " trajectories)\n";
    char line[160];
    std::snprintf(line, sizeof line, "%-10s %-11s %6s %7s %11s %9s %9s", "template", "orientation", "chi", "n_min",
                  "J(n_min)", "27/chi^3", "flux");
    *c.table << line << '\n';
    for (const auto& r : outcome.n_min) {
      std::snprintf(line, sizeof line, "%-10s %-11s %6.3g %7lld %11.3e %9.2f %9lld", r.template_family.c_str(),
                    r.orientation.c_str(), r.chi, static_cast<long long>(r.n_min), r.excess_at_n_min,
                    27.0 / (r.chi * r.chi * r.chi), static_cast<long long>(r.n_min_flux));
      *c.table << line << '\n';
    }
  }

  write_csv(c.output / "stability.csv", c, outcome.rows);
  if (c.sweep) write_n_min_csv(c.output / "n_min.csv", c, outcome.n_min);
  write_json(c.output / "stability.json", c, outcome);
  log->info("wrote {}", (c.output / "stability.csv").string());
  return outcome;
}

}  // namespace vfe::apps
