/* Every public function of vfe.h with every class of bad argument: the status, a message that
   says what is wrong, output buffers untouched, and the next good call's result equal to a
   fresh engine's (bitwise: deterministic=1). */
#include <vfe/vfe.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

#define NC 64 /* 4 x 4 x 4 cells */
#define SENTINEL 12345.0

static double centres[6] = {0.0021, 0.0043, 0.0042, 0.0055, 0.0031, 0.0024};
static double radii[2] = {0.0007, 0.0009};

/* A refused call on e: the status, a message of reasonable length, the buffer untouched. */
static void refused(vfe_engine* e, vfe_status got, vfe_status want, const double* buffer, const char* what) {
  const char* msg = vfe_last_error(e);
  int k, untouched = 1;
  CHECK(got == want, "%s: status %s, expected %s", what, vfe_status_name(got), vfe_status_name(want));
  CHECK(msg != NULL && strlen(msg) > 10 && strlen(msg) < 2000, "%s: message '%s'", what, msg ? msg : "(null)");
  if (buffer)
    for (k = 0; k < NC; ++k) untouched = untouched && buffer[k] == SENTINEL;
  CHECK(untouched, "%s: output buffer changed", what);
}

static void fill(double* b) {
  int k;
  for (k = 0; k < NC; ++k) b[k] = SENTINEL;
}

static vfe_engine* make(void) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {0.002, 0.002, 0.002};
  const int64_t cells[3] = {4, 4, 4};
  vfe_engine* e = NULL;
  if (vfe_create_cartesian(origin, spacing, cells, &e) != VFE_OK) return NULL;
  vfe_configure(e, "method=pmm particle_grid=50 deterministic=1");
  return e;
}

