// What a vfe_engine handle runs its calls on: libvfe's own engine on one mesh, or a backend
// another library of this tree supplies (libvfe_mpi's engine spread over MPI ranks), so that
// such an engine is an ordinary vfe_engine to its host. Installed with libvfe because libvfe
// exports it, but not part of the C API or a stable interface; libvfe stays free of what a
// backend needs (MPI).
#pragma once

#include <vfe/engine.hpp>
#include <vfe/vfe.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace vfe::detail {

/// One method per call of vfe.h that touches an engine; the C API checks the pointers,
/// holds the handle's busy flag and turns every exception (vfe::Error: status and message)
/// into the call's status and vfe_last_error. Sizes of spans are the C API's (cell_count
/// values per cell, the last compute's particles).
class VFE_API EngineBackend {
 public:
  virtual ~EngineBackend();

  /// First step of every collective call (configure, the computes, add_shape, deposit,
  /// interpolate): this process's argument check, `mine` and its message. A backend spread
  /// over processes makes every process throw the first failing one's Error, so that all
  /// return the same status and none is left waiting in the call; this default throws this
  /// process's failure only.
  virtual void agree(vfe_status mine, const std::string& message);

  virtual void configure(std::string_view options) = 0;
  virtual std::int64_t cell_count() const = 0;
  virtual void cell_volumes(std::span<double> out) const = 0;
  /// Spheres, or shapes when particles.shape_ids is set (radii are then the scales).
  virtual void compute(const vfe_particles& particles, std::span<double> out) = 0;
  virtual void void_fraction(std::span<double> out) const = 0;
  virtual std::int32_t add_shape(std::string_view spec) = 0;
  virtual Engine::WeightsSize weights_size() const = 0;
  virtual void weights(std::span<std::int64_t> offsets, std::span<std::int64_t> cells,
                       std::span<double> fractions) const = 0;
  virtual void deposit(std::int32_t components, std::span<const double> values, std::span<double> out) = 0;
  virtual void interpolate(std::int32_t components, std::span<const double> cell_field, std::span<double> out) = 0;
  virtual void set_log_callback(vfe_log_fn fn, void* user) = 0;
  virtual const Report& last_report() const = 0;
  virtual double last_report_value(std::string_view key) const = 0;
};

/// A field of vfe_report by name (the first keys of vfe_last_report_value) into value;
/// false, value untouched, for another key.
VFE_API bool report_field(const Report& report, std::string_view key, double& value) noexcept;

/// Creates a vfe_engine whose calls run on the backend make() returns (the handle owns it;
/// vfe_destroy deletes it). make's exceptions become the status and the creation message
/// (vfe_last_error(NULL)); *out is set only on success. out is not checked before make
/// runs, so a collective make can check it with its other arguments on every process.
VFE_API vfe_status create_engine(const std::function<std::unique_ptr<EngineBackend>()>& make,
                                 vfe_engine** out) noexcept;

/// The backend e was created on by create_engine; null for libvfe's own engines and NULL.
VFE_API EngineBackend* backend_of(const vfe_engine* e) noexcept;

/// Runs f(backend_of(e)) under the C API's guards, for a backend library's own calls on a
/// vfe_engine: e NULL, the busy flag, and f's exceptions to the status and vfe_last_error(e).
VFE_API vfe_status with_backend(const vfe_engine* e, const std::function<void(EngineBackend*)>& f) noexcept;

}  // namespace vfe::detail
