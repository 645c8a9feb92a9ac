// The Python module vfe._core: the C++ facade (vfe/engine.hpp), the stability stress test
// and the accuracy measures, over numpy arrays. Uses the engine's public headers only.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <vfe/engine.hpp>
#include <vfe/measures.hpp>
#include <vfe/stability.hpp>
#include <vfe/vfe.h>

#include <cstdint>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace py = pybind11;

namespace {

/// vfe.Error, set up in PYBIND11_MODULE; a subclass of RuntimeError.
PyObject* error_type = nullptr;

/// Raises vfe.Error with .status (the status name) and .message; str() is "NAME: message".
[[noreturn]] void raise_error(const std::string& status, const std::string& message) {
  py::object type = py::reinterpret_borrow<py::object>(error_type);
  py::object exc = type(status + ": " + message);
  exc.attr("status") = status;
  exc.attr("message") = message;
  PyErr_SetObject(error_type, exc.ptr());
  throw py::error_already_set();
}

/// An array's shape as Python prints it, for messages: "(4, 2)", "(5,)".
std::string shape_text(const py::array& a) {
  std::string t = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) t += (d ? ", " : "") + std::to_string(a.shape(d));
  return t + (a.ndim() == 1 ? ",)" : ")");
}

/// The type name of an array's dtype, for messages.
std::string dtype_name(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

/// A particle array as the engine reads it: a pointer and a stride (in elements) between
/// consecutive particles, viewing the caller's buffer when its layout allows, else a
/// contiguous copy (counted in `copies`).
template <class T>
struct Column {
  py::array_t<T> held;  // the array whose memory `data` points into
  const T* data = nullptr;
  std::int64_t stride = 0;
};

/// Checks dtype and shape ((n,) when width == 0, else (n, width)) and returns a view.
/// Zero copy when the inner axis is contiguous and the outer stride is a positive multiple
/// of the element size (any row stride: a column slice of a wider table is read in place);
/// otherwise (Fortran order, negative or broadcast strides) one contiguous copy.
template <class T>
Column<T> column(const py::handle& obj, const char* name, const char* dtype, py::ssize_t n, py::ssize_t width,
                 int& copies) {
  if (!py::isinstance<py::array>(obj))
    throw py::value_error(std::string(name) + " must be a numpy array of " + dtype + " (got " +
                          py::str(py::type::of(obj)).cast<std::string>() + "); use np.asarray(" + name +
                          ", dtype=np." + dtype + ")");
  py::array a = py::reinterpret_borrow<py::array>(obj);
  if (!py::dtype::of<T>().is(a.dtype()) && !a.dtype().equal(py::dtype::of<T>()))
    throw py::value_error(std::string(name) + " must have dtype " + dtype + " (got " + dtype_name(a) +
                          "); convert with np.asarray(" + name + ", dtype=np." + dtype + ")");
  const py::ssize_t want_ndim = width == 0 ? 1 : 2;
  std::string want_shape = "(" + std::to_string(n) + (width == 0 ? ",)" : ", " + std::to_string(width) + ")");
  if (a.ndim() != want_ndim || a.shape(0) != n || (width != 0 && a.shape(1) != width)) {
    throw py::value_error(std::string(name) + " must have shape " + want_shape + " (got " + shape_text(a) + ")");
  }
  Column<T> c;
  const auto el = static_cast<py::ssize_t>(sizeof(T));
  const bool inner_ok = width == 0 || a.strides(1) == el;
  const bool outer_ok = n <= 1 || (a.strides(0) > 0 && a.strides(0) % el == 0);
  if (inner_ok && outer_ok && n > 0) {
    c.held = py::reinterpret_borrow<py::array_t<T>>(a);
    c.data = static_cast<const T*>(a.data());
    c.stride = n <= 1 ? (width == 0 ? 1 : width) : a.strides(0) / el;
  } else {
    c.held = py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
    c.data = c.held.data();
    c.stride = width == 0 ? 1 : width;
    if (n > 0) ++copies;
  }
  return c;
}

template <class T>
std::span<T> as_span(py::array_t<T>& a) {
  return {a.mutable_data(), static_cast<std::size_t>(a.size())};
}

/// A float64 table of `rows` rows, (rows,) or (rows, k), C-contiguous (copied if not).
struct Components {
  py::array_t<double, py::array::c_style | py::array::forcecast> data;
  std::int32_t k = 1;
  bool two_d = false;
  std::span<const double> span() const { return {data.data(), static_cast<std::size_t>(data.size())}; }
  /// A new array of `rows` rows with the same components.
  py::array_t<double> like(py::ssize_t rows) const {
    return two_d ? py::array_t<double>({rows, py::ssize_t{k}}) : py::array_t<double>(rows);
  }
};

Components components(const py::object& obj, const char* name, py::ssize_t rows, const char* what) {
  if (!py::isinstance<py::array>(obj) ||
      !py::reinterpret_borrow<py::array>(obj).dtype().equal(py::dtype::of<double>()))
    throw py::value_error(std::string(name) + " must be a float64 numpy array; use np.asarray(" + name +
                          ", dtype=np.float64)");
  py::array a = py::reinterpret_borrow<py::array>(obj);
  if ((a.ndim() != 1 && a.ndim() != 2) || a.shape(0) != rows || (a.ndim() == 2 && a.shape(1) < 1))
    throw py::value_error(std::string(name) + " must have shape (" + std::to_string(rows) + ",) or (" +
                          std::to_string(rows) + ", k), one row per " + what + " (got " + shape_text(a) + ")");
  Components c;
  c.two_d = a.ndim() == 2;
  c.k = c.two_d ? static_cast<std::int32_t>(a.shape(1)) : 1;
  c.data = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  return c;
}

/// A 1-D (width 0) or (n, width) array of exactly dtype T, C-contiguous (copied if not).
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> mesh_array(const py::object& obj, const char* name,
                                                                      const char* dtype, py::ssize_t width) {
  if (!py::isinstance<py::array>(obj) || !py::reinterpret_borrow<py::array>(obj).dtype().equal(py::dtype::of<T>()))
    throw py::value_error(std::string(name) + " must be a numpy array of " + dtype + "; use np.asarray(" + name +
                          ", dtype=np." + dtype + ")");
  py::array a = py::reinterpret_borrow<py::array>(obj);
  if (a.ndim() != (width ? 2 : 1) || (width && a.shape(1) != width))
    throw py::value_error(std::string(name) + " must have shape " + (width ? "(n, 3)" : "(n,)") + " (got " +
                          shape_text(a) + ")");
  return py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
}

/// The particle count of a centres argument, or a clear error.
py::ssize_t particle_count(const py::handle& centres) {
  if (!py::isinstance<py::array>(centres))
    throw py::value_error("centres must be a numpy array of float64 with shape (n, 3) (got " +
                          py::str(py::type::of(centres)).cast<std::string>() + ")");
  py::array a = py::reinterpret_borrow<py::array>(centres);
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw py::value_error("centres must have shape (n, 3) (got " + shape_text(a) + ")");
  }
  return a.shape(0);
}