int main(void) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {0.002, 0.002, 0.002}, tiny[3] = {1e-200, 1e-200, 1e-200};
  const int64_t cells[3] = {4, 4, 4}, no_cells[3] = {4, 0, 4}, huge[3] = {1LL << 40, 1LL << 40, 1LL << 40};
  double out[NC], expected[NC], nan_centres[6], value = 0;
  double x[3] = {0, 1, 2};
  vfe_engine *e = NULL, *fresh = NULL;
  vfe_report rep;
  int32_t id = -7;
  int k;
  char* long_options;

  /* Creation: NULL pointers, bad geometry, missing or wrong files; *out stays NULL. */
  CHECK(vfe_create_cartesian(origin, spacing, cells, NULL) == VFE_ERROR_INVALID_ARGUMENT, "NULL out");
  CHECK(vfe_create_cartesian(NULL, spacing, cells, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "NULL origin");
  CHECK(vfe_create_cartesian(origin, spacing, no_cells, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "0 cells");
  CHECK(vfe_create_cartesian(origin, tiny, cells, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "tiny spacing");
  CHECK(vfe_create_cartesian(origin, spacing, huge, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "too many cells");
  CHECK(strlen(vfe_last_error(NULL)) > 10, "creation message: %s", vfe_last_error(NULL));
  CHECK(vfe_create_polymesh(NULL, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "NULL folder");
  CHECK(vfe_create_polymesh("no/such/case", &e) == VFE_ERROR_IO && e == NULL, "missing folder: %s",
        vfe_last_error(NULL));
  CHECK(vfe_create_rectilinear(x, 3, NULL, 2, x, 2, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "NULL nodes");
  CHECK(vfe_create_rectilinear(x, 1, x, 2, x, 2, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "one node");
  CHECK(vfe_create_rectilinear(x, -3, x, 2, x, 2, &e) == VFE_ERROR_INVALID_ARGUMENT && e == NULL, "negative count");

  /* Every engine function with e = NULL. */
  CHECK(vfe_configure(NULL, "method=pmm") == VFE_ERROR_INVALID_ARGUMENT, "configure NULL");
  CHECK(vfe_cell_count(NULL) == -1, "cell_count NULL");
  CHECK(vfe_cell_volumes(NULL, out) == VFE_ERROR_INVALID_ARGUMENT, "cell_volumes NULL");
  CHECK(vfe_compute(NULL, 2, centres, radii, NULL, out) == VFE_ERROR_INVALID_ARGUMENT, "compute NULL");
  CHECK(vfe_void_fraction(NULL, out) == VFE_ERROR_INVALID_ARGUMENT, "void_fraction NULL");
  CHECK(vfe_add_shape(NULL, "sphere", &id) == VFE_ERROR_INVALID_ARGUMENT, "add_shape NULL");
  CHECK(vfe_compute_shapes(NULL, 0, NULL, NULL, NULL, NULL, out) == VFE_ERROR_INVALID_ARGUMENT, "shapes NULL");
  CHECK(vfe_last_report(NULL, &rep) == VFE_ERROR_INVALID_ARGUMENT, "report NULL");
  CHECK(vfe_last_report_value(NULL, "particles", &value) == VFE_ERROR_INVALID_ARGUMENT, "report value NULL");
  vfe_destroy(NULL);

  /* The reference: a fresh engine's field. */
  fresh = make();
  CHECK(fresh != NULL, "fresh engine");
  CHECK(vfe_compute(fresh, 2, centres, radii, NULL, expected) == VFE_OK, "reference: %s", vfe_last_error(fresh));

  e = make();
  /* Options: unknown key, bad value, twice, not key=value, NULL, a 1 MiB string. */
  refused(e, vfe_configure(e, "bogus=1"), VFE_ERROR_INVALID_ARGUMENT, NULL, "unknown option");
  CHECK(strstr(vfe_last_error(e), "bogus") != NULL, "names the key: %s", vfe_last_error(e));
  refused(e, vfe_configure(e, "particle_grid=-3"), VFE_ERROR_INVALID_ARGUMENT, NULL, "bad value");
  refused(e, vfe_configure(e, "method=pmm method=exact"), VFE_ERROR_INVALID_ARGUMENT, NULL, "key twice");
  refused(e, vfe_configure(e, "method"), VFE_ERROR_INVALID_ARGUMENT, NULL, "not key=value");
  refused(e, vfe_configure(e, NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "NULL options");
  long_options = malloc(1 << 20);
  memcpy(long_options, "method=", 7);
  memset(long_options + 7, 'x', (1 << 20) - 8);
  long_options[(1 << 20) - 1] = '\0';
  refused(e, vfe_configure(e, long_options), VFE_ERROR_INVALID_ARGUMENT, NULL, "a 1 MiB option string");
  free(long_options);

  /* Computes: negative n, NULL arrays, NaN, r <= 0, overflowing volume, NULL output. */
  fill(out);
  refused(e, vfe_compute(e, -1, centres, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "negative n");
  refused(e, vfe_compute(e, 2, NULL, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "NULL centres");
  memcpy(nan_centres, centres, sizeof centres);
  nan_centres[4] = NAN;
  refused(e, vfe_compute(e, 2, nan_centres, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "NaN centre");
  radii[1] = 0;
  refused(e, vfe_compute(e, 2, centres, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "zero radius");
  radii[1] = 1e103;
  refused(e, vfe_compute(e, 2, centres, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "volume overflows");
  radii[1] = 0.0009;
  refused(e, vfe_compute(e, 2, centres, radii, NULL, NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "NULL output");
  CHECK(vfe_configure(e, "orientation=given") == VFE_OK, "given");
  refused(e, vfe_compute(e, 2, centres, radii, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out, "given without quaternions");
  CHECK(vfe_configure(e, "orientation=random outside=error") == VFE_OK, "outside=error");
  centres[0] = 0.0001; /* reaches beyond the grid */
  refused(e, vfe_compute(e, 2, centres, radii, NULL, out), VFE_ERROR_OUT_OF_DOMAIN, out, "outside=error");
  centres[0] = 0.0021;
  CHECK(vfe_configure(e, "outside=nearest") == VFE_OK, "nearest");

  /* Shapes: NULL spec or id, unknown kind, missing file, a folder, bad ids in a compute. */
  refused(e, vfe_add_shape(e, NULL, &id), VFE_ERROR_INVALID_ARGUMENT, NULL, "NULL spec");
  refused(e, vfe_add_shape(e, "sphere", NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "NULL id");
  refused(e, vfe_add_shape(e, "blob 1 2", &id), VFE_ERROR_INVALID_ARGUMENT, NULL, "unknown shape");
  refused(e, vfe_add_shape(e, "mesh no_such_file.stl", &id), VFE_ERROR_IO, NULL, "missing mesh file");
  refused(e, vfe_add_shape(e, "mesh .", &id), VFE_ERROR_IO, NULL, "a folder as mesh file");
  CHECK(id == -7, "shape id untouched (%d)", id);
  {
    int32_t ids[2] = {0, 5};
    fill(out);
    refused(e, vfe_compute_shapes(e, 2, centres, radii, NULL, ids, out), VFE_ERROR_INVALID_ARGUMENT, out,
            "unregistered shape id");
    refused(e, vfe_compute_shapes(e, 2, centres, radii, NULL, NULL, out), VFE_ERROR_INVALID_ARGUMENT, out,
            "NULL shape ids");
  }

  /* Reads: NULL outputs, unknown report key. */
  refused(e, vfe_cell_volumes(e, NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "cell_volumes NULL out");
  refused(e, vfe_void_fraction(e, NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "void_fraction NULL out");
  refused(e, vfe_last_report(e, NULL), VFE_ERROR_INVALID_ARGUMENT, NULL, "report NULL out");
  refused(e, vfe_last_report_value(e, NULL, &value), VFE_ERROR_INVALID_ARGUMENT, NULL, "NULL key");
  value = -5;
  refused(e, vfe_last_report_value(e, "no_such_fact", &value), VFE_ERROR_INVALID_ARGUMENT, NULL, "unknown key");
  CHECK(value == -5, "value untouched");

  /* After all of that, the next good call equals a fresh engine's, bit for bit. */
  fill(out);
  CHECK(vfe_compute(e, 2, centres, radii, NULL, out) == VFE_OK, "good compute: %s", vfe_last_error(e));
  for (k = 0; k < NC; ++k) CHECK(out[k] == expected[k], "cell %d: %.17g vs fresh %.17g", k, out[k], expected[k]);
  CHECK(strlen(vfe_last_error(e)) == 0, "the message is cleared on success");

  vfe_destroy(e);
  vfe_destroy(fresh);
  printf("%d passed, %d failed\n", checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
