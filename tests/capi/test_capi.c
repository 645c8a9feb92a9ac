/* The C API driven from C99: the calls a host solver makes, and its failures. */
#include <vfe/vfe.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"

static const double kPi = 3.14159265358979323846;

int main(void) {
  const double origin[3] = {0, 0, 0}, spacing[3] = {0.002, 0.002, 0.002};
  const int64_t cells[3] = {4, 4, 4};
  vfe_engine* e = NULL;
  vfe_status s;
  int64_t nc, c;
  double centres[6] = {0.004, 0.004, 0.004, 0.0011, 0.003, 0.005};
  double radii[2] = {0.0005, 0.0007};
  double *solid, *eps, *vol, total = 0, expected, saved;
  vfe_report rep;

  CHECK(strlen(vfe_version()) >= 5, "version '%s'", vfe_version());
  {
    /* The library, the generated header and CMake's project(VERSION) tell one version. */
    char from_macros[32];
    snprintf(from_macros, sizeof from_macros, "%d.%d.%d", VFE_VERSION_MAJOR, VFE_VERSION_MINOR, VFE_VERSION_PATCH);
    CHECK(strcmp(vfe_version(), from_macros) == 0, "vfe_version() '%s', macros '%s'", vfe_version(), from_macros);
    CHECK(strcmp(vfe_version(), VFE_PROJECT_VERSION) == 0, "vfe_version() '%s', project '%s'", vfe_version(),
          VFE_PROJECT_VERSION);
    CHECK(vfe_version_number() == (uint32_t)(VFE_VERSION_MAJOR * 10000 + VFE_VERSION_MINOR * 100 + VFE_VERSION_PATCH),
          "vfe_version_number() %lu", (unsigned long)vfe_version_number());
    CHECK(vfe_version_number() == VFE_VERSION_NUMBER, "vfe_version_number() %lu, VFE_VERSION_NUMBER %lu",
          (unsigned long)vfe_version_number(), (unsigned long)VFE_VERSION_NUMBER);
  }
  CHECK(strcmp(vfe_status_name(VFE_ERROR_IO), "VFE_ERROR_IO") == 0, "status name");

  s = vfe_create_cartesian(origin, spacing, cells, &e);
  CHECK(s == VFE_OK && e != NULL, "create: %s", vfe_last_error(NULL));
  if (!e) return 1;
  nc = vfe_cell_count(e);
  CHECK(nc == 64, "cell count %lld", (long long)nc);
  solid = (double*)malloc(sizeof(double) * (size_t)nc);
  eps = (double*)malloc(sizeof(double) * (size_t)nc);
  vol = (double*)malloc(sizeof(double) * (size_t)nc);
  CHECK(vfe_cell_volumes(e, vol) == VFE_OK, "cell volumes");
  CHECK(fabs(vol[0] - 8e-9) < 1e-22, "cell volume %g", vol[0]);

  expected = 4.0 / 3.0 * kPi * (radii[0] * radii[0] * radii[0] + radii[1] * radii[1] * radii[1]);
  {
    const char* methods[11] = {"method=direct",
                               "method=pmm",
                               "method=exact",
                               "method=divided",
                               "method=gaussian",
                               "method=gaussian sigma=1",
                               "method=porous_cube gamma=2",
                               "method=porous_cube gamma=1",
                               "method=big_particle",
                               "method=trilinear",
                               "method=pmm template=voxel particle_grid=100"};
    int m;
    for (m = 0; m < 11; ++m) {
      s = vfe_configure(e, methods[m]);
      CHECK(s == VFE_OK, "%s: %s", methods[m], vfe_last_error(e));
      s = vfe_compute(e, 2, centres, radii, NULL, solid);
      CHECK(s == VFE_OK, "compute %s: %s", methods[m], vfe_last_error(e));
      total = 0;
      for (c = 0; c < nc; ++c) total += solid[c];
      CHECK(fabs(total - expected) < 1e-12 * expected, "%s conserves volume: %g vs %g", methods[m], total, expected);
      CHECK(vfe_void_fraction(e, eps) == VFE_OK, "void fraction");
      CHECK(fabs(eps[0] - (1.0 - solid[0] / vol[0])) < 1e-15, "eps = 1 - Vs/V");
      CHECK(vfe_last_report(e, &rep) == VFE_OK && rep.particles == 2, "report");
      CHECK(fabs(rep.particle_volume - expected) < 1e-12 * expected, "report volume");
    }
  }

  /* A rectilinear grid on the same nodes gives the same exact and pmm fields. */
  {
    const double nodes[5] = {0, 0.002, 0.004, 0.006, 0.008}, bad_nodes[3] = {0, 0.002, 0.001};
    vfe_engine* r = NULL;
    double* other = (double*)malloc(sizeof(double) * (size_t)nc);
    const char* opts[2] = {"method=exact", "method=pmm template=fibonacci particle_grid=200 periodic=xy"};
    int m;
    CHECK(vfe_create_rectilinear(nodes, 5, nodes, 5, nodes, 5, &r) == VFE_OK && r != NULL, "rectilinear: %s",
          vfe_last_error(NULL));
    CHECK(r && vfe_cell_count(r) == 64, "rectilinear cell count");
    for (m = 0; r && m < 2; ++m) {
      double diff = 0;
      CHECK(vfe_configure(r, opts[m]) == VFE_OK && vfe_configure(e, opts[m]) == VFE_OK, "configure %s", opts[m]);
      CHECK(vfe_compute(r, 2, centres, radii, NULL, other) == VFE_OK, "rectilinear compute: %s", vfe_last_error(r));
      CHECK(vfe_compute(e, 2, centres, radii, NULL, solid) == VFE_OK, "cartesian compute: %s", vfe_last_error(e));
      for (c = 0; c < nc; ++c) diff += fabs(other[c] - solid[c]);
      CHECK(diff < 1e-12 * expected, "%s: rectilinear = cartesian (%g)", opts[m], diff);
    }
    CHECK(vfe_configure(e, "method=pmm periodic=none") == VFE_OK, "reset");
    vfe_destroy(r);
    r = NULL;
    CHECK(vfe_create_rectilinear(bad_nodes, 3, nodes, 5, nodes, 5, &r) == VFE_ERROR_INVALID_ARGUMENT && r == NULL &&
              strstr(vfe_last_error(NULL), "increasing") != NULL,
          "bad rectilinear nodes: %s", vfe_last_error(NULL));
    CHECK(vfe_create_rectilinear(NULL, 3, nodes, 5, nodes, 5, &r) == VFE_ERROR_INVALID_ARGUMENT, "NULL nodes");
    free(other);
  }

  /* Incremental update: an unmoved particle is skipped; the facts by name. */
  {
    double moved = -1, value = 0, total = 0;
    int c;
    CHECK(vfe_configure(e, "method=exact incremental=1") == VFE_OK, "incremental: %s", vfe_last_error(e));
    CHECK(vfe_compute(e, 2, centres, radii, NULL, solid) == VFE_OK, "incremental compute: %s", vfe_last_error(e));
    CHECK(vfe_last_report_value(e, "moved_particles", &moved) == VFE_OK && moved == 2.0, "first: all moved (%g)", moved);
    centres[0] += 1e-4;
    CHECK(vfe_compute(e, 2, centres, radii, NULL, solid) == VFE_OK, "incremental compute: %s", vfe_last_error(e));
    CHECK(vfe_last_report_value(e, "moved_particles", &moved) == VFE_OK && moved == 1.0, "one moved (%g)", moved);
    for (c = 0; c < nc; ++c) total += solid[c];
    CHECK(fabs(total - expected) < 1e-12 * expected, "incremental conserves volume: %g vs %g", total, expected);
    centres[0] -= 1e-4;
    CHECK(vfe_last_report_value(e, "deposited_volume", &value) == VFE_OK && fabs(value - expected) < 1e-12 * expected,
          "deposited_volume by name");
    CHECK(vfe_last_report_value(e, "bogus", &value) == VFE_ERROR_INVALID_ARGUMENT &&
              strstr(vfe_last_error(e), "moved_particles") != NULL,
          "unknown report key: %s", vfe_last_error(e));
    CHECK(vfe_last_report_value(e, NULL, &value) == VFE_ERROR_INVALID_ARGUMENT, "NULL key");
    CHECK(vfe_configure(e, "incremental=0 touched_only=0") == VFE_OK, "incremental off");
  }

  /* Failures: a status, a message, untouched output, a usable engine. */
  s = vfe_configure(e, "method=pmm bogus=1");
  CHECK(s == VFE_ERROR_INVALID_ARGUMENT, "unknown option status %d", (int)s);
  CHECK(strstr(vfe_last_error(e), "bogus") != NULL, "message names the key: %s", vfe_last_error(e));
  s = vfe_configure(e, "particle_grid=abc");
  CHECK(s == VFE_ERROR_INVALID_ARGUMENT && strstr(vfe_last_error(e), "particle_grid"), "bad value: %s",
        vfe_last_error(e));
  CHECK(vfe_configure(e, "periodic=xq") == VFE_ERROR_INVALID_ARGUMENT, "bad periodic axes");
  CHECK(vfe_configure(e, "periodic=none") == VFE_OK, "periodic=none");
  s = vfe_configure(e, "method=gaussian sigma=0");
  CHECK(s == VFE_ERROR_INVALID_ARGUMENT && strstr(vfe_last_error(e), "sigma"), "bad sigma: %s", vfe_last_error(e));
  s = vfe_configure(e, "gamma=-2");
  CHECK(s == VFE_ERROR_INVALID_ARGUMENT && strstr(vfe_last_error(e), "gamma"), "bad gamma: %s", vfe_last_error(e));

  saved = solid[0];
  solid[0] = -5.0;
  centres[4] = NAN;
  s = vfe_compute(e, 2, centres, radii, NULL, solid);
  CHECK(s == VFE_ERROR_INVALID_ARGUMENT, "NaN position status %d", (int)s);
  CHECK(strstr(vfe_last_error(e), "particle 1") != NULL, "NaN message: %s", vfe_last_error(e));
  CHECK(solid[0] == -5.0, "output untouched on failure");
  centres[4] = 0.003;
  radii[0] = -1.0;
  CHECK(vfe_compute(e, 2, centres, radii, NULL, solid) == VFE_ERROR_INVALID_ARGUMENT, "negative radius");
  radii[0] = 0.0005;
  CHECK(vfe_compute(e, 2, NULL, radii, NULL, solid) == VFE_ERROR_INVALID_ARGUMENT, "NULL centres");
  CHECK(vfe_compute(e, -1, centres, radii, NULL, solid) == VFE_ERROR_INVALID_ARGUMENT, "negative n");
  CHECK(vfe_compute(e, 2, centres, radii, NULL, NULL) == VFE_ERROR_INVALID_ARGUMENT, "NULL output");
  CHECK(vfe_configure(e, "outside=error method=exact") == VFE_OK, "outside=error");
  centres[0] = 0.0001;
  s = vfe_compute(e, 2, centres, radii, NULL, solid);
  CHECK(s == VFE_ERROR_OUT_OF_DOMAIN, "outside: %d %s", (int)s, vfe_last_error(e));
  centres[0] = 0.004;
  s = vfe_compute(e, 2, centres, radii, NULL, solid);
  CHECK(s == VFE_OK && strlen(vfe_last_error(e)) == 0, "usable after errors: %s", vfe_last_error(e));
  (void)saved;

  /* Zero particles: an empty field. */
  CHECK(vfe_compute(e, 0, NULL, NULL, NULL, solid) == VFE_OK, "n = 0: %s", vfe_last_error(e));
  total = 0;
  for (c = 0; c < nc; ++c) total += fabs(solid[c]);
  CHECK(total == 0.0, "empty field");

  {
    const int64_t zero_cells[3] = {4, 0, 4};
    vfe_engine* bad = NULL;
    s = vfe_create_cartesian(origin, spacing, zero_cells, &bad);
    CHECK(s == VFE_ERROR_INVALID_ARGUMENT && bad == NULL, "zero cells");
    CHECK(strstr(vfe_last_error(NULL), "cells[1]") != NULL, "creation message: %s", vfe_last_error(NULL));
    CHECK(vfe_create_polymesh("no/such/case", &bad) == VFE_ERROR_IO && bad == NULL, "polymesh: %s",
          vfe_last_error(NULL));
    s = vfe_create_polymesh(VFE_SOURCE_DIR "/data/openfoam/box_uniform_10x10x30", &bad);
    CHECK(s == VFE_OK && vfe_cell_count(bad) == 3000, "polymesh: %s", vfe_last_error(NULL));
    if (bad) {
      const double pc[3] = {0.005, 0.005, 0.005}, pr = 0.0007;
      double* f = (double*)malloc(sizeof(double) * 3000);
      double sum = 0;
      int64_t k;
      CHECK(vfe_compute(bad, 1, pc, &pr, NULL, f) == VFE_OK, "polymesh compute: %s", vfe_last_error(bad));
      for (k = 0; k < 3000; ++k) sum += f[k];
      CHECK(fabs(sum - 4.0 / 3.0 * kPi * pr * pr * pr) < 1e-12 * sum, "polymesh volume %g", sum);
      CHECK(vfe_configure(bad, "method=exact") == VFE_OK, "configure");
      CHECK(vfe_compute(bad, 1, pc, &pr, NULL, f) == VFE_OK, "exact on polymesh: %s", vfe_last_error(bad));
      for (sum = 0, k = 0; k < 3000; ++k) sum += f[k];
      CHECK(fabs(sum - 4.0 / 3.0 * kPi * pr * pr * pr) < 1e-12 * sum, "polymesh exact volume %g", sum);
      CHECK(vfe_configure(bad, "method=trilinear") == VFE_ERROR_UNSUPPORTED, "trilinear on polymesh is refused");
      CHECK(strstr(vfe_last_error(bad), "pmm") != NULL, "the refusal names alternatives: %s", vfe_last_error(bad));
      free(f);
      vfe_destroy(bad);
      bad = NULL;
    }
    CHECK(vfe_create_cartesian(NULL, spacing, cells, &bad) == VFE_ERROR_INVALID_ARGUMENT, "NULL origin");
  }
  CHECK(vfe_cell_count(NULL) == -1, "NULL engine count");
  CHECK(vfe_configure(NULL, "method=pmm") == VFE_ERROR_INVALID_ARGUMENT, "NULL engine configure");

  /* Shapes: an ellipsoid and the unit sphere, scaled. */
  {
    int32_t ell = -1, sph = -1, ids[2];
    double sc[2] = {0.001, 0.0005}, ctr[6] = {0.004, 0.004, 0.004, 0.003, 0.005, 0.004};
    CHECK(vfe_configure(e, "method=pmm outside=nearest") == VFE_OK, "pmm: %s", vfe_last_error(e));
    CHECK(vfe_add_shape(e, "ellipsoid 1 0.5 0.5", &ell) == VFE_OK, "ellipsoid: %s", vfe_last_error(e));
    CHECK(vfe_add_shape(e, "sphere", &sph) == VFE_OK && sph != ell, "sphere: %s", vfe_last_error(e));
    CHECK(vfe_add_shape(e, "blob 1", &sph) == VFE_ERROR_INVALID_ARGUMENT, "bad spec");
    ids[0] = ell;
    ids[1] = sph;
    s = vfe_compute_shapes(e, 2, ctr, sc, NULL, ids, solid);
    CHECK(s == VFE_OK, "compute_shapes: %s", vfe_last_error(e));
    expected = 4.0 / 3.0 * kPi * (0.25e-9 + 0.125e-9);
    total = 0;
    for (c = 0; c < nc; ++c) total += solid[c];
    CHECK(fabs(total - expected) < 1e-12 * expected, "shapes conserve volume: %g vs %g", total, expected);
    ids[0] = 9;
    CHECK(vfe_compute_shapes(e, 2, ctr, sc, NULL, ids, solid) == VFE_ERROR_INVALID_ARGUMENT, "bad id");
    CHECK(vfe_compute_shapes(e, 2, ctr, sc, NULL, NULL, solid) == VFE_ERROR_INVALID_ARGUMENT, "NULL ids");
  }

  /* direct with two threads on 85^3 cells: the deposits go through bins by regions of
   * cells (report fact binned_regions); every sphere lies inside, so the field holds their
   * volume, and each sphere's cell is the one holding its centre. */
  {
    const double h[3] = {1.0, 1.0, 1.0};
    const int64_t n85[3] = {85, 85, 85};
    const int64_t n = 70000;
    vfe_engine* big = NULL;
    double *ctr = malloc(3 * (size_t)n * sizeof(double)), *rad = malloc((size_t)n * sizeof(double));
    double *field = malloc(85 * 85 * 85 * sizeof(double)), *brute = calloc(85 * 85 * 85, sizeof(double));
    double regions = 0, worst = 0, sum = 0;
    uint64_t state = 12345;
    int64_t i, k;
    for (i = 0; i < n; ++i) {
      for (k = 0; k < 3; ++k) {
        state = state * 6364136223846793005ULL + 1442695040888963407ULL;
        ctr[3 * i + k] = 0.5 + 84.0 * (double)(state >> 11) / 9007199254740992.0;
      }
      rad[i] = 0.1 + 0.2 * (double)(i % 7) / 7.0;
      brute[(int64_t)ctr[3 * i] + 85 * ((int64_t)ctr[3 * i + 1] + 85 * (int64_t)ctr[3 * i + 2])] +=
          4.0 / 3.0 * kPi * rad[i] * rad[i] * rad[i];
    }
    CHECK(vfe_create_cartesian(origin, h, n85, &big) == VFE_OK, "85^3 grid: %s", vfe_last_error(NULL));
    CHECK(vfe_configure(big, "method=direct threads=2") == VFE_OK, "configure: %s", vfe_last_error(big));
    CHECK(vfe_compute(big, n, ctr, rad, NULL, field) == VFE_OK, "binned compute: %s", vfe_last_error(big));
    CHECK(vfe_last_report_value(big, "binned_regions", &regions) == VFE_OK && regions >= 2, "binned regions %g",
          regions);
    for (c = 0; c < 85 * 85 * 85; ++c) {
      sum += brute[c];
      if (fabs(field[c] - brute[c]) > worst) worst = fabs(field[c] - brute[c]);
    }
    CHECK(worst <= 1e-15 * sum, "binned field against each centre's cell: worst %g of %g", worst, sum);
    vfe_destroy(big);
    free(ctr);
    free(rad);
    free(field);
    free(brute);
  }

  vfe_destroy(e);
  vfe_destroy(NULL);
  free(solid);
  free(eps);
  free(vol);
  printf("%d passed, %d failed\n", checks - failures, failures);
  return failures == 0 ? 0 : 1;
}