/// A Python value as an option value: bools as 0/1, ints, floats (round-trip repr) and
/// strings without blanks or '='.
std::string option_value(const std::string& key, const py::handle& v) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>() ? "1" : "0";
  if (py::isinstance<py::int_>(v) || py::isinstance<py::float_>(v)) return py::repr(v).cast<std::string>();
  if (py::isinstance<py::str>(v)) {
    const std::string s = v.cast<std::string>();
    if (s.empty() || s.find_first_of(" \t\n=") != std::string::npos)
      throw py::value_error("option " + key + "='" + s + "': a value must be one word without blanks or '='");
    return s;
  }
  throw py::value_error("option " + key + ": give an int, float, bool or str (got " +
                        py::str(py::type::of(v)).cast<std::string>() + ")");
}

/// One engine and the lock that keeps two Python threads from using it at once (the engine
/// is not thread-safe; distinct engines are independent and compute in parallel).
class PyEngine {
 public:
  template <class Spec>
  explicit PyEngine(const Spec& spec) : engine_(spec) {}

  void configure(const std::string& options, const py::kwargs& kw) {
    std::string all = options;
    for (const auto& [k, v] : kw) {
      const std::string key = py::str(k).cast<std::string>();
      all += (all.empty() ? "" : " ") + key + "=" + option_value(key, v);
    }
    auto lock = acquire();
    engine_.configure(all);
  }

