// YAML scene configuration of `vfe run`.
#pragma once

#include <vfe/engine.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace vfe::apps {

/// Bad configuration; the message names the file, the line when known, and the problem.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One mesh of the scene: type cartesian or polymesh.
/// Cartesian grids are given either by origin + spacing + cells, or by bounds (the
/// particles' BOX BOUNDS or an explicit box) + spacing or cells.
/// An OpenFOAM polyMesh is given by path: its case folder, its constant folder or the
/// polyMesh folder itself (resolved against the config's folder).
struct MeshSpec {
  std::string name;
  std::string type = "cartesian";  ///< "cartesian", "rectilinear" or "polymesh"
  /// rectilinear: node coordinates per axis, each given as a list or as
  /// {lo, hi, cells, grading} (grading = last cell size / first, as blockMesh's).
  std::array<std::vector<double>, 3> nodes;
  std::filesystem::path path;      ///< polymesh: the folder, resolved against the config's folder
  std::optional<std::array<double, 3>> origin;
  std::optional<std::array<double, 3>> spacing;
  std::optional<std::array<std::int64_t, 3>> cells;
  bool bounds_particles_box = false;           ///< bounds: particles_box
  std::optional<std::array<double, 6>> bounds; ///< bounds: [xlo, xhi, ylo, yhi, zlo, zhi]
  int line = 0;                                ///< line in the config file (1-based, 0 unknown)
};

/// One method to run: engine method name, its own options, and a label for reports.
/// settings: option strings swept on top of options (particle grids, sigma, gamma): `vfe
/// study` runs each as one point of the method's family; `vfe run` runs each as a method of
/// its own (see expand_settings). Empty = the options alone.
struct MethodSpec {
  std::string method;
  std::string options;
  std::string label;
  std::vector<std::string> settings;
};

/// A named particle shape of the scene (`shapes:` list). spec is an Engine::add_shape spec;
/// a mesh file in it is resolved against the config's folder.
struct ShapeEntry {
  std::string name;
  std::string spec;
  int line = 0;  ///< line in the config file (1-based, 0 unknown)
};

/// Generated particles (`particles: {generate: {...}}`): count particles of one shape and
/// scale, centres uniformly at random in box (seeded), random unit quaternions
/// (orientations: random, run with orientation=given) or none (orientation=none).
struct GenerateSpec {
  std::int64_t count = 0;
  std::string shape;                   ///< a name of the shapes list
  double scale = 0;                    ///< the shape's scale (its unit length)
  std::array<double, 6> box{};         ///< xlo xhi ylo yhi zlo zhi: where the centres lie
  std::uint64_t seed = 1;
  std::string orientations = "random";  ///< "random" or "none"
};

/// A scene whose particles are a series of frames, computed one after another. The
/// frames are every frame of the listed dumps (globs expanded), in TIMESTEP order, or the
/// frames a command prints, as they come; timesteps keeps those in [from, to], then frames
/// keeps the indices [first, last] of what is left.
struct FrameSeriesSpec {
  /// Dump paths or glob patterns (* ? [...]), resolved against the config's folder.
  std::vector<std::string> files;
  /// Instead of files: a shell command, run in the config's folder, that prints LIGGGHTS/
  /// LAMMPS text dump frames on its standard output (e.g. the live LIGGGHTS driver).
  std::string command;
  std::filesystem::path command_folder;  ///< where the command runs: the config's folder
  std::int64_t first_frame = 0;  ///< 0-based index in the ordered series; negative counts from the end
  std::int64_t last_frame = -1;  ///< inclusive; -1 = the last frame
  std::optional<std::int64_t> from_timestep, to_timestep;  ///< inclusive bounds of the timesteps kept
  double dem_dt = 0;  ///< DEM time step: a frame's time is timestep * dem_dt (0 = not given: the timestep)
  int line = 0;       ///< line of the particles entry in the config (1-based, 0 unknown)
};

