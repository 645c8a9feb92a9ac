// C API: a catch-all layer over vfe::Engine. No exception crosses into C.
#include <vfe/engine.hpp>
#include <vfe/vfe.h>

#include <atomic>
#include <new>
#include <span>
#include <string>

struct vfe_engine {
  std::unique_ptr<vfe::Engine> engine;
  std::string last_error;
  std::atomic<bool> busy{false};  ///< a call is running on this engine
};

namespace {

thread_local std::string g_creation_error;

#define VFE_STR2(x) #x
#define VFE_STR(x) VFE_STR2(x)
constexpr const char* kVersion =
    VFE_STR(VFE_VERSION_MAJOR) "." VFE_STR(VFE_VERSION_MINOR) "." VFE_STR(VFE_VERSION_PATCH);

/// Runs f, turning every exception into a status and a message in `error`.
template <class F>
vfe_status guarded(std::string& error, F&& f) noexcept {
  try {
    f();
    error.clear();
    return VFE_OK;
  } catch (const vfe::Error& e) {
    error = e.what();
    return e.status();
  } catch (const std::bad_alloc&) {
    error = "out of memory; use fewer particles or a coarser mesh per engine";
    return VFE_ERROR_OUT_OF_MEMORY;
  } catch (const std::exception& e) {
    error = std::string("internal error: ") + e.what() + " (please report it)";
    return VFE_ERROR_INTERNAL;
  } catch (...) {
    error = "internal error of unknown kind (please report it)";
    return VFE_ERROR_INTERNAL;
  }
}

/// Runs f on engine e unless another thread is inside a call on e: then the call is
/// refused without touching e (its message goes to the calling thread's creation error).
template <class F>
vfe_status on_engine(const vfe_engine* e, F&& f) noexcept {
  auto* engine = const_cast<vfe_engine*>(e);
  if (engine->busy.exchange(true, std::memory_order_acquire)) {
    g_creation_error =
        "this engine is being used by another thread; one engine must not be called from two threads at once "
        "(use one engine per thread)";
    return VFE_ERROR_INVALID_ARGUMENT;
  }
  const vfe_status s = guarded(engine->last_error, f);
  engine->busy.store(false, std::memory_order_release);
  return s;
}

vfe_status null_argument(std::string& error, const char* what) {
  error = std::string(what) + " is NULL; pass a valid pointer";
  return VFE_ERROR_INVALID_ARGUMENT;
}

/// Builds an engine from a mesh spec; *out is set only on success.
template <class MeshSpec>
vfe_status create(const MeshSpec& spec, vfe_engine** out) {
  vfe_engine* created = nullptr;
  const vfe_status s = guarded(g_creation_error, [&] {
    auto e = std::make_unique<vfe_engine>();
    e->engine = std::make_unique<vfe::Engine>(spec);
    created = e.release();
  });
  if (s == VFE_OK) *out = created;
  return s;
}

}  // namespace