  py::dict options() {
    auto lock = acquire();
    const std::string text = engine_.options();
    py::dict d;
    std::size_t i = 0;
    while (i < text.size()) {
      std::size_t j = text.find(' ', i);
      if (j == std::string::npos) j = text.size();
      const std::string kv = text.substr(i, j - i);
      const std::size_t eq = kv.find('=');
      if (eq != std::string::npos) d[py::str(kv.substr(0, eq))] = kv.substr(eq + 1);
      i = j + 1;
    }
    return d;
  }

  std::string option(const std::string& key) {
    auto lock = acquire();
    return engine_.option(key);
  }

  std::int64_t cell_count() { return engine_.cell_count(); }
  bool is_polymesh() { return engine_.is_polymesh(); }

  py::array_t<double> cell_volumes() {
    py::array_t<double> out(engine_.cell_count());
    auto lock = acquire();
    engine_.cell_volumes(std::span<double>(out.mutable_data(), static_cast<std::size_t>(out.size())));
    return out;
  }

  py::array_t<double> cell_centres() {
    const auto n = static_cast<py::ssize_t>(engine_.cell_count());
    py::array_t<double> out({n, py::ssize_t{3}});
    auto lock = acquire();
    engine_.cell_centres(std::span<double>(out.mutable_data(), static_cast<std::size_t>(out.size())));
    return out;
  }

  py::array_t<double> compute(const py::object& centres, const py::object& radii, const py::object& orientations,
                              const py::object& shape_ids, const py::object& ids, const py::object& out) {
    const py::ssize_t n = particle_count(centres);
    int copies = 0;
    const Column<double> c = column<double>(centres, "centres", "float64", n, 3, copies);
    const Column<double> r = column<double>(radii, "radii", "float64", n, 0, copies);
    std::optional<Column<double>> q;
    if (!orientations.is_none()) q = column<double>(orientations, "orientations", "float64", n, 4, copies);
    std::optional<Column<std::int32_t>> s;
    if (!shape_ids.is_none()) s = column<std::int32_t>(shape_ids, "shape_ids", "int32", n, 0, copies);
    std::optional<Column<std::int64_t>> id;
    if (!ids.is_none()) id = column<std::int64_t>(ids, "ids", "int64", n, 0, copies);
    py::array_t<double> result;
    if (out.is_none()) {
      result = py::array_t<double>(engine_.cell_count());
    } else {
      // Written in place, so it must be exactly the field's layout.
      const bool ok = py::isinstance<py::array>(out) &&
                      py::reinterpret_borrow<py::array>(out).dtype().equal(py::dtype::of<double>());
      if (ok) result = py::reinterpret_borrow<py::array_t<double>>(out);
      if (!ok || result.ndim() != 1 || result.shape(0) != engine_.cell_count() ||
          !(result.flags() & py::array::c_style) || !result.writeable())
        throw py::value_error("out must be a writeable C-contiguous float64 array of shape (" +
                              std::to_string(engine_.cell_count()) + ",)");
    }
    // The C API's view: byte strides, optional shape ids and host ids, all read in place.
    vfe_particles view{};
    view.n = n;
    view.centres = c.data;
    view.centres_stride = c.stride * std::int64_t(sizeof(double));
    view.radii = r.data;
    view.radii_stride = r.stride * std::int64_t(sizeof(double));
    if (q) {
      view.orientations = q->data;
      view.orientations_stride = q->stride * std::int64_t(sizeof(double));
    }
    if (s) {
      view.shape_ids = s->data;
      view.shape_ids_stride = s->stride * std::int64_t(sizeof(std::int32_t));
    }
    if (id) {
      view.ids = id->data;
      view.ids_stride = id->stride * std::int64_t(sizeof(std::int64_t));
    }
    const std::span<double> field(result.mutable_data(), static_cast<std::size_t>(result.size()));
    {
      py::gil_scoped_release unlocked;
      std::lock_guard<std::mutex> lock(mutex_);
      engine_.compute(view, field);
    }
    input_copies_ = copies;
    return result;
  }

  /// The last compute's weights (option weights=1) in CSR form: offsets (particles + 1),
  /// cells and fractions (entries).
  py::tuple weights() {
    auto lock = acquire();
    const vfe::Engine::WeightsSize size = engine_.weights_size();
    py::array_t<std::int64_t> offsets(size.particles + 1), cells(size.entries);
    py::array_t<double> fractions(size.entries);
    engine_.weights(as_span(offsets), as_span(cells), as_span(fractions));
    return py::make_tuple(offsets, cells, fractions);
  }

