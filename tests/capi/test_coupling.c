/* The coupling API driven from C99: a mesh from the host's arrays, particles in the host's
   own layout, weights, deposit, interpolate, the log callback, and their bad calls. */
#include <vfe/vfe.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"

static const double kPi = 3.14159265358979323846;

/* Two unit cubes side by side along x, as OpenFOAM orders a mesh: the internal face first. */
#define P(i, j, k) ((i) + 3 * ((j) + 2 * (k)))
static double points[36];
static const int64_t faces[44] = {
    P(1, 0, 0), P(1, 1, 0), P(1, 1, 1), P(1, 0, 1), /* internal x = 1: owner 0 -> neighbour 1 */
    P(0, 0, 0), P(0, 0, 1), P(0, 1, 1), P(0, 1, 0), /* x = 0 */
    P(2, 0, 0), P(2, 1, 0), P(2, 1, 1), P(2, 0, 1), /* x = 2 */
    P(0, 0, 0), P(1, 0, 0), P(1, 0, 1), P(0, 0, 1), /* y = 0 */
    P(1, 0, 0), P(2, 0, 0), P(2, 0, 1), P(1, 0, 1),
    P(0, 1, 0), P(0, 1, 1), P(1, 1, 1), P(1, 1, 0), /* y = 1 */
    P(1, 1, 0), P(1, 1, 1), P(2, 1, 1), P(2, 1, 0),
    P(0, 0, 0), P(0, 1, 0), P(1, 1, 0), P(1, 0, 0), /* z = 0 */
    P(1, 0, 0), P(1, 1, 0), P(2, 1, 0), P(2, 0, 0),
    P(0, 0, 1), P(1, 0, 1), P(1, 1, 1), P(0, 1, 1), /* z = 1 */
    P(1, 0, 1), P(2, 0, 1), P(2, 1, 1), P(1, 1, 1)};
static const int64_t owner[11] = {0, 0, 1, 0, 1, 0, 1, 0, 1, 0, 1};
static const int64_t neighbour[1] = {1};

struct host_particle {
  double x[3];
  double velocity[3];
  double radius;
  int64_t id;
};

static int log_calls = 0;
static void count_log(int level, const char* message, void* user) {
  (void)level;
  (void)message;
  ++*(int*)user;
}