extern "C" {

const char* vfe_version(void) { return kVersion; }

uint32_t vfe_version_number(void) { return VFE_VERSION_NUMBER; }

const char* vfe_status_name(vfe_status s) {
  switch (s) {
    case VFE_OK: return "VFE_OK";
    case VFE_ERROR_INVALID_ARGUMENT: return "VFE_ERROR_INVALID_ARGUMENT";
    case VFE_ERROR_OUT_OF_DOMAIN: return "VFE_ERROR_OUT_OF_DOMAIN";
    case VFE_ERROR_IO: return "VFE_ERROR_IO";
    case VFE_ERROR_UNSUPPORTED: return "VFE_ERROR_UNSUPPORTED";
    case VFE_ERROR_OUT_OF_MEMORY: return "VFE_ERROR_OUT_OF_MEMORY";
    case VFE_ERROR_INTERNAL: return "VFE_ERROR_INTERNAL";
  }
  return "VFE_UNKNOWN_STATUS";
}

vfe_status vfe_create_cartesian(const double origin[3], const double spacing[3], const int64_t cells[3],
                                vfe_engine** out) {
  if (!out) return null_argument(g_creation_error, "out");
  if (!origin) return null_argument(g_creation_error, "origin");
  if (!spacing) return null_argument(g_creation_error, "spacing");
  if (!cells) return null_argument(g_creation_error, "cells");
  vfe::CartesianGridSpec spec;
  for (int d = 0; d < 3; ++d) {
    spec.origin[d] = origin[d];
    spec.spacing[d] = spacing[d];
    spec.cells[d] = cells[d];
  }
  return create(spec, out);
}

vfe_status vfe_create_polymesh(const char* polymesh_dir, vfe_engine** out) {
  if (!out) return null_argument(g_creation_error, "out");
  if (!polymesh_dir) return null_argument(g_creation_error, "polymesh_dir");
  return create(vfe::PolyMeshSpec{polymesh_dir}, out);
}

vfe_status vfe_create_rectilinear(const double* x_nodes, int64_t n_x, const double* y_nodes, int64_t n_y,
                                  const double* z_nodes, int64_t n_z, vfe_engine** out) {
  if (!out) return null_argument(g_creation_error, "out");
  const double* nodes[3] = {x_nodes, y_nodes, z_nodes};
  const int64_t counts[3] = {n_x, n_y, n_z};
  vfe::RectilinearGridSpec spec;
  for (int d = 0; d < 3; ++d) {
    if (!nodes[d]) return null_argument(g_creation_error, d == 0 ? "x_nodes" : d == 1 ? "y_nodes" : "z_nodes");
    if (counts[d] < 0) {
      g_creation_error = std::string("node count of axis ") + "xyz"[d] + " is negative; pass the length of the array";
      return VFE_ERROR_INVALID_ARGUMENT;
    }
  }
  const vfe_status copied = guarded(g_creation_error, [&] {
    for (int d = 0; d < 3; ++d) spec.nodes[d].assign(nodes[d], nodes[d] + counts[d]);
  });
  return copied == VFE_OK ? create(spec, out) : copied;
}

void vfe_destroy(vfe_engine* e) { delete e; }

vfe_status vfe_configure(vfe_engine* e, const char* options) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!options) return null_argument(e->last_error, "options");
  return on_engine(e, [&] { e->engine->configure(options); });
}

int64_t vfe_cell_count(const vfe_engine* e) { return e ? e->engine->cell_count() : -1; }

vfe_status vfe_cell_volumes(const vfe_engine* e, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!out) return null_argument(error, "out");
  return guarded(error, [&] { e->engine->cell_volumes(std::span<double>(out, e->engine->cell_count())); });
}

vfe_status vfe_compute(vfe_engine* e, int64_t n, const double* centres, const double* radii,
                       const double* orientations, double* solid_volume) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!solid_volume) return null_argument(e->last_error, "solid_volume");
  return on_engine(e, [&] {
    vfe::ParticleView view;
    view.n = n;
    view.centres = centres;
    view.radii = radii;
    view.orientations = orientations;
    e->engine->compute(view, std::span<double>(solid_volume, e->engine->cell_count()));
  });
}

vfe_status vfe_void_fraction(const vfe_engine* e, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!out) return null_argument(error, "out");
  return on_engine(e, [&] { e->engine->void_fraction(std::span<double>(out, e->engine->cell_count())); });
}

const char* vfe_last_error(const vfe_engine* e) { return e ? e->last_error.c_str() : g_creation_error.c_str(); }

vfe_status vfe_add_shape(vfe_engine* e, const char* spec, int32_t* shape_id) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!spec) return null_argument(e->last_error, "spec");
  if (!shape_id) return null_argument(e->last_error, "shape_id");
  std::int32_t id = -1;
  const vfe_status s = on_engine(e, [&] { id = e->engine->add_shape(spec); });
  if (s == VFE_OK) *shape_id = id;
  return s;
}

vfe_status vfe_compute_shapes(vfe_engine* e, int64_t n, const double* centres, const double* scales,
                              const double* orientations, const int32_t* shape_ids, double* solid_volume) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!solid_volume) return null_argument(e->last_error, "solid_volume");
  if (n > 0 && !shape_ids) return null_argument(e->last_error, "shape_ids");
  return on_engine(e, [&] {
    vfe::ParticleView view;
    view.n = n;
    view.centres = centres;
    view.radii = scales;
    view.orientations = orientations;
    view.shape_ids = shape_ids;
    e->engine->compute(view, std::span<double>(solid_volume, e->engine->cell_count()));
  });
}