  /// Per-particle values (particles,) or (particles, k) to cells (cell_count,) or (cell_count, k).
  py::array_t<double> deposit(const py::object& values) {
    auto lock = acquire();
    const auto rows = static_cast<py::ssize_t>(engine_.weights_size().particles);
    const Components in = components(values, "values", rows, "the last compute's particles");
    py::array_t<double> out = in.like(engine_.cell_count());
    engine_.deposit(in.k, in.span(), as_span(out));
    return out;
  }

  /// A cell field (cell_count,) or (cell_count, k) to the last compute's particles.
  py::array_t<double> interpolate(const py::object& field) {
    auto lock = acquire();
    const auto particles = static_cast<py::ssize_t>(engine_.weights_size().particles);
    const Components in = components(field, "field", engine_.cell_count(), "cell_count");
    py::array_t<double> out = in.like(particles);
    engine_.interpolate(in.k, in.span(), as_span(out));
    return out;
  }

  py::array_t<double> void_fraction() {
    py::array_t<double> out(engine_.cell_count());
    auto lock = acquire();
    engine_.void_fraction(std::span<double>(out.mutable_data(), static_cast<std::size_t>(out.size())));
    return out;
  }

  py::dict report() {
    auto lock = acquire();
    const vfe::Report& r = engine_.last_report();
    py::dict d;
    d["particles"] = r.particles;
    d["fast_path_particles"] = r.fast_path_particles;
    d["sub_elements"] = r.sub_elements;
    d["particle_grid_min"] = r.particle_grid_min;
    d["particle_grid_max"] = r.particle_grid_max;
    d["particle_volume"] = r.particle_volume;
    d["deposited_volume"] = r.deposited_volume;
    d["dropped_volume"] = r.dropped_volume;
    d["outside_particles"] = r.outside_particles;
    d["clipped_volume"] = r.clipped_volume;
    // Facts newer than the vfe_report struct, by name; integers as such.
    d["moved_particles"] = static_cast<std::int64_t>(engine_.last_report_value("moved_particles"));
    d["touched_cells"] = static_cast<std::int64_t>(engine_.last_report_value("touched_cells"));
    return d;
  }

  double report_value(const std::string& key) {
    auto lock = acquire();
    return engine_.last_report_value(key);
  }

  std::int32_t add_shape(const std::string& spec) {
    auto lock = acquire();
    return engine_.add_shape(spec);
  }

  double shape_volume(std::int32_t id) {
    auto lock = acquire();
    return engine_.shape_volume(id);
  }

  std::int64_t particle_grid_for(double diameter, double cell_size) {
    auto lock = acquire();
    return engine_.particle_grid_for(diameter, cell_size);
  }

  int input_copies() const { return input_copies_; }

 private:
  /// Waits for the engine with the GIL released (a compute in another thread holds the
  /// lock without the GIL), then returns holding both.
  std::unique_lock<std::mutex> acquire() {
    std::unique_lock<std::mutex> lock(mutex_, std::defer_lock);
    if (!lock.try_lock()) {
      py::gil_scoped_release unlocked;
      lock.lock();
    }
    return lock;
  }

  vfe::Engine engine_;
  std::mutex mutex_;
  int input_copies_ = 0;
};

/// Accepts str or os.PathLike.
std::string path_string(const py::object& p) {
  return py::module_::import("os").attr("fspath")(p).cast<std::string>();
}

std::vector<double> nodes(const py::object& obj, const char* axis) {
  py::array_t<double, py::array::c_style | py::array::forcecast> a =
      py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.ndim() != 1)
    throw py::value_error(std::string(axis) + " must be a 1-D sequence of node coordinates");
  return {a.data(), a.data() + a.size()};
}

