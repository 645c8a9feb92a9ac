/* Instructions per compute on an OpenFOAM mesh, for comparing two builds (docs/performance.md):
 *   cc -O2 -std=c99 scripts/polymesh_instructions.c -I engine/include -I build/release/engine/include \
 *      -L build/release/engine -lvfe -o polymesh_instructions
 *   LD_LIBRARY_PATH=BUILD/engine valgrind --tool=callgrind --callgrind-out-file=/dev/null \
 *      ./polymesh_instructions data/openfoam/box_uniform_10x10x30 "method=direct threads=1" R
 * for R = 1 and 3; (Ir(3) - Ir(1)) / 2 is one compute. 20000 spheres of 0.5 mm in
 * [5, 15] x [5, 15] x [5, 55] mm from a fixed linear congruential sequence. */
#include <vfe/vfe.h>
#include <stdio.h>
#include <stdlib.h>
int main(int argc, char** argv) {
  const char* dir = argv[1];
  const char* options = argv[2];
  int repeats = atoi(argv[3]);
  int n = 20000, i;
  vfe_engine* e = NULL;
  double *c = malloc(sizeof(double) * 3 * n), *r = malloc(sizeof(double) * n), *out;
  unsigned long long s = 12345;
  for (i = 0; i < 3 * n; ++i) {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    double u = (double)(s >> 11) / 9007199254740992.0;
    c[i] = (i % 3 == 2) ? 0.005 + 0.05 * u : 0.005 + 0.01 * u;
  }
  for (i = 0; i < n; ++i) r[i] = 0.0005;
  if (vfe_create_polymesh(dir, &e) != VFE_OK) { puts(vfe_last_error(NULL)); return 1; }
  if (vfe_configure(e, options) != VFE_OK) { puts(vfe_last_error(e)); return 1; }
  out = malloc(sizeof(double) * vfe_cell_count(e));
  for (i = 0; i < repeats; ++i)
    if (vfe_compute(e, n, c, r, NULL, out) != VFE_OK) { puts(vfe_last_error(e)); return 1; }
  vfe_destroy(e);
  return 0;
}
