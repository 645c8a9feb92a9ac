// C API: a catch-all layer over an engine backend (vfe/detail/engine_backend.hpp): libvfe's
// own vfe::Engine, or a backend another library of the tree supplies. No exception crosses
// into C.
#include <vfe/detail/engine_backend.hpp>
#include <vfe/engine.hpp>
#include <vfe/vfe.h>

#include <atomic>
#include <new>
#include <span>
#include <string>

struct vfe_engine {
  std::unique_ptr<vfe::detail::EngineBackend> backend;  ///< what every call runs on
  bool delegated = false;                                ///< backend given to create_engine
  std::string last_error;
  std::atomic<bool> busy{false};  ///< a call is running on this engine
};

namespace vfe::detail {

EngineBackend::~EngineBackend() = default;

void EngineBackend::agree(vfe_status mine, const std::string& message) {
  if (mine != VFE_OK) throw Error(mine, message);
}

}  // namespace vfe::detail

namespace {

thread_local std::string g_creation_error;

#define VFE_STR2(x) #x
#define VFE_STR(x) VFE_STR2(x)
constexpr const char* kVersion =
    VFE_STR(VFE_VERSION_MAJOR) "." VFE_STR(VFE_VERSION_MINOR) "." VFE_STR(VFE_VERSION_PATCH);

/// libvfe's own engine on one mesh as the handle's backend.
class MeshBackend final : public vfe::detail::EngineBackend {
 public:
  template <class MeshSpec>
  explicit MeshBackend(const MeshSpec& spec) : engine_(spec) {}

  void configure(std::string_view options) override { engine_.configure(options); }
  std::int64_t cell_count() const override { return engine_.cell_count(); }
  void cell_volumes(std::span<double> out) const override { engine_.cell_volumes(out); }
  void compute(const vfe_particles& particles, std::span<double> out) override { engine_.compute(particles, out); }
  void void_fraction(std::span<double> out) const override { engine_.void_fraction(out); }
  std::int32_t add_shape(std::string_view spec) override { return engine_.add_shape(spec); }
  vfe::Engine::WeightsSize weights_size() const override { return engine_.weights_size(); }
  void weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells,
               std::span<double> fractions) const override {
    engine_.weights(offsets, cells, fractions);
  }
  void deposit(std::int32_t components, std::span<const double> values, std::span<double> out) override {
    engine_.deposit(components, values, out);
  }
  void interpolate(std::int32_t components, std::span<const double> cell_field, std::span<double> out) override {
    engine_.interpolate(components, cell_field, out);
  }
  void set_log_callback(vfe_log_fn fn, void* user) override { engine_.set_log_callback(fn, user); }
  const vfe::Report& last_report() const override { return engine_.last_report(); }
  double last_report_value(std::string_view key) const override { return engine_.last_report_value(key); }

 private:
  vfe::Engine engine_;
};

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

/// Runs a collective call on e: check (this process's arguments, throwing vfe::Error), its
/// outcome agreed over the backend's processes, then run. So a process with a bad argument
/// fails the call on every process instead of leaving the others waiting inside run.
template <class Check, class Run>
vfe_status collective(const vfe_engine* e, Check&& check, Run&& run) noexcept {
  return on_engine(e, [&] {
    std::string message;
    const vfe_status mine = guarded(message, check);
    e->backend->agree(mine, message);
    run();
  });
}

std::string null_message(const char* what) { return std::string(what) + " is NULL; pass a valid pointer"; }

vfe_status null_argument(std::string& error, const char* what) {
  error = null_message(what);
  return VFE_ERROR_INVALID_ARGUMENT;
}

/// The check of a collective call's pointer argument.
void require_pointer(const void* p, const char* what) {
  if (!p) throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, null_message(what));
}

void require_components(int32_t components) {
  if (components < 1 || components > 64)
    throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "components is " + std::to_string(components) + "; give 1 to 64");
}

/// Wraps the backend make() gives into a new handle; *out is set only on success.
template <class Make>
vfe_status create(Make&& make, bool delegated, vfe_engine** out) noexcept {
  vfe_engine* created = nullptr;
  const vfe_status s = guarded(g_creation_error, [&] {
    auto e = std::make_unique<vfe_engine>();
    e->backend = make();
    e->delegated = delegated;
    created = e.release();
  });
  if (s != VFE_OK) return s;
  if (!out) {
    delete created;
    return null_argument(g_creation_error, "out");
  }
  *out = created;
  return VFE_OK;
}

/// Builds libvfe's own engine from a mesh spec; *out is set only on success.
template <class MeshSpec>
vfe_status create(const MeshSpec& spec, vfe_engine** out) {
  return create([&] { return std::make_unique<MeshBackend>(spec); }, false, out);
}

/// Packed arrays of n particles as the C API's view (spheres when shape_ids is NULL).
vfe_particles packed(int64_t n, const double* centres, const double* radii, const double* orientations,
                     const int32_t* shape_ids) {
  vfe_particles p{};
  p.n = n;
  p.centres = centres;
  p.radii = radii;
  p.orientations = orientations;
  p.shape_ids = shape_ids;
  return p;
}

/// The computes' one path; shapes: vfe_compute_shapes, whose shape_ids are required.
vfe_status compute(vfe_engine* e, const vfe_particles* p, double* solid_volume, bool shapes) {
  if (!e) return null_argument(g_creation_error, "engine");
  return collective(
      e,
      [&] {
        require_pointer(p, "particles");
        require_pointer(solid_volume, "solid_volume");
        if (shapes && p->n > 0) require_pointer(p->shape_ids, "shape_ids");
      },
      [&] { e->backend->compute(*p, std::span<double>(solid_volume, e->backend->cell_count())); });
}

}  // namespace