/// Sets one vfe::StabilityOptions field from a keyword (py::cast_error for a wrong type).
void stability_option(vfe::StabilityOptions& o, const std::string& key, const py::handle& v) {
  if (key == "chi") o.chi = v.cast<double>();
  else if (key == "method") o.method = v.cast<std::string>();
  else if (key == "engine_options") o.engine_options = v.cast<std::string>();
  else if (key == "particle_grids") {
    if (py::isinstance<py::str>(v) || py::isinstance<py::int_>(v))
      o.particle_grids.push_back(py::str(v).cast<std::string>());  // one grid: "auto" or 40
    else
      for (const auto& g : v) o.particle_grids.push_back(py::str(g).cast<std::string>());
  } else if (key == "step") o.step = v.cast<double>();
  else if (key == "cells") o.cells = v.cast<double>();
  else if (key == "trajectories") o.trajectories = v.cast<int>();
  else if (key == "seed") o.seed = v.cast<std::uint64_t>();
  else if (key == "jump_criterion") o.jump_criterion = v.cast<double>();
  else if (key == "superficial_velocity") o.superficial_velocity = v.cast<double>();
  else if (key == "fluid_dt") o.fluid_dt = v.cast<double>();
  else if (key == "diameter") o.diameter = v.cast<double>();
  else if (key == "threads") o.threads = v.cast<int>();
  else if (key == "shape") o.shape = v.cast<std::string>();
  else if (key == "reference_grid") o.reference_grid = v.cast<std::int64_t>();
  else
    throw py::type_error("stability_test: unknown option '" + key +
                         "'; known: chi, method, engine_options, particle_grids, step, cells, trajectories, "
                         "seed, jump_criterion, superficial_velocity, fluid_dt, diameter, threads, shape, "
                         "reference_grid");
}

/// vfe.stability_test(**options): the keys of vfe::StabilityOptions.
py::dict stability_test(const py::kwargs& kw) {
  vfe::StabilityOptions o;
  for (const auto& [k, v] : kw) {
    const std::string key = py::str(k).cast<std::string>();
    try {
      stability_option(o, key, v);
    } catch (const py::cast_error&) {
      throw py::type_error("stability_test: " + key + "=" + py::repr(v).cast<std::string>() +
                           " has the wrong type (numbers for chi, step, cells, ...; str for method, "
                           "engine_options, shape; a list for particle_grids)");
    }
  }
  vfe::StabilityReport rep;
  {
    py::gil_scoped_release unlocked;
    rep = vfe::stability_test(o);
  }
  py::list rows;
  for (const vfe::StabilityResult& r : rep.results) {
    py::dict d;
    d["particle_grid"] = r.particle_grid;
    d["grid_min"] = r.grid_min;
    d["grid_max"] = r.grid_max;
    d["max_jump"] = r.max_jump;
    d["max_jump_exact"] = r.max_jump_exact;
    d["excess_jump"] = r.excess_jump;
    d["mean_excess_jump"] = r.mean_excess_jump;
    d["excess_in_sub_elements"] = r.excess_in_sub_elements;
    d["unstable_trajectories"] = r.unstable_trajectories;
    d["stable"] = r.stable;
    d["psi_max"] = r.psi_max;
    d["psi_excess"] = r.psi_excess;
    d["flux_stable"] = r.flux_stable;
    d["worst_trajectory"] = r.worst_trajectory;
    rows.append(d);
  }
  py::dict out;
  out["chi"] = rep.options.chi;
  out["method"] = rep.options.method;
  out["steps"] = rep.steps;
  out["jump_criterion"] = rep.options.jump_criterion;
  out["flux_criterion"] = rep.flux_criterion;
  out["results"] = rows;
  return out;
}

/// A read-only contiguous float64 (n,) argument.
std::span<const double> field_arg(const py::object& obj, const char* name, py::ssize_t n, int& copies,
                                  std::vector<py::array_t<double>>& keep) {
  const Column<double> c = column<double>(obj, name, "float64", n, 0, copies);
  keep.push_back(c.held);
  if (c.stride != 1) {
    keep.back() = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(c.held);
    return {keep.back().data(), static_cast<std::size_t>(n)};
  }
  return {c.data, static_cast<std::size_t>(n)};
}