vfe_status vfe_last_report(const vfe_engine* e, vfe_report* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!out) return null_argument(const_cast<vfe_engine*>(e)->last_error, "out");
  *out = e->engine->last_report();
  return VFE_OK;
}

vfe_status vfe_last_report_value(const vfe_engine* e, const char* key, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!key) return null_argument(error, "key");
  if (!out) return null_argument(error, "out");
  double value = 0;
  const vfe_status s = guarded(error, [&] { value = e->engine->last_report_value(key); });
  if (s == VFE_OK) *out = value;
  return s;
}

const char* vfe_method_name(int32_t i) {
  const auto names = vfe::method_names();
  return i >= 0 && static_cast<std::size_t>(i) < names.size() ? names[static_cast<std::size_t>(i)].data() : nullptr;
}

vfe_status vfe_create_polymesh_arrays(int64_t n_points, const double* points, int64_t n_faces,
                                      const int64_t* face_offsets, const int64_t* face_points, const int64_t* owner,
                                      int64_t n_internal_faces, const int64_t* neighbour, vfe_engine** out) {
  if (!out) return null_argument(g_creation_error, "out");
  vfe::PolyMeshArrays a;
  a.n_points = n_points;
  a.points = points;
  a.n_faces = n_faces;
  a.face_offsets = face_offsets;
  a.face_points = face_points;
  a.owner = owner;
  a.n_internal_faces = n_internal_faces;
  a.neighbour = neighbour;
  return create(a, out);
}

vfe_status vfe_compute_particles(vfe_engine* e, const vfe_particles* p, double* solid_volume) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!p) return null_argument(e->last_error, "particles");
  if (!solid_volume) return null_argument(e->last_error, "solid_volume");
  return on_engine(e, [&] { e->engine->compute(*p, std::span<double>(solid_volume, e->engine->cell_count())); });
}

vfe_status vfe_weights_size(const vfe_engine* e, int64_t* n_particles, int64_t* n_entries) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!n_particles) return null_argument(error, "n_particles");
  if (!n_entries) return null_argument(error, "n_entries");
  vfe::Engine::WeightsSize size;
  const vfe_status s = on_engine(e, [&] { size = e->engine->weights_size(); });
  if (s == VFE_OK) {
    *n_particles = size.particles;
    *n_entries = size.entries;
  }
  return s;
}

vfe_status vfe_weights(const vfe_engine* e, int64_t* offsets, int64_t* cells, double* fractions) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!offsets) return null_argument(error, "offsets");
  return on_engine(e, [&] {
    const vfe::Engine::WeightsSize size = e->engine->weights_size();
    if (size.entries > 0 && (!cells || !fractions))
      throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "cells or fractions is NULL; pass arrays of n_entries values");
    e->engine->weights(std::span<std::int64_t>(offsets, size.particles + 1), std::span<std::int64_t>(cells, size.entries),
                       std::span<double>(fractions, size.entries));
  });
}

vfe_status vfe_deposit(const vfe_engine* e, int32_t components, const double* values, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!out) return null_argument(error, "out");
  return on_engine(e, [&] {
    const std::int64_t n = e->engine->weights_size().particles;
    if (n > 0 && !values) throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "values is NULL; pass components per particle");
    if (components < 1 || components > 64)
      throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "components is " + std::to_string(components) + "; give 1 to 64");
    e->engine->deposit(components, std::span<const double>(values, n * components),
                       std::span<double>(out, e->engine->cell_count() * components));
  });
}

vfe_status vfe_interpolate(const vfe_engine* e, int32_t components, const double* cell_field, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!cell_field) return null_argument(error, "cell_field");
  return on_engine(e, [&] {
    const std::int64_t n = e->engine->weights_size().particles;
    if (n > 0 && !out) throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "out is NULL; pass components per particle");
    if (components < 1 || components > 64)
      throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "components is " + std::to_string(components) + "; give 1 to 64");
    e->engine->interpolate(components, std::span<const double>(cell_field, e->engine->cell_count() * components),
                           std::span<double>(out, n * components));
  });
}

vfe_status vfe_set_log_callback(vfe_engine* e, vfe_log_fn fn, void* user) {
  if (!e) return null_argument(g_creation_error, "engine");
  return on_engine(e, [&] { e->engine->set_log_callback(fn, user); });
}

}  // extern "C"