namespace vfe::detail {

vfe_status create_engine(const std::function<std::unique_ptr<EngineBackend>()>& make, vfe_engine** out) noexcept {
  return create(make, true, out);
}

EngineBackend* backend_of(const vfe_engine* e) noexcept { return e && e->delegated ? e->backend.get() : nullptr; }

vfe_status with_backend(const vfe_engine* e, const std::function<void(EngineBackend*)>& f) noexcept {
  if (!e) return null_argument(g_creation_error, "engine");
  return on_engine(e, [&] { f(backend_of(e)); });
}

}  // namespace vfe::detail

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
  return collective(e, [&] { require_pointer(options, "options"); }, [&] { e->backend->configure(options); });
}

int64_t vfe_cell_count(const vfe_engine* e) { return e ? e->backend->cell_count() : -1; }

vfe_status vfe_cell_volumes(const vfe_engine* e, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!out) return null_argument(error, "out");
  return guarded(error, [&] { e->backend->cell_volumes(std::span<double>(out, e->backend->cell_count())); });
}

vfe_status vfe_compute(vfe_engine* e, int64_t n, const double* centres, const double* radii,
                       const double* orientations, double* solid_volume) {
  const vfe_particles p = packed(n, centres, radii, orientations, nullptr);
  return compute(e, &p, solid_volume, false);
}

vfe_status vfe_void_fraction(const vfe_engine* e, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!out) return null_argument(error, "out");
  return on_engine(e, [&] { e->backend->void_fraction(std::span<double>(out, e->backend->cell_count())); });
}

const char* vfe_last_error(const vfe_engine* e) { return e ? e->last_error.c_str() : g_creation_error.c_str(); }

vfe_status vfe_add_shape(vfe_engine* e, const char* spec, int32_t* shape_id) {
  if (!e) return null_argument(g_creation_error, "engine");
  std::int32_t id = -1;
  const vfe_status s = collective(
      e,
      [&] {
        require_pointer(spec, "spec");
        require_pointer(shape_id, "shape_id");
      },
      [&] { id = e->backend->add_shape(spec); });
  if (s == VFE_OK) *shape_id = id;
  return s;
}

vfe_status vfe_compute_shapes(vfe_engine* e, int64_t n, const double* centres, const double* scales,
                              const double* orientations, const int32_t* shape_ids, double* solid_volume) {
  const vfe_particles p = packed(n, centres, scales, orientations, shape_ids);
  return compute(e, &p, solid_volume, true);
}

vfe_status vfe_last_report(const vfe_engine* e, vfe_report* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  if (!out) return null_argument(const_cast<vfe_engine*>(e)->last_error, "out");
  *out = e->backend->last_report();
  return VFE_OK;
}

vfe_status vfe_last_report_value(const vfe_engine* e, const char* key, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!key) return null_argument(error, "key");
  if (!out) return null_argument(error, "out");
  double value = 0;
  const vfe_status s = guarded(error, [&] { value = e->backend->last_report_value(key); });
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
  return compute(e, p, solid_volume, false);
}

vfe_status vfe_weights_size(const vfe_engine* e, int64_t* n_particles, int64_t* n_entries) {
  if (!e) return null_argument(g_creation_error, "engine");
  auto& error = const_cast<vfe_engine*>(e)->last_error;
  if (!n_particles) return null_argument(error, "n_particles");
  if (!n_entries) return null_argument(error, "n_entries");
  vfe::Engine::WeightsSize size;
  const vfe_status s = on_engine(e, [&] { size = e->backend->weights_size(); });
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
    const vfe::Engine::WeightsSize size = e->backend->weights_size();
    if (size.entries > 0 && (!cells || !fractions))
      throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "cells or fractions is NULL; pass arrays of n_entries values");
    e->backend->weights(std::span<std::int64_t>(offsets, size.particles + 1),
                        std::span<std::int64_t>(cells, size.entries), std::span<double>(fractions, size.entries));
  });
}

vfe_status vfe_deposit(const vfe_engine* e, int32_t components, const double* values, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  std::int64_t n = 0;
  return collective(
      e,
      [&] {
        require_pointer(out, "out");
        n = e->backend->weights_size().particles;
        if (n > 0 && !values) throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "values is NULL; pass components per particle");
        require_components(components);
      },
      [&] {
        e->backend->deposit(components, std::span<const double>(values, n * components),
                            std::span<double>(out, e->backend->cell_count() * components));
      });
}

vfe_status vfe_interpolate(const vfe_engine* e, int32_t components, const double* cell_field, double* out) {
  if (!e) return null_argument(g_creation_error, "engine");
  std::int64_t n = 0;
  return collective(
      e,
      [&] {
        require_pointer(cell_field, "cell_field");
        n = e->backend->weights_size().particles;
        if (n > 0 && !out) throw vfe::Error(VFE_ERROR_INVALID_ARGUMENT, "out is NULL; pass components per particle");
        require_components(components);
      },
      [&] {
        e->backend->interpolate(components,
                                std::span<const double>(cell_field, e->backend->cell_count() * components),
                                std::span<double>(out, n * components));
      });
}

vfe_status vfe_set_log_callback(vfe_engine* e, vfe_log_fn fn, void* user) {
  if (!e) return null_argument(g_creation_error, "engine");
  return on_engine(e, [&] { e->backend->set_log_callback(fn, user); });
}

}  // extern "C"