int main(void) {
  int64_t offsets[12], n_particles = -1, n_entries = -1, cw[3] = {-1, -1, -1};
  double fw[3] = {0, 0, 0}, solid[2], vol[2], out[6] = {7, 7, 7, 7, 7, 7}, at[6], field[6];
  vfe_engine *e = NULL, *bad = NULL;
  vfe_particles p;
  struct host_particle host[2];
  int i, j, k;
  int64_t bad_owner[11];

  for (k = 0; k < 2; ++k)
    for (j = 0; j < 2; ++j)
      for (i = 0; i < 3; ++i) {
        points[3 * P(i, j, k)] = i;
        points[3 * P(i, j, k) + 1] = j;
        points[3 * P(i, j, k) + 2] = k;
      }
  for (i = 0; i < 12; ++i) offsets[i] = 4 * i;

  CHECK(strcmp(vfe_method_name(0), "direct") == 0, "first method: %s", vfe_method_name(0));
  CHECK(strcmp(vfe_method_name(8), "auto") == 0, "last method: %s", vfe_method_name(8));
  CHECK(vfe_method_name(9) == NULL && vfe_method_name(-1) == NULL, "past the last method");

  CHECK(vfe_create_polymesh_arrays(12, points, 11, offsets, faces, owner, 1, neighbour, NULL) ==
            VFE_ERROR_INVALID_ARGUMENT, "NULL out");
  memcpy(bad_owner, owner, sizeof owner);
  bad_owner[3] = -5;
  CHECK(vfe_create_polymesh_arrays(12, points, 11, offsets, faces, bad_owner, 1, neighbour, &bad) != VFE_OK &&
            bad == NULL, "a negative owner is refused");
  CHECK(strlen(vfe_last_error(NULL)) > 10, "with a message: %s", vfe_last_error(NULL));
  CHECK(vfe_create_polymesh_arrays(12, points, 11, offsets, faces, owner, 1, neighbour, &e) == VFE_OK,
        "create from arrays: %s", vfe_last_error(NULL));
  CHECK(vfe_cell_count(e) == 2, "two cells");
  CHECK(vfe_cell_volumes(e, vol) == VFE_OK && fabs(vol[0] - 1) < 1e-15 && fabs(vol[1] - 1) < 1e-15, "unit cells");

  /* Before any compute, and after one without weights: refused, outputs untouched. */
  CHECK(vfe_deposit(e, 1, fw, out) == VFE_ERROR_INVALID_ARGUMENT && out[0] == 7, "deposit before a compute");
  CHECK(vfe_weights_size(e, &n_particles, &n_entries) == VFE_ERROR_INVALID_ARGUMENT && n_particles == -1,
        "weights before a compute");

  host[0].x[0] = 1.0; host[0].x[1] = 0.5; host[0].x[2] = 0.5; host[0].radius = 0.3; host[0].id = 40;
  host[1].x[0] = 0.5; host[1].x[1] = 0.5; host[1].x[2] = 0.5; host[1].radius = 0.2; host[1].id = 41;
  for (i = 0; i < 2; ++i) host[i].velocity[0] = host[i].velocity[1] = host[i].velocity[2] = 1.0 + i;
  memset(&p, 0, sizeof p);
  p.n = 2;
  p.centres = host[0].x;
  p.centres_stride = sizeof host[0];
  p.radii = &host[0].radius;
  p.radii_stride = sizeof host[0];
  p.ids = &host[0].id;
  p.ids_stride = sizeof host[0];
  CHECK(vfe_compute_particles(e, NULL, solid) == VFE_ERROR_INVALID_ARGUMENT, "NULL particles");
  CHECK(vfe_configure(e, "method=exact") == VFE_OK, "exact: %s", vfe_last_error(e));
  CHECK(vfe_compute_particles(e, &p, solid) == VFE_OK, "compute: %s", vfe_last_error(e));
  CHECK(vfe_weights_size(e, &n_particles, &n_entries) == VFE_ERROR_INVALID_ARGUMENT, "weights=0: no weights");
  CHECK(strstr(vfe_last_error(e), "weights=1") != NULL, "the message names the option: %s", vfe_last_error(e));

  CHECK(vfe_configure(e, "weights=1") == VFE_OK, "weights=1: %s", vfe_last_error(e));
  log_calls = 0;
  CHECK(vfe_set_log_callback(e, count_log, &log_calls) == VFE_OK, "log callback");
  CHECK(vfe_configure(e, "log_level=info") == VFE_OK, "info");
  CHECK(vfe_compute_particles(e, &p, solid) == VFE_OK, "compute: %s", vfe_last_error(e));
  CHECK(log_calls > 0, "the host got the log (%d)", log_calls);
  CHECK(vfe_set_log_callback(e, NULL, NULL) == VFE_OK && vfe_configure(e, "log_level=warn") == VFE_OK, "stderr again");
  CHECK(fabs(solid[0] + solid[1] - 4.0 / 3.0 * kPi * (0.027 + 0.008)) < 1e-14, "volume conserved");
  CHECK(vfe_weights_size(e, &n_particles, &n_entries) == VFE_OK && n_particles == 2 && n_entries == 3,
        "sizes %lld %lld", (long long)n_particles, (long long)n_entries);
  CHECK(vfe_weights(e, offsets, NULL, fw) == VFE_ERROR_INVALID_ARGUMENT, "NULL cells");
  CHECK(vfe_weights(e, offsets, cw, fw) == VFE_OK, "weights: %s", vfe_last_error(e));
  CHECK(offsets[0] == 0 && offsets[1] == 2 && offsets[2] == 3, "CSR offsets");
  CHECK(fabs(fw[0] - 0.5) < 1e-14 && fabs(fw[1] - 0.5) < 1e-14 && cw[0] != cw[1], "half in each cell");
  CHECK(cw[2] == 0 && fabs(fw[2] - 1) < 1e-15, "the small one in cell 0");

  /* Deposit the particles' momentum-like 3-vectors; interpolate a cell field back. */
  {
    double values[6];
    for (i = 0; i < 2; ++i)
      for (k = 0; k < 3; ++k) values[3 * i + k] = host[i].velocity[k];
    CHECK(vfe_deposit(e, 0, values, out) == VFE_ERROR_INVALID_ARGUMENT, "zero components");
    CHECK(vfe_deposit(e, 3, NULL, out) == VFE_ERROR_INVALID_ARGUMENT, "NULL values");
    CHECK(vfe_deposit(e, 3, values, out) == VFE_OK, "deposit: %s", vfe_last_error(e));
    CHECK(fabs(out[0] - (0.5 * 1 + 1 * 2)) < 1e-14 && fabs(out[3] - 0.5 * 1) < 1e-14, "deposit %g %g", out[0], out[3]);
    for (i = 0; i < 6; ++i) field[i] = 3.0;
    CHECK(vfe_interpolate(e, 3, NULL, at) == VFE_ERROR_INVALID_ARGUMENT, "NULL field");
    CHECK(vfe_interpolate(e, 3, field, at) == VFE_OK, "interpolate: %s", vfe_last_error(e));
    for (i = 0; i < 6; ++i) CHECK(fabs(at[i] - 3.0) < 1e-15, "a constant comes back: %g", at[i]);
    field[0] = 1.0; /* cell 0, x */
    field[3] = 5.0; /* cell 1, x */
    CHECK(vfe_interpolate(e, 3, field, at) == VFE_OK && fabs(at[0] - 3.0) < 1e-14 && fabs(at[3] - 1.0) < 1e-14,
          "weighted averages %g %g", at[0], at[3]);
  }
  vfe_destroy(e);
  printf("%d passed, %d failed\n", checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