py::dict compare_fields(const py::object& solid, const py::object& solid_exact, const py::object& cell_volumes,
                        double particle_volume) {
  if (!py::isinstance<py::array>(solid)) throw py::value_error("solid must be a numpy array of float64");
  const py::ssize_t n = py::reinterpret_borrow<py::array>(solid).size();
  int copies = 0;
  std::vector<py::array_t<double>> keep;
  const auto a = field_arg(solid, "solid", n, copies, keep);
  const auto b = field_arg(solid_exact, "solid_exact", n, copies, keep);
  const auto v = field_arg(cell_volumes, "cell_volumes", n, copies, keep);
  const vfe::AccuracyMeasures m = vfe::compare_fields(a, b, v, particle_volume);
  py::dict d;
  d["theta"] = m.theta;
  d["max_error"] = m.max_error;
  d["l1"] = m.l1;
  d["volume_error"] = m.volume_error;
  d["cells_compared"] = m.cells_compared;
  return d;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "vfe: void fraction of CFD cells from DEM particles (the engine's C++ facade over numpy)";

  static py::exception<vfe::Error> error(m, "Error", PyExc_RuntimeError);
  error_type = error.ptr();
  error.doc() = "A failed engine call: .status is the status name (e.g. 'VFE_ERROR_INVALID_ARGUMENT'), "
                ".message says what was wrong and how to fix it.";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const vfe::Error& e) {
      try {
        raise_error(vfe_status_name(e.status()), e.what());
      } catch (py::error_already_set& set) {
        set.restore();
      }
    }
  });

  m.def("version", &vfe_version, "Version of the loaded engine library, 'MAJOR.MINOR.PATCH'.");
  m.def(
      "method_names",
      [] {
        py::list names;
        for (const std::string_view name : vfe::method_names()) names.append(std::string(name));
        return names;
      },
      "Every method's name ('direct', 'pmm', ...), in the engine's order.");
  m.def(
      "status_name", [](int s) { return std::string(vfe_status_name(static_cast<vfe_status>(s))); }, py::arg("status"),
      "Name of a vfe_status code (0 -> 'VFE_OK').");

  py::class_<PyEngine>(m, "Engine",
                       "An engine on one mesh. Not for two threads at once (calls wait for each other); "
                       "distinct engines compute in parallel, without the GIL.")
      .def_static(
          "cartesian",
          [](std::array<double, 3> origin, std::array<double, 3> spacing, std::array<std::int64_t, 3> cells) {
            return std::make_unique<PyEngine>(vfe::CartesianGridSpec{origin, spacing, cells});
          },
          py::arg("origin"), py::arg("spacing"), py::arg("cells"),
          "Uniform Cartesian grid: cells[d] cells of size spacing[d] from origin; cell (i, j, k) has index "
          "i + nx*(j + ny*k).")
      .def_static(
          "rectilinear",
          [](const py::object& x, const py::object& y, const py::object& z) {
            vfe::RectilinearGridSpec spec;
            spec.nodes = {nodes(x, "x"), nodes(y, "y"), nodes(z, "z")};
            return std::make_unique<PyEngine>(spec);
          },
          py::arg("x"), py::arg("y"), py::arg("z"),
          "Rectilinear (graded) grid from strictly increasing node coordinates per axis.")
      .def_static(
          "polymesh",
          [](const py::object& dir) { return std::make_unique<PyEngine>(vfe::PolyMeshSpec{path_string(dir)}); },
          py::arg("path"), "OpenFOAM polyMesh: a case folder, its constant folder or the polyMesh folder.")
      .def_static(
          "polymesh_arrays",
          [](const py::object& points, const py::object& face_offsets, const py::object& face_points,
             const py::object& owner, const py::object& neighbour) {
            const auto p = mesh_array<double>(points, "points", "float64", 3);
            const auto fo = mesh_array<std::int64_t>(face_offsets, "face_offsets", "int64", 0);
            const auto fp = mesh_array<std::int64_t>(face_points, "face_points", "int64", 0);
            const auto ow = mesh_array<std::int64_t>(owner, "owner", "int64", 0);
            const auto nb = mesh_array<std::int64_t>(neighbour, "neighbour", "int64", 0);
            if (fo.size() != ow.size() + 1)
              throw py::value_error("face_offsets must have one entry per face plus one (" +
                                    std::to_string(ow.size() + 1) + "), got " + std::to_string(fo.size()));
            vfe::PolyMeshArrays mesh;
            mesh.n_points = p.shape(0);
            mesh.points = p.data();
            mesh.n_faces = ow.size();
            mesh.face_offsets = fo.data();
            mesh.face_points = fp.data();
            mesh.owner = ow.data();
            mesh.n_internal_faces = nb.size();
            mesh.neighbour = nb.data();
            return std::make_unique<PyEngine>(mesh);
          },
          py::arg("points"), py::arg("face_offsets"), py::arg("face_points"), py::arg("owner"), py::arg("neighbour"),
          "Face-based mesh from arrays, ordered as OpenFOAM orders it (internal faces first): points (n, 3) "
          "float64; face_offsets (faces + 1,), face_points, owner (faces,), neighbour (internal faces,) int64. "
          "Copied; the same engine as Engine.polymesh on the same mesh.")
      .def("configure", &PyEngine::configure, py::arg("options") = "",
           "Applies a 'key=value key=value' string and/or keywords (bools as 0/1); all or nothing.")
      .def("options", &PyEngine::options, "All options and their current values as a dict of strings.")
      .def("option", &PyEngine::option, py::arg("key"), "One option's current value as text.")
      .def_property_readonly("cell_count", &PyEngine::cell_count)
      .def_property_readonly("is_polymesh", &PyEngine::is_polymesh)
      .def("cell_volumes", &PyEngine::cell_volumes, "Cell volumes, (cell_count,) float64, in cell order.")
      .def("cell_centres", &PyEngine::cell_centres, "Cell centres, (cell_count, 3) float64, in cell order.")
      .def("compute", &PyEngine::compute, py::arg("centres"), py::arg("radii"), py::arg("orientations") = py::none(),
           py::arg("shape_ids") = py::none(), py::kw_only(), py::arg("ids") = py::none(), py::arg("out") = py::none(),
           "Solid volume per cell of the particles: centres (n, 3), radii (n,) (the scales with shape_ids), "
           "orientations (n, 4) quaternions w, x, y, z, all float64; shape_ids (n,) int32; ids (n,) int64, the "
           "host's particle ids (orientation=random follows them). Arrays whose rows "
           "are contiguous are read in place at any row stride; other layouts are copied once "
           "(input_copies says how many). Returns (cell_count,) float64, or fills out. The GIL is released.")
      .def("weights", &PyEngine::weights,
           "With weights=1: the last compute's (offsets, cells, fractions), per particle its cells and the "
           "fraction of its volume in each (CSR).")
      .def("deposit", &PyEngine::deposit, py::arg("values"),
           "With weights=1: per-particle values (particles,) or (particles, k) summed into cells by the weights.")
      .def("interpolate", &PyEngine::interpolate, py::arg("field"),
           "With weights=1: a cell field (cell_count,) or (cell_count, k) at the last compute's particles.")
      .def("void_fraction", &PyEngine::void_fraction, "Void fraction of the last compute, (cell_count,) float64.")
      .def("report", &PyEngine::report,
           "Facts about the last compute: every vfe_report field and moved_particles, touched_cells.")
      .def("report_value", &PyEngine::report_value, py::arg("key"), "One fact of the last compute by name.")
      .def("add_shape", &PyEngine::add_shape, py::arg("spec"),
           "Registers a shape ('sphere', 'ellipsoid A B C', 'superquadric A B C E1 E2', 'clump x y z r; ...', "
           "'mesh FILE'); returns its id.")
      .def("shape_volume", &PyEngine::shape_volume, py::arg("id"), "Volume of a shape at scale 1.")
      .def("particle_grid_for", &PyEngine::particle_grid_for, py::arg("diameter"), py::arg("cell_size"),
           "Sub-elements per particle that particle_grid gives a particle of this diameter in this cell size.")
      .def_property_readonly("input_copies", &PyEngine::input_copies,
                             "Arrays the last compute copied because their layout could not be read in place.");

  m.def("stability_test", &stability_test,
        "The stability stress test (docs/stability.md). Keywords: chi, method, engine_options, particle_grids, "
        "step, cells, trajectories, seed, jump_criterion, superficial_velocity, fluid_dt, diameter, threads, "
        "shape, reference_grid. Returns a dict with 'results', one row (dict) per particle grid.");
  m.def("compare_fields", &compare_fields, py::arg("solid"), py::arg("solid_exact"), py::arg("cell_volumes"),
        py::arg("particle_volume"),
        "Accuracy of a solid-volume field against the exact one (docs/design.md section 8): theta, max_error, l1, "
        "volume_error, cells_compared.");
  m.attr("DEFAULT_JUMP_CRITERION") = vfe::kDefaultJumpCriterion;
}