struct SceneConfig {
  std::string name;
  std::filesystem::path source;          ///< the config file (for messages)
  std::filesystem::path particles_file;  ///< resolved against the config's folder (empty when generated)
  std::int64_t frame = -1;               ///< 0-based, negative from the end (-1 = last)
  /// Shapes of the scene, in order (shape id i = shapes[i] on every engine).
  std::vector<ShapeEntry> shapes;
  /// Dump particles: value of the dump's `shape` column (else `type`) -> shape name.
  std::map<std::int64_t, std::string> shape_by_type;
  std::optional<GenerateSpec> generate;  ///< particles generated instead of read
  /// The particles are a series of frames (particles: files, or frames: all / [first, last]).
  std::optional<FrameSeriesSpec> series;
  std::vector<MeshSpec> meshes;
  /// Cartesian grids over the particles' box with cubic cells of spacing chi * mean particle
  /// diameter, one per value (named chi_<value>), after the listed meshes.
  std::vector<double> chi;
  std::vector<MethodSpec> methods;
  /// Default: exact for spheres; for shaped particles (exact takes spheres only) pmm with
  /// particle_grid=4000.
  MethodSpec reference{"exact", "", "exact", {}};
  int threads = 0;
  int repeats = 5;
  std::string options;                   ///< applied to every method (before its own)
  std::filesystem::path output;          ///< resolved against the config's folder
  bool vtk = false;                      ///< write <mesh>.vti / <mesh>.vtu
  bool foam = false;                     ///< write OpenFOAM voidfraction fields (polyMesh meshes)
  /// Runs with weights=1 and writes the coupling fields: the particle velocity Us per cell
  /// (VTK, and OpenFOAM's Us beside voidfraction) and the per-particle weights as CSV.
  bool coupling = false;

  /// True when the particles carry shapes (generated, or a dump with shape_by_type).
  bool shaped() const { return generate.has_value() || !shape_by_type.empty(); }
  /// Index of a shape name in shapes, -1 if unknown.
  int shape_index(const std::string& shape_name) const;
};

/// The reference of shaped scenes when the config names none.
MethodSpec default_shape_reference();

/// Reads and validates a config file. Relative paths in it are relative to its folder.
SceneConfig load_config(const std::filesystem::path& file);

/// Keeps only the methods labelled in `labels` (in the config's order; empty keeps every
/// one), as `vfe study --families` and `vfe run --methods` select them; the reference stays.
/// Throws ConfigError naming an unknown label and the config's labels.
void keep_methods(SceneConfig& config, const std::vector<std::string>& labels);

/// Parses config text; base_dir resolves relative paths, source names the text in messages.
SceneConfig parse_config(const std::string& text, const std::filesystem::path& base_dir,
                         const std::string& source);

/// The grid of a Cartesian mesh (ConfigError for a polymesh). particles_box (xlo xhi ylo yhi zlo zhi) is needed for
/// bounds: particles_box. When spacing does not divide the box, the grid keeps the spacing,
/// rounds the cell count up and *note says so. Throws ConfigError.
vfe::CartesianGridSpec resolve_grid(const MeshSpec& mesh, const std::array<double, 6>* particles_box,
                                    const std::string& source, std::string* note = nullptr);

/// The polyMesh folder (holding points, faces, owner, neighbour, boundary) of a polymesh
/// path: dir/constant/polyMesh, dir/polyMesh or dir itself, whichever exists first. Files may
/// be gzipped (name.gz). Empty when there is none.
std::filesystem::path find_polymesh_folder(const std::filesystem::path& dir);

/// Checks that every polymesh mesh's path holds a polyMesh; throws ConfigError naming the
/// mesh, its line in the config, the path and what was expected.
void check_mesh_paths(const SceneConfig& config);

/// The mesh of one chi value: bounds particles_box, spacing chi * mean_diameter (kept
/// exactly: the grid extends past the box when the spacing does not divide it).
MeshSpec chi_mesh(double chi, double mean_diameter);

/// Name of the mesh of one chi value: "chi_" followed by the value (e.g. chi_0.75).
std::string chi_mesh_name(double chi);

/// One method per setting: label "<label>_<setting>" ('=' as '-', blanks as '_'), options
/// "<options> <setting>". Methods without settings are kept as they are.
std::vector<MethodSpec> expand_settings(const std::vector<MethodSpec>& methods);

/// Merges option strings "key=value ..." left to right (a later key replaces an earlier
/// one, keeping the first position). Throws ConfigError on a token without '='.
std::string merge_options(const std::vector<std::string>& parts);

/// Engine options every method of a scene starts from, later ones winning: the config's
/// threads, the particle source's options (e.g. orientation=given for quaternions), the
/// config's options, then a command-line thread count. Errors name `source`.
std::string scene_options(const SceneConfig& cfg, std::optional<int> threads, const std::string& particle_options,
                          const std::string& source);

}  // namespace vfe::apps
